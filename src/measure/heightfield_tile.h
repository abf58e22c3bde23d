// measure: the explicit tile a heightfield measurement is traced on (its SurfacePlan: heightfield_trade.h): an
// assembly's tile sized by the trade table at one alpha pair, or a user's heightmap with the bias the table
// predicts for it; the tile itself through a SurfaceCache; and a VNDF measured on it as values.
#pragma once

#include "measure/heightfield_trade.h"
#include "measure/surface_cache.h"
#include "measure/vndf.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace microsim {

// A tile and whether it can be measured: `runnable` false with `why` when no tile meets the target (or the
// assembly cannot be built at the alphas).
struct SurfaceDecision {
  SurfacePlan plan;
  bool runnable = false;
  std::string why;
};

// max(ax, ay) / min(ax, ay).
double alpha_anisotropy(const std::pair<double, double>& alpha);

// The tile of an assembly at one alpha pair and `seed`: the cheapest size of the built-in trade table meeting
// `size` (its min_resolution: the assembly's supported range), then the assembly's own range at that size.
// Pure. `runnable` false with `why` when no size fits or the assembly cannot be built there.
SurfaceDecision plan_assembly_tile(const std::string& assembly, SizeRequest size, const std::pair<double, double>& alpha,
                                   std::uint64_t seed);
// A user's heightmap read through `cache` (its own resolution; the bias the table predicts for it against a
// target TV `target_tv` at `anisotropy`). Throws std::runtime_error naming a file that cannot be read.
SurfaceDecision plan_heightmap_tile(const std::string& path, double target_tv, double anisotropy, SurfaceCache& cache);

// The cache key of an assembly's planned tile.
SurfaceKey surface_key(const SurfacePlan& plan, const std::pair<double, double>& alpha);
// The tile: built (or read back) through the cache, or the user's heightmap (std::invalid_argument when its
// heights are not those planned). Throws Cancelled when the build is cancelled.
const microgeom::Heightfield& tile_surface(const SurfacePlan& plan, const std::pair<double, double>& alpha,
                                           SurfaceCache& cache, const RunControl& run);
// What names the surface in a histogram's attributes: the heightmap's path, or "assembly smith <hash>".
std::string surface_label(const SurfacePlan& plan);

// The values of a heightfield VNDF, in the shape an experiment's report and a resumed run read: an "analysis"
// member of per-binning fits as the ellipsoid's (TV to Smith's D_v with the analytic NDF, its noise floor and
// chi-square), plus "heightfield": the TV to Smith with the tile's own NDF and the tracer's diagnostics.
nlohmann::json heightfield_vndf_values(const HeightfieldVndf& measurement, const std::vector<std::uint64_t>& unbinned,
                                       const SurfacePlan& plan);

}  // namespace microsim
