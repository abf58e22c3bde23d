// experiment: the heightfield of a masking measurement (masking_surface.h).
#include "experiment/masking_surface.h"

#include <fmt/core.h>

namespace microsim::experiment {

microgeom::AssemblyParams masking_assembly_params(const SpecQuantity& q, const SpecMaterial& m,
                                                  std::pair<double, double> alpha, std::uint64_t seed) {
  microgeom::AssemblyParams p;
  p.assembly = q.surface.kind == SurfaceChoice::Kind::assembly ? q.surface.name
                                                               : (m.ndf == WalkNdf::ggx ? "smith" : "beckmann");
  p.alpha_x = alpha.first;
  p.alpha_y = alpha.second;
  p.resolution = q.resolution;
  p.seed = seed;
  p.corr_cells = microgeom::default_corr_cells(q.resolution);
  return p;
}

std::string masking_surface_text(const SpecQuantity& q, const SpecMaterial& m, std::pair<double, double> alpha,
                                 std::uint64_t seed) {
  if (q.surface.kind == SurfaceChoice::Kind::heightmap) return "heightmap " + q.surface.name;
  const microgeom::AssemblyParams p = masking_assembly_params(q, m, alpha, seed);
  return fmt::format("assembly {} {}^2, correlation length {} cells, alpha ({}, {}), seed {}", p.assembly,
                     p.resolution, p.corr_cells, p.alpha_x, p.alpha_y, p.seed);
}

microgeom::Heightfield acquire_masking_surface(const SpecQuantity& q, const SpecMaterial& m,
                                               std::pair<double, double> alpha, std::uint64_t seed,
                                               const RunControl& run) {
  if (q.surface.kind == SurfaceChoice::Kind::heightmap) return microgeom::load_heightmap_exr(q.surface.name);
  try {
    return microgeom::build_assembly(masking_assembly_params(q, m, alpha, seed), nullptr, {},
                                     [&run] { return run.cancelled(); });
  } catch (const microgeom::BuildCancelled&) {
    throw Cancelled("masking surface build");
  }
}

}  // namespace microsim::experiment
