#include "trace/trace_vndf.h"

#include "core/block_runner.h"
#include "core/cpu_time.h"
#include "core/random.h"

#include <fmt/core.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace microsim {

// ---- the target ------------------------------------------------------------------------------------------

EllipsoidTarget::EllipsoidTarget(double alpha_x, double alpha_y, int mesh_level, embree::BuildQuality quality)
    : ellipsoid_{alpha_x, alpha_y}, mesh_level_(mesh_level < 0 ? -1 : mesh_level) {
  if (!(alpha_x > 0.0) || !(alpha_y > 0.0) || !std::isfinite(alpha_x) || !std::isfinite(alpha_y)) {
    throw std::invalid_argument(fmt::format("ellipsoid roughness ({}, {}) must be positive and finite", alpha_x, alpha_y));
  }
  if (!is_mesh()) check_quadric_roughness(alpha_x, alpha_y);  // before any Embree work (QuadricEllipsoid checks too)
  device_ = std::make_unique<embree::Device>();
  scene_ = std::make_unique<embree::Scene>(*device_, quality, /*robust=*/true);
  if (is_mesh()) {
    mesh_ = std::make_unique<microgeom::EllipsoidTriMesh>(microgeom::build_ellipsoid_mesh(ellipsoid_, mesh_level_));
    auto buffers = microgeom::triangle_buffers(*mesh_);
    scene_->add_triangles(buffers.vertices, buffers.indices);
    face_normals_.assign(buffers.face_normals.begin(), buffers.face_normals.end());
  } else {
    quadric_ = std::make_unique<QuadricEllipsoid>(ellipsoid_);
    quadric_->attach(*scene_);
  }
  scene_->commit();
}

std::string EllipsoidTarget::describe() const {
  if (!is_mesh()) return "quadric";
  return fmt::format("mesh level {} ({} triangles)", mesh_level_, triangle_count());
}

// ---- the beam ----------------------------------------------------------------------------------------------

ParallelBeam::ParallelBeam(const microgeom::Ellipsoid& ellipsoid, const Vec3<double>& wi) : ellipsoid_(ellipsoid) {
  if (!(wi.z() > 0.0) || !wi.allFinite()) {
    throw std::invalid_argument(fmt::format("beam direction ({}, {}, {}) must point above the horizon", wi.x(), wi.y(), wi.z()));
  }
  wi_ = wi.normalized();
  orthonormal_basis(wi_, b1_, b2_);
  // Silhouette: the ellipsoid {x : x^T A x <= 1}, A = diag(ax^2, ay^2, 1), projected on span(b1, b2) is
  // the ellipse {y : y^T S^-1 y <= 1} with S = P A^-1 P^T, P = [b1 b2]^T (the image of the unit ball
  // under P A^-1/2). Uniform points: y = L w, L L^T = S, w uniform in the unit disk.
  const Vec3<double> inv_a(1.0 / sqr(ellipsoid.ax), 1.0 / sqr(ellipsoid.ay), 1.0);
  const double s11 = b1_.cwiseProduct(inv_a).dot(b1_);
  const double s12 = b1_.cwiseProduct(inv_a).dot(b2_);
  const double s22 = b2_.cwiseProduct(inv_a).dot(b2_);
  l11_ = std::sqrt(s11);
  l21_ = s12 / l11_;
  l22_ = safe_sqrt(s22 - l21_ * l21_);
  l11_ *= kBeamMargin;
  l21_ *= kBeamMargin;
  l22_ *= kBeamMargin;
  // Start beyond the support plane along wi (1% and a unit of slack): every origin is outside.
  start_ = 1.01 * ellipsoid.support(wi_) + 1.0;
}

double ParallelBeam::area() const { return kPi<double> * l11_ * l22_; }

double ParallelBeam::expected_hit_fraction() const {
  const GGX<double> ggx(ellipsoid_.ax, ellipsoid_.ay);
  return ellipsoid_.footprint_area() * ggx.projected_area(wi_) / area();
}

