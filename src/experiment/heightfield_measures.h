// experiment: the library calls behind a heightfield decision (Model::heightfield), shared by the planner's
// pilots and the runs: the tile a decision plans (the trade table's size rule for an assembly, the user's own
// for a heightmap), the surface itself (through the SurfaceCache), and the VNDF measured on it.
#pragma once

#include "measure/heightfield_trade.h"
#include "experiment/plan.h"
#include "measure/surface_cache.h"
#include "measure/vndf.h"

#include <nlohmann/json.hpp>

namespace microsim::experiment {

// The tile of a heightfield decision at `seed` (the run's): an assembly sized by choose_surface_size on the
// built-in table (its supported range: microgeom::check_supported_range), or a heightmap read through
// `cache` (its own resolution; the bias the table predicts for it). `runnable` false with `why` when no tile
// meets the target (or the assembly cannot be built at the material's alphas). Pure but for reading a
// heightmap (one that cannot be read: std::invalid_argument naming the quantity's key).
struct SurfaceDecision {
  SurfacePlan plan;
  bool runnable = false;
  std::string why;
};
SurfaceDecision plan_surface(const SpecQuantity& quantity, const Decision& decision, std::uint64_t seed,
                             SurfaceCache& cache);

// The tile of an assembly at one alpha pair and `seed`: the cheapest size of the built-in trade table meeting
// `size` (its min_resolution: the assembly's supported range), then the assembly's own range at that size.
// Pure. `runnable` false with `why` when no size fits or the assembly cannot be built there.
SurfaceDecision plan_assembly_tile(const std::string& assembly, SizeRequest size, const std::pair<double, double>& alpha,
                                   std::uint64_t seed);

// The cache key of an assembly's planned tile.
SurfaceKey surface_key(const SurfacePlan& plan, const std::pair<double, double>& alpha);

// The surface of a heightfield decision: built (or read back) through the cache, or the user's heightmap.
// Throws Cancelled when the build is cancelled.
const microgeom::Heightfield& decision_surface(const Decision& decision, SurfaceCache& cache, const RunControl& run);
// The same, or null when the build was cancelled.
const microgeom::Heightfield* decision_surface_or_null(const Decision& decision, SurfaceCache& cache, const RunControl& run);

// What names the surface in a histogram's attributes: the heightmap's path, or "assembly smith <hash>".
std::string surface_label(const SurfacePlan& plan);

// The values of a heightfield VNDF, in the shape the report and a resumed run read: an "analysis" member of
// per-binning fits as the ellipsoid's (TV to Smith's D_v with the analytic NDF, its noise floor and
// chi-square), plus "heightfield": the TV to Smith with the tile's own NDF and the tracer's diagnostics.
nlohmann::json heightfield_vndf_values(const HeightfieldVndf& measurement, const std::vector<std::uint64_t>& unbinned,
                                       const SurfacePlan& plan);

}  // namespace microsim::experiment
