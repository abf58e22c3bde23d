// experiment: the one place a masking measurement gets its explicit heightfield (plan.h: Model::heightfield
// for a masking quantity): the spec's heightmap loaded, or an assembly built in-process with microgeom per
// alpha. Kept small on purpose: a surface cache (built once per parameters' hash, on disk) goes behind
// acquire_masking_surface without changing its callers.
#pragma once

#include "core/run_control.h"
#include "experiment/spec.h"
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

// The heightfield: the heightmap (the quantity's surface is a heightmap .exr), else the assembly of
// masking_assembly_params, built now. Throws Cancelled when run.cancel is set during a build, and what
// load_heightmap_exr and build_assembly throw (bad input: std::invalid_argument).
microgeom::Heightfield acquire_masking_surface(const SpecQuantity& quantity, const SpecMaterial& material,
                                               std::pair<double, double> alpha, std::uint64_t seed,
                                               const RunControl& run);

}  // namespace microsim::experiment