namespace {

// n uniform points of the unit disk by rejection from the square (no trigonometry; 4/pi pairs on
// average), without a data-dependent branch: every candidate is written, and the write position advances
// only when it is accepted. xs and ys hold n + 1 values. The sequence is that of a loop drawing pairs
// (x first) until one falls inside, repeated n times.
inline void disk_points(CounterRng& rng, int n, double* xs, double* ys) {
  int k = 0;
  while (k < n) {
    const double x = 2.0 * rng.uniform() - 1.0;
    const double y = 2.0 * rng.uniform() - 1.0;
    xs[k] = x;
    ys[k] = y;
    k += int(x * x + y * y < 1.0);
  }
}

// Rays are generated, traced and binned in batches of this many (a block is 16 batches): each stage
// runs as a tight loop over the batch, so the binning is vectorised and independent of Embree's code.
constexpr int kBatch = 256;
static_assert(kRaysPerBlock % kBatch == 0);

struct BatchBuffers {
  double disk_x[kBatch + 1], disk_y[kBatch + 1];
  float org_x[kBatch], org_y[kBatch], org_z[kBatch];
  float nx[kBatch], ny[kBatch], nz[kBatch];  // counted normals
  int bins[kBatch];
};

// Origins of a batch: disk points mapped to the beam, rounded to float.
inline void beam_origins(const ParallelBeam& beam, BatchBuffers& b, int n) {
  for (int i = 0; i < n; ++i) {
    const Vec3<double> o = beam.origin(b.disk_x[i], b.disk_y[i]);
    b.org_x[i] = float(o.x());
    b.org_y[i] = float(o.y());
    b.org_z[i] = float(o.z());
  }
}

constexpr std::size_t kMaxBinnings = 8;
constexpr int kUnknownBin = std::numeric_limits<int>::min();
constexpr int kNotCounted = -2;

// One block's tally: per binning its bins, then one for unbinned hits.
struct BlockTally {
  std::vector<std::vector<std::uint64_t>> counts;
  std::uint64_t rays = 0, hits = 0;
  void count(std::size_t binning, int bin) {
    std::vector<std::uint64_t>& c = counts[binning];
    ++c[bin >= 0 ? std::size_t(bin) : c.size() - 1];
  }
};


// Mesh targets: per-triangle cache of its bins (kUnknownBin until first hit, kNotCounted for faces whose
// hits do not count), `stride` ints per triangle. A triangle has one normal, so its bins are computed on
// its first hit; racing threads store the same values. Slot 0 is published last (release) and read first
// (acquire): a thread that sees it set sees the whole entry. (Storing slot 0 first let another thread
// read a lobe bin still unknown, about one run in eight at mesh level 4: a hit counted as unbinned.)
class FaceBinCache {
public:
  FaceBinCache(const EllipsoidTarget& target, const Vec3<double>& wi, std::span<const FastDirectionBinner> binners)
      : target_(target), wi_(wi), binners_(binners), stride_(std::max<std::size_t>(binners.size(), 1)),
        slots_(new std::atomic<int>[target.triangle_count() * stride_]) {
    const std::size_t n = target.triangle_count() * stride_;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, std::size_t(1) << 16), [&](const auto& r) {
      for (std::size_t i = r.begin(); i != r.end(); ++i) slots_[i].store(kUnknownBin, std::memory_order_relaxed);
    });
  }
  void prefetch(unsigned int face) const { __builtin_prefetch(&slots_[std::size_t(face) * stride_]); }
  void count(BlockTally& tally, unsigned int face) const {
    std::atomic<int>* slot = &slots_[std::size_t(face) * stride_];
    int first_value = slot[0].load(std::memory_order_acquire);
    if (first_value == kUnknownBin) first_value = fill(slot, face);
    if (first_value == kNotCounted) return;
    ++tally.hits;
    for (std::size_t k = 0; k < binners_.size(); ++k) tally.count(k, slot[k].load(std::memory_order_relaxed));
  }

private:
  int fill(std::atomic<int>* slot, unsigned int face) const {
    Vec3<double> n;
    const embree::Hit hit{0.0f, face, 0, Vec3<float>::Zero(), 0.0f, 0.0f};
    const bool counted = target_.counted_normal(hit, wi_, n);
    auto value = [&](std::size_t k) { return !counted ? kNotCounted : (k < binners_.size() ? binners_[k](n) : 0); };
    for (std::size_t k = stride_; k-- > 1;) slot[k].store(value(k), std::memory_order_relaxed);
    const int first_value = value(0);
    slot[0].store(first_value, std::memory_order_release);
    return first_value;
  }
  const EllipsoidTarget& target_;
  Vec3<double> wi_;
  std::span<const FastDirectionBinner> binners_;
  std::size_t stride_;
  std::unique_ptr<std::atomic<int>[]> slots_;
};

