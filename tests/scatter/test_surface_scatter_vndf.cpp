// On a mirror heightfield, the directions leaving the first bounce of the multiple-scattering paths
// (scatter/surface_path.h), whether or not they escape, are exactly the mirror reflections of the
// first-hit normals that `trace vndf --surface` (trace_vndf_heightfield) histograms, for the same rays.
#include "scatter/surface_path.h"

#include "core/block_runner.h"
#include "microgeom/assembly.h"
#include "trace/masking.h"

#include <gtest/gtest.h>

#include <vector>

namespace microsim {
namespace {

// Histograms, in `binning`, the first-bounce normal of every path (the half vector of wi and the direction
// leaving the first facet, which for a mirror is that facet's normal), over the blocks of the VNDF run
// (its origins: block b's CounterRng(seed, b), two draws per ray). Every first direction is checked to
// be exactly reflect(wi, m) of the hit facet's normal m.
std::vector<std::uint64_t> first_bounce_normals(const HeightfieldScene& scene, const Vec3<double>& wi,
                                                const DirectionBinning& binning, std::uint64_t rays, std::uint64_t seed,
                                                std::uint64_t& hits, int& mismatches) {
  const SurfacePathTracer tracer(scene, Material::mirror(), wi, 1);
  std::vector<std::uint64_t> counts(std::size_t(binning.size()), 0);
  const BlockPlan plan{rays, kRaysPerBlock};
  SurfacePath path;
  std::vector<SurfacePathEvent> events;
  hits = 0;
  mismatches = 0;
  for (std::uint64_t block = 0; block < plan.blocks(); ++block) {
    CounterRng origins(seed, block);
    for (std::uint64_t i = 0; i < plan.units_in(block); ++i) {
      const double u0 = origins.uniform(), u1 = origins.uniform();
      events.clear();
      tracer.trace(tracer.origin(u0, u1), path_event_stream(seed, block, i, kRaysPerBlock), path, &events);
      if (events.empty()) continue;  // no facet met from above (a loss)
      ++hits;
      const Vec3<double> m = scene.field().triangle_normal(events[0].triangle);
      if (events[0].wo != reflect(wi, m)) ++mismatches;
      const auto bin = binning.bin_of((wi + events[0].wo).normalized());
      if (bin) ++counts[std::size_t(*bin)];
    }
  }
  return counts;
}

TEST(SurfaceScatterVndf, MirrorFirstBounceIsTheReflectedVndfNormal) {
  microgeom::AssemblyParams p;
  p.assembly = "smith";
  p.alpha_x = p.alpha_y = 0.8;
  p.resolution = 64;
  p.seed = 2;
  const auto field = microgeom::build_assembly(p);
  const HeightfieldScene scene(field);
  const DirectionBinning binning = DirectionBinning::sphere(31);
  for (const double theta : {30.0, 75.0}) {
    const Vec3<double> wi = direction_from_degrees(theta, 40.0);
    TraceOptions to;
    to.rays = 3 * kRaysPerBlock + 77;
    to.seed = 5;
    HeightfieldVndfDiagnostics diag;
    const TraceResult vndf = trace_vndf_heightfield(scene, wi, std::span(&binning, 1), to, &diag);
    std::uint64_t hits = 0;
    int mismatches = 0;
    const auto counts = first_bounce_normals(scene, wi, binning, to.rays, to.seed, hits, mismatches);
    EXPECT_EQ(mismatches, 0) << theta;
    EXPECT_EQ(hits, vndf.hits) << theta;
    EXPECT_EQ(counts, vndf.counts[0]) << theta;
    EXPECT_GT(vndf.hits, to.rays - 10);
    // Negative control: another seed's rays give other normals.
    const auto other = first_bounce_normals(scene, wi, binning, to.rays, to.seed + 1, hits, mismatches);
    EXPECT_NE(other, vndf.counts[0]) << theta;
  }
}

}  // namespace
}  // namespace microsim
