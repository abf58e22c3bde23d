#include "microsim/trace_vndf.h"

#include "microsim/progress.h"
#include "microsim/random.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <time.h>

namespace microsim {

// ---- fast binning -----------------------------------------------------------------------------------------

FastDirectionBinner::FastDirectionBinner(const DirectionBinning& b) : binning_(&b) {
  const nlohmann::json d = b.describe();
  lobe_ = b.kind() == BinningKind::lobe;
  rows_ = b.rows();
  cols_ = b.cols();
  z_min_ = b.z_min();
  z_max_ = b.z_max();
  inv_dz_ = rows_ / (z_max_ - z_min_);
  if (lobe_) {
    inv_ax_ = 1.0 / d.at("alpha").at(0).get<double>();
    inv_ay_ = 1.0 / d.at("alpha").at(1).get<double>();
    exact_only_ = d.at("domain").get<std::string>() != "microfacet_normal";
  }
  if (cols_ < 8) exact_only_ = true;  // sectors of pi/4 or wider: keep the simple path
  cols_per_radian_ = cols_ / (2 * kPi<double>);
  edge_cos_.resize(std::size_t(cols_) + 1);
  edge_sin_.resize(std::size_t(cols_) + 1);
  for (int j = 0; j <= cols_; ++j) {
    const double phi = 2 * kPi<double> * double(j % cols_) / double(cols_);
    edge_cos_[std::size_t(j)] = std::cos(phi);
    edge_sin_[std::size_t(j)] = std::sin(phi);
  }
}

namespace {
// arctan on [0, 1] (Abramowitz & Stegun 1964, eq. 4.4.47: |error| <= 1e-5 rad): only a first guess of
// the sector, which the edge tests below correct and confirm.
inline double atan_unit(double t) {
  const double t2 = t * t;
  return t * (0.9998660 + t2 * (-0.3302995 + t2 * (0.1801410 + t2 * (-0.0851330 + t2 * 0.0208351))));
}

// phi = base + sign * atan(min / max) by octant, index = (|y| > |x|) + 2 (x < 0) + 4 (y < 0):
// first quadrant q = a or pi/2 - a, then pi - q, pi + q, 2 pi - q for the other quadrants.
struct OctantMap {
  double base[8], sign[8];
  constexpr OctantMap() : base{}, sign{} {
    const double half_pi = kPi<double> / 2;
    for (int i = 0; i < 8; ++i) {
      const bool swap = i & 1, x_negative = i & 2, y_negative = i & 4;
      const double qb = swap ? half_pi : 0.0, qs = swap ? -1.0 : 1.0;  // q = qb + qs a
      double pb = 0.0, ps = 1.0;                                        // phi = pb + ps q
      if (x_negative && !y_negative) pb = kPi<double>, ps = -1.0;
      if (x_negative && y_negative) pb = kPi<double>, ps = 1.0;
      if (!x_negative && y_negative) pb = 2 * kPi<double>, ps = -1.0;
      base[i] = pb + ps * qb;
      sign[i] = ps * qs;
    }
  }
};
constexpr OctantMap kOctants;
}  // namespace

int FastDirectionBinner::operator()(const Vec3<double>& direction) const {
  if (exact_only_ || !direction.allFinite()) return exact(direction);
  // A point along the parameter-space direction (not normalised: the column needs only its direction).
  const Vec3<double> v = lobe_ ? Vec3<double>(direction.x() * inv_ax_, direction.y() * inv_ay_, direction.z()) : direction;
  const double len2 = v.squaredNorm();
  if (!(len2 > 1e-280) || !(len2 < 1e280)) return exact(direction);  // zero, or near under/overflow
  const double z = v.z() / std::sqrt(len2);
  if (lobe_ && (z < z_min_ || z > z_max_)) {
    // Outside the lobe's parameter space (bin_of: nullopt) unless within round-off of its rim.
    if (z < z_min_ - 1e-12 || z > z_max_ + 1e-12) return -1;
    return exact(direction);
  }
  // Row, with a guard band where round-off could move u.z across a row edge. r >= -1e-15 here, so
  // truncation is floor except in the guard band.
  const double r = (z_max_ - z) * inv_dz_;
  const double r_floor = double(static_cast<long long>(r));
  const double frac = r - r_floor;
  // Column: arctangent by octant (branch-free), then the sector whose edges bracket (x, y).
  const double x = v.x(), y = v.y(), ax = std::abs(x), ay = std::abs(y);
  const bool swap = ay > ax;
  const double lo = swap ? ax : ay, hi = swap ? ay : ax;
  const int octant = int(swap) | (int(x < 0) << 1) | (int(y < 0) << 2);
  if ((frac < 1e-9) | (frac > 1 - 1e-9) | !(hi > 1e-150 * std::sqrt(len2))) return exact(direction);  // row edge or pole
  const int row = std::min(int(r_floor), rows_ - 1);
  const double phi = kOctants.base[octant] + kOctants.sign[octant] * atan_unit(lo / hi);
  int col = std::clamp(int(phi * cols_per_radian_), 0, cols_ - 1);
  // cross(e_j, p) >= 0: p is at or counter-clockwise of edge j (less than pi away).
  const auto side = [&](int j) { return edge_cos_[std::size_t(j)] * y - edge_sin_[std::size_t(j)] * x; };
  while (col > 0 && side(col) < 0) --col;
  while (col < cols_ - 1 && side(col + 1) >= 0) ++col;
  const double margin = 1e-12 * hi;
  if (!((side(col) >= margin) & (side(col + 1) <= -margin))) return exact(direction);  // near an edge, or wrapped
  return row * cols_ + col;
}

// ---- the target ------------------------------------------------------------------------------------------

EllipsoidTarget::EllipsoidTarget(double alpha_x, double alpha_y, int mesh_level, embree::BuildQuality quality)
    : ellipsoid_{alpha_x, alpha_y}, mesh_level_(mesh_level < 0 ? -1 : mesh_level) {
  if (!(alpha_x > 0.0) || !(alpha_y > 0.0) || !std::isfinite(alpha_x) || !std::isfinite(alpha_y)) {
    throw std::invalid_argument(fmt::format("ellipsoid roughness ({}, {}) must be positive and finite", alpha_x, alpha_y));
  }
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

// Uniform point of the unit disk by rejection from the square (no trigonometry; 4/pi pairs on average).
inline void disk_point(CounterRng& rng, double& x, double& y) {
  do {
    x = 2.0 * rng.uniform() - 1.0;
    y = 2.0 * rng.uniform() - 1.0;
  } while (x * x + y * y >= 1.0);
}

double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

constexpr std::size_t kMaxBinnings = 8;
constexpr int kUnknownBin = std::numeric_limits<int>::min();
constexpr int kNotCounted = -2;

struct LocalHistograms {
  std::vector<std::vector<std::uint64_t>> counts;
  std::vector<std::uint64_t> unbinned;
  std::uint64_t rays = 0, hits = 0;
};

}  // namespace

TraceResult trace_vndf(const EllipsoidTarget& target, const Vec3<double>& wi_in,
                       std::span<const DirectionBinning> binnings, const TraceOptions& options) {
  if (options.rays == 0) throw std::invalid_argument("trace_vndf: the number of rays must be positive");
  const ParallelBeam beam(target.ellipsoid(), wi_in);
  const Vec3<double> wi = wi_in.normalized();
  const Vec3<float> dir = beam.direction().cast<float>();
  const std::uint64_t blocks = (options.rays + kRaysPerBlock - 1) / kRaysPerBlock;
  const std::size_t nb = binnings.size();
  if (nb > kMaxBinnings) throw std::invalid_argument(fmt::format("trace_vndf: at most {} binnings", kMaxBinnings));
  std::vector<FastDirectionBinner> binners;
  for (const DirectionBinning& b : binnings) binners.emplace_back(b);
  // Mesh targets: per-triangle cache of its bins (kUnknownBin until first hit, kNotCounted for faces
  // whose hits do not count), `stride` ints per triangle.
  const std::size_t stride = std::max<std::size_t>(nb, 1);
  std::unique_ptr<std::atomic<int>[]> face_cache;
  if (target.is_mesh()) {
    const std::size_t n = target.triangle_count() * stride;
    face_cache.reset(new std::atomic<int>[n]);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, std::size_t(1) << 16), [&](const auto& r) {
      for (std::size_t i = r.begin(); i != r.end(); ++i) face_cache[i].store(kUnknownBin, std::memory_order_relaxed);
    });
  }

  tbb::enumerable_thread_specific<LocalHistograms> locals([&] {
    LocalHistograms h;
    h.counts.resize(nb);
    for (std::size_t k = 0; k < nb; ++k) h.counts[k].assign(std::size_t(binnings[k].size()), 0);
    h.unbinned.assign(nb, 0);
    return h;
  });
  std::atomic<bool> stopped{false};
  ProgressBar progress("trace vndf", options.rays, options.progress);
  const embree::Scene& scene = target.scene();
  const RTCScene rtc_scene = scene.handle();
  constexpr float kInf = std::numeric_limits<float>::infinity();

  // Mesh: a triangle has one normal, so its bins (or "not counted") are computed on its first hit and
  // cached; racing threads store the same values.
  constexpr unsigned int kNoFace = RTC_INVALID_GEOMETRY_ID;
  auto count_face = [&](LocalHistograms& local, unsigned int face) {
    std::atomic<int>* slot = &face_cache[std::size_t(face) * stride];
    int first_value = slot[0].load(std::memory_order_relaxed);
    if (first_value == kUnknownBin) {
      Vec3<double> n;
      const embree::Hit hit{0.0f, face, 0, Vec3<float>::Zero(), 0.0f, 0.0f};
      const bool counted = target.counted_normal(hit, wi, n);
      for (std::size_t k = 0; k < stride; ++k) {
        slot[k].store(!counted ? kNotCounted : (k < nb ? binners[k](n) : 0), std::memory_order_relaxed);
      }
      first_value = slot[0].load(std::memory_order_relaxed);
    }
    if (first_value == kNotCounted) return;
    ++local.hits;
    for (std::size_t k = 0; k < nb; ++k) {
      const int bin = slot[k].load(std::memory_order_relaxed);
      if (bin >= 0) {
        ++local.counts[k][std::size_t(bin)];
      } else {
        ++local.unbinned[k];
      }
    }
  };

  const auto start = std::chrono::steady_clock::now();
  const double cpu_start = process_cpu_seconds();
  auto body = [&](const tbb::blocked_range<std::uint64_t>& range) {
    embree::FlushDenormalsScope ftz;  // Embree wants FTZ/DAZ in every tracing thread
    LocalHistograms& local = locals.local();
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    for (std::uint64_t block = range.begin(); block != range.end(); ++block) {
      if (options.stop_on_interrupt && interrupted()) {
        stopped.store(true, std::memory_order_relaxed);
        return;
      }
      const std::uint64_t first = block * kRaysPerBlock;
      const std::uint64_t count = std::min(kRaysPerBlock, options.rays - first);
      CounterRng rng(options.seed, block);
      unsigned int pending_face = kNoFace;
      for (std::uint64_t i = 0; i < count; ++i) {
        double x, y;
        disk_point(rng, x, y);
        const Vec3<float> o = beam.origin(x, y).cast<float>();
        RTCRayHit rh;
        rh.ray.org_x = o.x();
        rh.ray.org_y = o.y();
        rh.ray.org_z = o.z();
        rh.ray.dir_x = dir.x();
        rh.ray.dir_y = dir.y();
        rh.ray.dir_z = dir.z();
        rh.ray.tnear = 0.0f;
        rh.ray.tfar = kInf;
        rh.ray.time = 0.0f;
        rh.ray.mask = 0xffffffffu;
        rh.ray.id = 0;
        rh.ray.flags = 0;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(rtc_scene, &context, &rh);
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
        if (face_cache) {
          // Software pipelining: fetch this triangle's cache line now, bin the previous hit while it
          // arrives (the order of integer increments does not matter).
          __builtin_prefetch(&face_cache[std::size_t(rh.hit.primID) * stride]);
          if (pending_face != kNoFace) count_face(local, pending_face);
          pending_face = rh.hit.primID;
          continue;
        }
        const embree::Hit hit{rh.ray.tfar, rh.hit.primID, rh.hit.geomID,
                              Vec3<float>(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z), rh.hit.u, rh.hit.v};
        Vec3<double> n;
        if (!target.counted_normal(hit, wi, n)) continue;
        ++local.hits;
        for (std::size_t k = 0; k < nb; ++k) {
          const int bin = binners[k](n);
          if (bin >= 0) {
            ++local.counts[k][std::size_t(bin)];
          } else {
            ++local.unbinned[k];
          }
        }
      }
      if (pending_face != kNoFace) count_face(local, pending_face);
      pending_face = kNoFace;
      local.rays += count;
      progress.add(count);
    }
  };

  if (options.threads > 0) {
    tbb::task_arena arena(options.threads);
    arena.execute([&] { tbb::parallel_for(tbb::blocked_range<std::uint64_t>(0, blocks, 1), body); });
  } else {
    tbb::parallel_for(tbb::blocked_range<std::uint64_t>(0, blocks, 1), body);
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double cpu_seconds = process_cpu_seconds() - cpu_start;
  progress.finish();
  scene.device().check("rtcIntersect1");

  TraceResult result;
  result.counts.resize(nb);
  for (std::size_t k = 0; k < nb; ++k) result.counts[k].assign(std::size_t(binnings[k].size()), 0);
  result.unbinned.assign(nb, 0);
  // Integer sums: the merge order does not matter, the result is exact.
  for (const LocalHistograms& h : locals) {
    result.rays += h.rays;
    result.hits += h.hits;
    for (std::size_t k = 0; k < nb; ++k) {
      for (std::size_t b = 0; b < h.counts[k].size(); ++b) result.counts[k][b] += h.counts[k][b];
      result.unbinned[k] += h.unbinned[k];
    }
  }
  result.seconds = seconds;
  result.cpu_seconds = cpu_seconds;
  result.partial = stopped.load() || result.rays < options.rays;
  return result;
}

std::vector<BeamRay> generate_beam_rays(const ParallelBeam& beam, std::uint64_t count, std::uint64_t seed) {
  std::vector<BeamRay> rays(count);
  const Vec3<float> dir = beam.direction().cast<float>();
  const std::uint64_t blocks = (count + kRaysPerBlock - 1) / kRaysPerBlock;
  tbb::parallel_for(std::uint64_t(0), blocks, [&](std::uint64_t block) {
    CounterRng rng(seed, block);
    const std::uint64_t first = block * kRaysPerBlock, n = std::min(kRaysPerBlock, count - first);
    for (std::uint64_t i = 0; i < n; ++i) {
      double x, y;
      disk_point(rng, x, y);
      rays[first + i] = {beam.origin(x, y).cast<float>(), dir};
    }
  });
  return rays;
}

}  // namespace microsim
