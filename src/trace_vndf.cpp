#include "microsim/trace_vndf.h"

#include "microsim/progress.h"
#include "microsim/random.h"

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

  const auto start = std::chrono::steady_clock::now();
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
        const embree::Hit hit{rh.ray.tfar, rh.hit.primID, rh.hit.geomID,
                              Vec3<float>(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z), rh.hit.u, rh.hit.v};
        const auto n = target.counted_normal(hit, wi);
        if (!n) continue;
        ++local.hits;
        for (std::size_t k = 0; k < nb; ++k) {
          const auto bin = binnings[k].bin_of(*n);
          if (bin) {
            ++local.counts[k][std::size_t(*bin)];
          } else {
            ++local.unbinned[k];
          }
        }
      }
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
