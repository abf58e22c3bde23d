// experiment: the heightfield of a masking measurement (masking_surface.h).
#include "experiment/masking_surface.h"
#include "experiment/plan.h"

#include <fmt/core.h>

#include <algorithm>

namespace microsim::experiment {

std::uint64_t masking_surface_seed(std::uint64_t run_seed, int realisation) {
  constexpr std::uint64_t kRealisationPurpose = 33;  // derived_seed purposes: plan_kinds.h's below 32, the masking pilot's 32
  return realisation == 0 ? run_seed : derived_seed(run_seed, kRealisationPurpose, std::uint64_t(realisation));
}

microgeom::AssemblyParams masking_assembly_params(const SpecQuantity& q, const SpecMaterial& m,
                                                  std::pair<double, double> alpha, std::uint64_t seed) {
  microgeom::AssemblyParams p;
  p.assembly = q.surface.kind == SurfaceChoice::Kind::assembly ? q.surface.name
                                                               : std::string(microgeom::plain_assembly(m.ndf));
  p.alpha_x = alpha.first;
  p.alpha_y = alpha.second;
  p.resolution = q.resolution;
  p.seed = seed;
  p.corr_cells = masking_corr_cells(p.assembly, q.resolution);
  return p;
}

double masking_corr_cells(const std::string& assembly, int resolution) {
  const microgeom::AssemblyInfo* info = microgeom::find_assembly(assembly);
  if (info == nullptr || info->reference != NdfKind::ggx) return microgeom::default_corr_cells(resolution);
  return std::clamp(double(resolution) / kMaskingMinTiles, kMaskingMinCorrCells, kMaskingMaxCorrCells);
}

std::string masking_surface_text(const SpecQuantity& q, const SpecMaterial& m, std::pair<double, double> alpha,
                                 std::uint64_t seed) {
  if (q.surface.kind == SurfaceChoice::Kind::heightmap) return "heightmap " + q.surface.name;
  const microgeom::AssemblyParams p = masking_assembly_params(q, m, alpha, seed);
  const double tiles = p.resolution / p.corr_cells;
  return fmt::format("assembly {} {}^2, correlation length {} cells ({} l per tile{}), alpha ({}, {}), seed {}",
                     p.assembly, p.resolution, p.corr_cells, tiles,
                     tiles < kMaskingMinTiles ? fmt::format(": narrower than {} l, its masking biased beyond the "
                                                            "spread of realisations", kMaskingMinTiles) : "",
                     p.alpha_x, p.alpha_y, p.seed);
}

SurfaceKey masking_surface_key(const SpecQuantity& q, const SpecMaterial& m, std::pair<double, double> alpha,
                               std::uint64_t seed) {
  const microgeom::AssemblyParams p = masking_assembly_params(q, m, alpha, seed);
  SurfaceKey key;
  key.assembly = p.assembly;
  key.ndf = to_string(m.ndf);
  key.alpha_x = p.alpha_x;
  key.alpha_y = p.alpha_y;
  key.resolution = p.resolution;
  key.corr_cells = p.corr_cells;
  key.ndf_match = "radial";
  key.seed = p.seed;
  return key;
}

const microgeom::Heightfield& acquire_masking_surface(const SpecQuantity& q, const SpecMaterial& m,
                                                      std::pair<double, double> alpha, std::uint64_t seed,
                                                      SurfaceCache& cache, const RunControl& run) {
  if (q.surface.kind == SurfaceChoice::Kind::heightmap) return cache.heightmap(q.surface.name);
  return cache.surface_for(masking_surface_key(q, m, alpha, seed), run);
}

}  // namespace microsim::experiment
