// experiment: the tile of a heightfield decision and its surface (heightfield_measures.h).
#include "experiment/heightfield_measures.h"

#include <fmt/core.h>

#include <stdexcept>

namespace microsim::experiment {

SurfaceDecision plan_surface(const SpecQuantity& q, const Decision& d, std::uint64_t seed, SurfaceCache& cache,
                             bool sees_heights) {
  if (q.surface.kind == SurfaceChoice::Kind::heightmap) {
    try {
      return plan_heightmap_tile(q.surface.name, q.target, alpha_anisotropy(d.alpha), cache);
    } catch (const std::runtime_error& e) {  // the user's heightmap cannot be read: bad input naming the key
      throw std::invalid_argument(fmt::format("{}.surface: {}", q.key, e.what()));
    }
  }
  return plan_assembly_tile(q.surface.name, {q.target, alpha_anisotropy(d.alpha), d.view.theta_deg, sees_heights}, d.alpha,
                            seed);
}

const microgeom::Heightfield& decision_surface(const Decision& decision, SurfaceCache& cache, const RunControl& run) {
  return tile_surface(decision.surface, decision.alpha, cache, run);
}

const microgeom::Heightfield* decision_surface_or_null(const Decision& decision, SurfaceCache& cache, const RunControl& run) {
  try {
    return &decision_surface(decision, cache, run);
  } catch (const Cancelled&) {
    return nullptr;
  }
}

}  // namespace microsim::experiment