// Traces one block of the beam: disk points from CounterRng(seed, block), in batches of kBatch.
class BeamBlockTracer {
public:
  BeamBlockTracer(const EllipsoidTarget& target, const ParallelBeam& beam, const Vec3<double>& wi,
                  std::span<const DirectionBinning> binnings, std::span<const FastDirectionBinner> binners,
                  const FaceBinCache* faces)
      : target_(target), beam_(beam), wi_(wi), dir_(beam.direction().cast<float>()), binnings_(binnings),
        binners_(binners), faces_(faces) {}

  BlockTally trace(const BlockPlan& plan, std::uint64_t seed, std::uint64_t block, BatchBuffers& b) const {
    embree::FlushDenormalsScope ftz;  // Embree wants FTZ/DAZ in every tracing thread
    BlockTally tally;
    tally.counts.resize(binnings_.size());
    for (std::size_t k = 0; k < binnings_.size(); ++k) tally.counts[k].assign(std::size_t(binnings_[k].size()) + 1, 0);
    const std::uint64_t count = plan.units_in(block);
    CounterRng rng(seed, block);
    for (std::uint64_t batch_first = 0; batch_first < count; batch_first += kBatch) {
      const int n = int(std::min<std::uint64_t>(kBatch, count - batch_first));
      disk_points(rng, n, b.disk_x, b.disk_y);
      beam_origins(beam_, b, n);
      if (faces_) trace_mesh_batch(b, n, tally);
      else trace_quadric_batch(b, n, tally);
    }
    tally.rays = count;
    return tally;
  }

private:
  RTCRayHit intersect(const BatchBuffers& b, int i, RTCIntersectContext& context) const {
    constexpr float kInf = std::numeric_limits<float>::infinity();
    RTCRayHit rh = embree::make_ray_hit(b.org_x[i], b.org_y[i], b.org_z[i], dir_.x(), dir_.y(), dir_.z(), 0.0f, kInf);
    rtcIntersect1(target_.scene().handle(), &context, &rh);
    return rh;
  }
  // Mesh: software pipelining: fetch a hit triangle's cache line, bin the previous hit while it arrives
  // (the order of integer increments does not matter).
  void trace_mesh_batch(BatchBuffers& b, int n, BlockTally& tally) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    unsigned int pending = RTC_INVALID_GEOMETRY_ID;
    for (int i = 0; i < n; ++i) {
      const RTCRayHit rh = intersect(b, i, context);
      if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
      faces_->prefetch(rh.hit.primID);
      if (pending != RTC_INVALID_GEOMETRY_ID) faces_->count(tally, pending);
      pending = rh.hit.primID;
    }
    if (pending != RTC_INVALID_GEOMETRY_ID) faces_->count(tally, pending);
  }
  // Quadric: a lean loop of rtcIntersect1 calls, as the raw benchmark's; normals (zero for a miss, which
  // does not count) go to b.nx/ny/nz, then the counted ones (EllipsoidTarget::counted_normal's rule, in
  // double) are compacted in place without a data-dependent branch and binned.
  void trace_quadric_batch(BatchBuffers& b, int n, BlockTally& tally) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    for (int i = 0; i < n; ++i) {
      const RTCRayHit rh = intersect(b, i, context);
      const bool hit = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
      b.nx[i] = hit ? rh.hit.Ng_x : 0.0f;
      b.ny[i] = hit ? rh.hit.Ng_y : 0.0f;
      b.nz[i] = hit ? rh.hit.Ng_z : 0.0f;
    }
    int counted = 0;
    for (int i = 0; i < n; ++i) {
      const float x = b.nx[i], y = b.ny[i], z = b.nz[i];
      b.nx[counted] = x;
      b.ny[counted] = y;
      b.nz[counted] = z;
      counted += int(EllipsoidTarget::counts(Vec3<double>(x, y, z), wi_));
    }
    tally.hits += std::uint64_t(counted);
    for (std::size_t k = 0; k < binners_.size(); ++k) {
      binners_[k].bin_floats(b.nx, b.ny, b.nz, counted, b.bins);
      for (int i = 0; i < counted; ++i) tally.count(k, b.bins[i]);
    }
  }

  const EllipsoidTarget& target_;
  const ParallelBeam& beam_;
  Vec3<double> wi_;
  Vec3<float> dir_;
  std::span<const DirectionBinning> binnings_;
  std::span<const FastDirectionBinner> binners_;
  const FaceBinCache* faces_;
};

