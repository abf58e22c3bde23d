// experiment: the one place a masking measurement gets its explicit heightfield (plan.h: Model::heightfield
// for a masking quantity): the spec's heightmap, or an assembly per alpha, both through the run's surface
// cache (surface_cache.h: built once per parameters' hash, kept in DIR/surfaces, read back on resumption).
#pragma once

#include "core/run_control.h"
#include "experiment/spec.h"
#include "experiment/surface_cache.h"
#include "microgeom/assembly.h"
#include "microgeom/heightfield.h"

#include <cstdint>
#include <string>
#include <utility>

namespace microsim::experiment {

// The assembly a masking decision builds (the quantity's surface is an assembly, or auto with conditional
// masking): the named assembly, or for auto the Smith-like one of the material's NDF (`smith` for GGX,
// `beckmann` for Beckmann), at `alpha`, the quantity's resolution, the default correlation length
// (microgeom::default_corr_cells) and `seed`. Pure.
microgeom::AssemblyParams masking_assembly_params(const SpecQuantity& quantity, const SpecMaterial& material,
                                                  std::pair<double, double> alpha, std::uint64_t seed);

// What the surface is, in words, for the plan's reason ("assembly smith 256^2, correlation length 16 cells,
// alpha 0.5, seed 7" or "heightmap PATH").
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
