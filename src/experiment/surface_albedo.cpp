// experiment: an albedo table on explicit surfaces, its plan and its cells (surface_albedo.h).
#include "experiment/surface_albedo.h"

#include "core/wall_clock.h"
#include "experiment/heightfield_measures.h"
#include "measure/albedo.h"
#include "measure/heightfield_trade.h"
#include "experiment/measures.h"
#include "scatter/surface_scatter.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

namespace microsim::experiment {
namespace {

// E_min: the smallest single-scattering albedo of the table (analytic, to 1e-4 absolute; every side it has),
// a lower bound of every albedo the target applies to (all orders hold order 1 on each side).
double smallest_targeted_albedo(const ExperimentSpec& spec, const SpecQuantity& q, const RunControl& run) {
  const AlbedoTable t = measure_albedo_table(albedo_request(spec, q, Model::analytic, 1, 0, 1e-4, 1, run));
  if (t.partial) throw Cancelled("plan: the smallest albedo of the table");
  double smallest = 1;
  for (const AlbedoQuantity& quantity : t.quantities)
    for (const Estimate& e : quantity.cells) smallest = std::min(smallest, e.value - e.standard_error);
  return std::max(smallest, 0.0);
}

// The same tile size at every alpha (the trade table is in normalised slope space: isotropic alphas share
// its rows); the plan of the first alpha with every alpha's key hash joined, or why none fits.
SurfaceDecision plan_albedo_tiles(const SpecQuantity& q, const std::vector<double>& alphas, double smallest,
                                  std::uint64_t seed, double mu_min) {
  const double grazing_deg = std::acos(mu_min) * 180 / std::numbers::pi;
  const double tv = std::stod(fmt::format("{:.3g}", q.target * smallest));  // as the reasons print it
  const SizeRequest size{tv, 1, grazing_deg, true};
  SurfaceDecision first = plan_assembly_tile(q.surface.name, size, {alphas.front(), alphas.front()}, seed);
  first.plan.reason = fmt::format("albedo bias <= TV of the visible normals: target {} x smallest targeted albedo {:.3g} "
                                  "= TV {:.3g} (most grazing mu {:.3g}: theta {:.3g} deg); ",
                                  q.target, smallest, tv, mu_min, grazing_deg) + first.plan.reason;
  if (!first.runnable) {
    first.why = first.plan.reason;
    return first;
  }
  for (std::size_t i = 1; i < alphas.size(); ++i) {
    const SurfaceDecision other = plan_assembly_tile(q.surface.name, size, {alphas[i], alphas[i]}, seed);
    if (!other.runnable) return other;
    first.plan.hash += "," + other.plan.hash;
  }
  return first;
}

}  // namespace

SurfaceDecision plan_albedo_surfaces(const ExperimentSpec& spec, const SpecQuantity& q, std::uint64_t seed,
                                     const RunControl& run) {
  if (q.surface.kind != SurfaceChoice::Kind::assembly) {
    SurfaceDecision none;
    none.why = "an albedo table needs a tile per alpha: a heightmap is one surface at one alpha (name an assembly)";
    return none;
  }
  std::vector<double> alphas;
  for (const auto& a : spec.material(q.material).alphas) alphas.push_back(a.first);
  return plan_albedo_tiles(q, alphas, smallest_targeted_albedo(spec, q, run), seed, gauss_legendre_mus(q.mus).mus.front());
}

AlbedoTableRequest surface_albedo_request(const ExperimentSpec& spec, const Decision& d, std::uint64_t paths,
                                          int max_order, std::uint64_t seed, const RunControl& run) {
  AlbedoTableRequest r = albedo_request(spec, spec.quantities[d.quantity], Model::heightfield, paths, max_order, 0,
                                        seed, run);
  r.resolution = d.surface.resolution;
  return r;
}

AlbedoTableRequest sampled_albedo_request(const ExperimentSpec& spec, const Decision& d, std::uint64_t paths,
                                          std::uint64_t seed, const RunControl& run) {
  if (d.model.model == Model::heightfield) return surface_albedo_request(spec, d, paths, d.order_cap, seed, run);
  return albedo_request(spec, spec.quantities[d.quantity], Model::smith_walk, paths, d.order_cap, 0, seed, run);
}

std::optional<AlbedoCells> surface_albedo_cells_of(const AlbedoTableRequest& request, const BlockRange& cells,
                                                   const SurfacePlan& plan, SurfaceCache& surfaces) {
  const auto paths = [&](std::size_t row, const ScatterOptions& o) {
    const double alpha = request.alphas.at(row);
    const microgeom::Heightfield& field = surfaces.surface_for(surface_key(plan, {alpha, alpha}), request.run);
    return scatter_on_surface(surfaces.scene_for(field), o);
  };
  try {
    return surface_albedo_cells(request, cells, paths);
  } catch (const Cancelled&) {  // a tile's build
    return std::nullopt;
  }
}

}  // namespace microsim::experiment