void add_tally(TraceResult& result, const BlockTally& tally) {
  result.rays += tally.rays;
  result.hits += tally.hits;
  for (std::size_t k = 0; k < result.counts.size(); ++k) {
    for (std::size_t b = 0; b < result.counts[k].size(); ++b) result.counts[k][b] += tally.counts[k][b];
    result.unbinned[k] += tally.counts[k].back();
  }
}

}  // namespace

TraceResult empty_trace_result(std::span<const DirectionBinning> binnings, std::uint64_t total_blocks) {
  TraceResult result;
  result.counts.resize(binnings.size());
  for (std::size_t k = 0; k < binnings.size(); ++k) result.counts[k].assign(std::size_t(binnings[k].size()), 0);
  result.unbinned.assign(binnings.size(), 0);
  result.total_blocks = total_blocks;
  return result;
}

TraceResult trace_vndf(const EllipsoidTarget& target, const Vec3<double>& wi_in,
                       std::span<const DirectionBinning> binnings, const TraceOptions& options) {
  if (options.rays == 0) throw std::invalid_argument("trace_vndf: the number of rays must be positive");
  if (binnings.size() > kMaxBinnings) throw std::invalid_argument(fmt::format("trace_vndf: at most {} binnings", kMaxBinnings));
  const ParallelBeam beam(target.ellipsoid(), wi_in);
  const Vec3<double> wi = wi_in.normalized();
  std::vector<FastDirectionBinner> binners;
  for (const DirectionBinning& b : binnings) binners.emplace_back(b);
  std::optional<FaceBinCache> faces;
  if (target.is_mesh()) faces.emplace(target, wi, binners);
  const BeamBlockTracer tracer(target, beam, wi, binnings, binners, faces ? &*faces : nullptr);

  const BlockPlan plan{options.rays, kRaysPerBlock};
  TraceResult result = empty_trace_result(binnings, plan.blocks());
  tbb::enumerable_thread_specific<std::unique_ptr<BatchBuffers>> buffers([] { return std::make_unique<BatchBuffers>(); });
  const auto start = std::chrono::steady_clock::now();
  const double cpu_start = process_cpu_seconds();
  const BlockRunStatus status = for_each_block(
      selected_blocks(plan, options.blocks), options.run, {"trace vndf", plan},
      [&](std::uint64_t block) { return tracer.trace(plan, options.seed, block, *buffers.local()); },
      [&](BlockTally&& tally, std::uint64_t) { add_tally(result, tally); });
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.cpu_seconds = process_cpu_seconds() - cpu_start;
  target.scene().device().check("rtcIntersect1");
  result.blocks = status.done;
  result.partial = status.cancelled;
  return result;
}

std::vector<BeamRay> generate_beam_rays(const ParallelBeam& beam, std::uint64_t count, std::uint64_t seed) {
  std::vector<BeamRay> rays(count);
  const Vec3<float> dir = beam.direction().cast<float>();
  const BlockPlan plan{count, kRaysPerBlock};
  // The same disk points, origins and order as trace_vndf's batches; each block writes its own rays.
  for_each_block(
      BlockRange{0, plan.blocks()}, RunControl{}, {"beam rays", plan},
      [&](std::uint64_t block) {
        CounterRng rng(seed, block);
        auto b = std::make_unique<BatchBuffers>();
        const std::uint64_t first = plan.first_unit(block), n = plan.units_in(block);
        for (std::uint64_t batch_first = 0; batch_first < n; batch_first += kBatch) {
          const int m = int(std::min<std::uint64_t>(kBatch, n - batch_first));
          disk_points(rng, m, b->disk_x, b->disk_y);
          beam_origins(beam, *b, m);
          for (int i = 0; i < m; ++i)
            rays[first + batch_first + std::size_t(i)] = {Vec3<float>(b->org_x[i], b->org_y[i], b->org_z[i]), dir};
        }
        return n;
      },
      [](std::uint64_t, std::uint64_t) {});
  return rays;
}

}  // namespace microsim
