// experiment: an albedo table on explicit surfaces (kind "albedo", Model::heightfield: the spec names an
// assembly). One tile per alpha of the material, every tile of the same size and seed (SurfacePlan; cache keys
// surface_key(plan, {alpha, alpha})), built once through the SurfaceCache; each cell (alpha, mu) traces its own
// paths from its own seed on its alpha's tile (scatter/albedo_table.h surface_albedo_cells), so that any split
// of the cells over ranks or shards gives the one-process table bit for bit.
//
// The tile's size. The albedo is an expectation over the first visible normal of a bounded weight (the
// path's escaping energy, in [0, 1]), so a tile whose visible normals are TV t from the infinite surface's
// moves it by at most about t (|E_P - E_Q| <= TV(P, Q) for a weight in [0, 1]; the traced VNDF departs from
// the tile's NDF by about the NDF's TV, docs/surfaces.md 8.1). A relative target r on every targeted albedo
// is then an absolute bias r E_min, E_min the smallest targeted albedo of the table: taken from the analytic
// single-scattering table (E1 <= E, E1_R <= E_R, E1_T <= E_T: a lower bound of each). The tile is the trade
// table's cheapest with bias <= kBiasShare r E_min, wide (scattering_min_tiles: the heights are seen) and
// wide enough for the most grazing mu (grazing_min_tiles). That is a rule of thumb, not a bound: the finite
// tile's masking also differs, which the width rules keep below the spread of realisations they measured.
// The target itself is the Monte Carlo error on these surfaces: the spread between realisations is not in it.
//
// The order cap: as the walk's (plan_kinds.h walk_order_cap), from a pilot on the roughest alpha's tile; single
// scattering (orders = single) is capped at 1. The count: a pilot table of pilot_paths paths per cell.
// A heightmap is one surface at one alpha: an albedo table on it is not planned (runnable false, says why).
#pragma once

#include "experiment/heightfield_measures.h"
#include "experiment/plan.h"
#include "measure/surface_cache.h"
#include "scatter/albedo_table.h"

#include <optional>
#include <vector>

namespace microsim::experiment {

// The tiles of an albedo quantity whose model is a heightfield (the rule above) at the run's `seed`: the first
// alpha's plan, every alpha's key hash joined in `hash`; runnable false with why for a heightmap or when no
// tile fits. Runs the analytic table for E_min (Cancelled when run.cancel stops it).
SurfaceDecision plan_albedo_surfaces(const ExperimentSpec& spec, const SpecQuantity& quantity, std::uint64_t seed,
                                     const RunControl& run);

// The request of a surface albedo decision (albedo_request, model surface, with the tile's resolution).
AlbedoTableRequest surface_albedo_request(const ExperimentSpec& spec, const Decision& decision, std::uint64_t paths,
                                          int max_order, std::uint64_t seed, const RunControl& run);

// The request of a round of a sampled albedo decision: the walk's (albedo_request), or on its tiles
// (surface_albedo_request), at the decision's order cap.
AlbedoTableRequest sampled_albedo_request(const ExperimentSpec& spec, const Decision& decision, std::uint64_t paths,
                                          std::uint64_t seed, const RunControl& run);

// The cells [cells.begin, cells.end) of a surface albedo `request` (its alphas the table's rows) on the tiles
// of `plan` from `surfaces` (built or read back as needed; the Embree scene of one tile at a time,
// SurfaceCache::scene_for). nullopt when cancelled, during a build too.
std::optional<AlbedoCells> surface_albedo_cells_of(const AlbedoTableRequest& request, const BlockRange& cells,
                                                   const SurfacePlan& plan, SurfaceCache& surfaces);

}  // namespace microsim::experiment
