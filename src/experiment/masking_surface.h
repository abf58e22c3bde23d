// experiment: the one place a masking measurement gets its explicit heightfield (plan.h: Model::heightfield
// for a masking quantity): the spec's heightmap, or an assembly per alpha, both through the run's surface
// cache (surface_cache.h: built once per parameters' hash, kept in DIR/surfaces, read back on resumption).
#pragma once

#include "core/run_control.h"
#include "experiment/spec.h"
#include "measure/surface_cache.h"
#include "microgeom/assembly.h"
#include "microgeom/heightfield.h"

#include <cstdint>
#include <string>
#include <utility>

namespace microsim::experiment {

// The correlation length (cells) of a masking tile of N^2: masking sees the heights, and what decides its bias
// is the tile's width in correlation lengths, not the cells per length (docs/heightfield-trade.md 3, smith,
// alpha 0.5, 60-85 deg: below 64 l every statistic moves beyond the spread of three realisations, from 64 l
// on none does; at a fixed 64 l, l = 4, 8, 16 and 32 cells agree within that spread). So a GGX-reference
// assembly gets l = N / 64 clamped to [4, 16] (4: the smallest measured; 16: the builder's default): 64 l
// from N = 256 on, more from N = 2048; a smaller N is narrower than 64 l (the plan's text says its width).
// Other assemblies keep microgeom::default_corr_cells (the Beckmann control's slopes need l >= 16).
inline constexpr double kMaskingMinTiles = 64;
inline constexpr double kMaskingMinCorrCells = 4;
inline constexpr double kMaskingMaxCorrCells = 16;
double masking_corr_cells(const std::string& assembly, int resolution);

// The build seed of realisation k of a masking quantity's surface at the run's seed: the run's own for k = 0,
// else a seed derived from it (independent surfaces of the same assembly, NDF and size).
std::uint64_t masking_surface_seed(std::uint64_t run_seed, int realisation);

// The assembly a masking decision builds (the quantity's surface is an assembly, or auto with conditional
// masking): the named assembly, or for auto the Smith-like one of the material's NDF (`smith` for GGX,
// `beckmann` for Beckmann), at `alpha`, the quantity's resolution, masking_corr_cells and `seed`. Pure.
microgeom::AssemblyParams masking_assembly_params(const SpecQuantity& quantity, const SpecMaterial& material,
                                                  std::pair<double, double> alpha, std::uint64_t seed);

// What the surface is, in words, for the plan's reason ("assembly smith 256^2, correlation length 4 cells (64
// l per tile), alpha 0.5, seed 7" or "heightmap PATH").
std::string masking_surface_text(const SpecQuantity& quantity, const SpecMaterial& material,
                                 std::pair<double, double> alpha, std::uint64_t seed);

// The cache key of masking_assembly_params (the material's NDF, radial NDF matching: build_assembly's default).
SurfaceKey masking_surface_key(const SpecQuantity& quantity, const SpecMaterial& material,
                               std::pair<double, double> alpha, std::uint64_t seed);
// The heightfield, from `cache`: the heightmap (the quantity's surface is a heightmap .exr), else the
// assembly of masking_surface_key (built once, or read back). Throws Cancelled when run.cancel is set during
// a build, and what the cache throws for a heightmap it cannot read or a build it refuses.
const microgeom::Heightfield& acquire_masking_surface(const SpecQuantity& quantity, const SpecMaterial& material,
                                                      std::pair<double, double> alpha, std::uint64_t seed,
                                                      SurfaceCache& cache, const RunControl& run);

}  // namespace microsim::experiment
