// experiment: the tile of a heightfield decision (Model::heightfield), shared by the planner's pilots and the
// runs: an assembly's sized by the trade table for the quantity's target and view, or the spec's heightmap
// (measure/heightfield_tile.h), and the decision's surface itself through the SurfaceCache.
#pragma once

#include "experiment/plan.h"
#include "measure/heightfield_tile.h"

namespace microsim::experiment {

// The tile of a heightfield decision at `seed` (the run's): an assembly sized by choose_surface_size on the
// built-in table (its supported range: microgeom::check_supported_range), or a heightmap read through `cache`.
// A heightmap that cannot be read: std::invalid_argument naming the quantity's key. `sees_heights`: the quantity
// sees the tile's heights (a wide tile), not only its visible normals (a VNDF, a validation against them).
SurfaceDecision plan_surface(const SpecQuantity& quantity, const Decision& decision, std::uint64_t seed,
                             SurfaceCache& cache, bool sees_heights);

// The surface of a heightfield decision (tile_surface of its plan at its alpha). Throws Cancelled when the build
// is cancelled; decision_surface_or_null: null then.
const microgeom::Heightfield& decision_surface(const Decision& decision, SurfaceCache& cache, const RunControl& run);
const microgeom::Heightfield* decision_surface_or_null(const Decision& decision, SurfaceCache& cache, const RunControl& run);

}  // namespace microsim::experiment
