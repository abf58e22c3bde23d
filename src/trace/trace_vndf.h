// microsim: the exact VNDF oracle. A parallel beam along -wi hits the GGX ellipsoid (Heitz 2018,
// "Sampling the GGX Distribution of Visible Normals", JCGT 7(4), sec. 2; design note section 2); the
// normals of the first hits with z >= 0 are distributed exactly as the visible normal distribution
// D_v(wi, m) (Heitz 2014, JCGT 3(2), eq. 16): the upper half of the ellipsoid has the GGX normal
// distribution per unit footprint area, and a convex body masks nothing, so only Monte Carlo noise
// remains (plus tessellation bias for the meshed ellipsoid).
//
// Target: the full ellipsoid as an exact quadric (Embree user geometry, double-precision intersection),
// or the truncated ellipsoid meshed at level K (microgeom/ellipsoid_mesh.h). A hit counts when it is
// entering (front-facing: <normal, wi> > 0) and on the upper half (normal.z >= 0, which has the sign of
// the hit point's z). Back-facing hits on the open mesh are rays that entered through the base plane,
// i.e. whose first hit on the full ellipsoid has z < 0: they do not count.
//
// Beam: ray origins uniform over the ellipse that is the ellipsoid's exact silhouette seen along wi
// (enlarged by kBeamMargin), in the plane through the centre orthogonal to wi, moved back along wi
// beyond the ellipsoid's support in that direction; every ray starts outside the ellipsoid.
//
// Determinism: rays are traced in blocks of kRaysPerBlock; block b draws its variates from
// CounterRng(seed, b) (inside a block, batches of 256 rays are generated, traced, filtered and binned,
// each stage a tight loop over the batch, which keeps the overhead over raw rtcIntersect1 small); the
// block runner (core/block_runner.h) adds the block tallies in block order, so counts depend only on
// (seed, block range): the same whatever the thread count, and shards add up to the whole run.
#pragma once

#include "core/block_runner.h"
#include "core/run_control.h"
#include "microgeom/ellipsoid.h"
#include "microgeom/ellipsoid_mesh.h"
#include "stats/binning.h"
#include "stats/direction_binner.h"  // FastDirectionBinner (the tracers' binning kernel; it was declared here)
#include "trace/embree.h"
#include "trace/quadric.h"

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

namespace microsim {

inline constexpr std::uint64_t kRaysPerBlock = 4096;
inline constexpr double kBeamMargin = 1.0 + 1e-3;  // beam radius / silhouette radius: covers round-off

// The ellipsoid in an Embree scene: exact quadric (mesh_level < 0) or mesh of that level.
class EllipsoidTarget {
public:
  EllipsoidTarget(double alpha_x, double alpha_y, int mesh_level,
                  embree::BuildQuality quality = embree::BuildQuality::high);
  EllipsoidTarget(const EllipsoidTarget&) = delete;
  EllipsoidTarget& operator=(const EllipsoidTarget&) = delete;

  const microgeom::Ellipsoid& ellipsoid() const { return ellipsoid_; }
  bool is_mesh() const { return mesh_level_ >= 0; }
  int mesh_level() const { return mesh_level_; }
  std::size_t triangle_count() const { return face_normals_.size(); }
  const microgeom::EllipsoidTriMesh* mesh() const { return mesh_.get(); }
  const embree::Scene& scene() const { return *scene_; }
  // "quadric" or "mesh level K (N triangles)".
  std::string describe() const;

