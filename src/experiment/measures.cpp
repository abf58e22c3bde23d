// experiment: the library calls behind a decision (measures.h).
#include "experiment/measures.h"

#include "scatter/analytic_scatter.h"

#include <fmt/core.h>

#include <cmath>
#include <limits>
#include <stdexcept>

namespace microsim::experiment {

Material albedo_table_material(const SpecMaterial& material) {
  return material.facet.kind() == MaterialKind::conductor ? Material::mirror() : material.facet;
}

VndfRequest vndf_request(const ExperimentSpec& spec, const Decision& decision, std::uint64_t rays, std::uint64_t seed,
                         const RunControl& run) {
  VndfRequest request;
  request.theta_deg = decision.view.theta_deg;
  request.phi_deg = decision.view.phi_deg;
  request.rays = rays;
  request.seed = seed;
  request.rows = spec.quantities[decision.quantity].rows;
  request.run = run;
  return request;
}

WalkKernel walk_kernel_of(const SpecQuantity& quantity) {
  return quantity.settings.value("walk_kernel", "scalar") == "lanes" ? WalkKernel::lanes : WalkKernel::scalar;
}

SmithMicrosurface scatter_surface(const SpecMaterial& material, const Decision& decision) {
  return {material.ndf, decision.alpha.first, decision.alpha.second, HeightDistribution::uniform};
}

ScatterOptions scatter_request(const SpecMaterial& material, const Decision& decision, std::uint64_t paths,
                               std::uint64_t seed, const RunControl& run) {
  ScatterOptions o;
  o.wi = direction_from_degrees(decision.view.theta_deg, decision.view.phi_deg);
  o.material = material.facet;
  o.paths = paths;
  o.seed = seed;
  o.max_order = decision.order_cap;
  o.rows = kScatterRows;
  o.run = run;
  return o;
}

ScatterExpectation analytic_scatter_lobe(const SpecMaterial& material, const Decision& decision, const RunControl& run) {
  return measure_analytic_scatter(material.ndf, decision.alpha,
                                  direction_from_degrees(decision.view.theta_deg, decision.view.phi_deg), material.facet,
                                  kScatterRows, run);
}

AlbedoTableRequest albedo_request(const ExperimentSpec& spec, const SpecQuantity& quantity, Model model,
                                  std::uint64_t paths, int max_order, double tolerance, std::uint64_t seed,
                                  const RunControl& run) {
  const SpecMaterial& m = spec.material(quantity.material);
  AlbedoTableRequest r;
  r.model = model == Model::smith_walk   ? AlbedoModel::smith_walk
            : model == Model::heightfield ? AlbedoModel::surface
                                          : AlbedoModel::analytic;
  r.ndf = m.ndf;
  r.material = albedo_table_material(m);
  r.inside = quantity.inside;
  r.alphas.clear();
  for (const auto& a : m.alphas) r.alphas.push_back(a.first);
  r.mus = quantity.mus;
  if (tolerance > 0) r.tolerance = tolerance;
  r.paths = paths;
  r.seed = seed;
  if (max_order > 0) r.max_order = max_order;
  if (r.model == AlbedoModel::smith_walk) r.walk_kernel = walk_kernel_of(quantity);
  r.run = run;
  return r;
}

}  // namespace microsim::experiment