  // The normal a hit reports (the quadric's analytic unit normal as Embree stored it in float, or the
  // triangle's unit normal in double), if the hit counts for the VNDF seen from wi: front-facing and on
  // the upper half; false otherwise. Not renormalised: the binning normalises (DirectionBinning::bin_of).
  bool counted_normal(const embree::Hit& hit, const Vec3<double>& wi, Vec3<double>& normal) const {
    normal = is_mesh() ? face_normals_[hit.prim_id] : hit.Ng.cast<double>();
    return counts(normal, wi);
  }
  // The rule itself: front-facing seen from wi and on the upper half.
  static bool counts(const Vec3<double>& normal, const Vec3<double>& wi) {
    return normal.dot(wi) > 0.0 && normal.z() >= 0.0;
  }

private:
  microgeom::Ellipsoid ellipsoid_;
  int mesh_level_;
  std::unique_ptr<embree::Device> device_;
  std::unique_ptr<embree::Scene> scene_;
  std::unique_ptr<QuadricEllipsoid> quadric_;
  std::unique_ptr<microgeom::EllipsoidTriMesh> mesh_;
  std::vector<Vec3<double>> face_normals_;
};

// The beam: a uniform point of the (enlarged) silhouette ellipse -> a ray along -wi.
class ParallelBeam {
public:
  ParallelBeam(const microgeom::Ellipsoid& ellipsoid, const Vec3<double>& wi);
  // Ray origin for a point (x, y) of the unit disk.
  Vec3<double> origin(double disk_x, double disk_y) const {
    const double s = l11_ * disk_x, t = l21_ * disk_x + l22_ * disk_y;
    return s * b1_ + t * b2_ + start_ * wi_;
  }
  Vec3<double> direction() const { return -wi_; }
  // Area of the beam's cross-section (the enlarged silhouette ellipse).
  double area() const;
  // The fraction of beam rays whose first hit counts, for the exact ellipsoid: the projected area of its
  // visible upper half, footprint area x (wi.z + t) / 2 (Heitz 2014 eq. 7 with the Smith G1), over area().
  double expected_hit_fraction() const;

private:
  microgeom::Ellipsoid ellipsoid_;
  Vec3<double> wi_, b1_, b2_;
  double l11_, l21_, l22_;  // Cholesky factor of the silhouette's 2x2 matrix (times the margin)
  double start_;            // distance of the origins' plane from the centre, beyond the support
};

struct TraceOptions {
  std::uint64_t rays = 1'000'000;
  std::uint64_t seed = 1;
  std::optional<BlockRange> blocks;  // trace only these blocks of kRaysPerBlock rays (a shard); default all
  RunControl run;                    // threads, cancel token, progress ("trace vndf")
};

struct TraceResult {
  std::uint64_t rays = 0;  // rays traced (completed blocks)
  std::uint64_t hits = 0;  // counted first hits
  std::vector<std::vector<std::uint64_t>> counts;  // per binning, per bin
  std::vector<std::uint64_t> unbinned;              // per binning: counted hits outside its parameter space
  double seconds = 0;      // wall-clock time of the tracing loop
  double cpu_seconds = 0;  // CPU time of the process (all threads) during the loop: robust to other load
  BlockRange blocks;              // the blocks traced (a prefix of the requested ones when cancelled)
  std::uint64_t total_blocks = 0;  // blocks of the whole run (options.rays in blocks of kRaysPerBlock)
  bool partial = false;    // cancelled before all requested blocks were traced
  double rays_per_second() const { return seconds > 0 ? double(rays) / seconds : 0.0; }
  double cpu_ns_per_ray() const { return rays > 0 ? 1e9 * cpu_seconds / double(rays) : 0.0; }
};

// A result with every count zero for `binnings`, to which block tallies are added.
TraceResult empty_trace_result(std::span<const DirectionBinning> binnings, std::uint64_t total_blocks);

// Traces `options.rays` rays of the beam seen from wi (unit, wi.z > 0) and histograms the counted
// normals in every binning. Throws std::invalid_argument for wi.z <= 0 or rays == 0.
TraceResult trace_vndf(const EllipsoidTarget& target, const Vec3<double>& wi,
                       std::span<const DirectionBinning> binnings, const TraceOptions& options);

// The same loop without binning, on pre-generated beam rays, for the throughput benchmark's raw rate:
// calls rtcIntersect1 on rays[begin, end) and returns the number of hits.
struct BeamRay {
  Vec3<float> origin, dir;
};
std::vector<BeamRay> generate_beam_rays(const ParallelBeam& beam, std::uint64_t count, std::uint64_t seed);

}  // namespace microsim
