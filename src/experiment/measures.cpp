// experiment: the library calls behind a decision (measures.h).
#include "experiment/measures.h"

#include <cmath>
#include <limits>

namespace microsim::experiment {

Material albedo_table_material(const SpecMaterial& material) {
  return material.facet.kind() == MaterialKind::conductor ? Material::mirror() : material.facet;
}

bool albedo_target_applies(const SpecQuantity& quantity, std::string_view table_quantity) {
  return table_quantity.starts_with(quantity.orders == Orders::single ? "E1" : "E");
}

std::string albedo_target_text(const SpecQuantity& quantity) { return quantity.orders == Orders::single ? "E1*" : "E*"; }

AlbedoTableRequest albedo_request(const ExperimentSpec& spec, const SpecQuantity& quantity, Model model,
                                  std::uint64_t paths, int max_order, double tolerance, std::uint64_t seed,
                                  const RunControl& run) {
  const SpecMaterial& m = spec.material(quantity.material);
  AlbedoTableRequest r;
  r.model = model == Model::smith_walk ? AlbedoModel::smith_walk : AlbedoModel::analytic;
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
  r.run = run;
  return r;
}

namespace {
double relative_error(const Estimate& e) {
  if (e.standard_error == 0) return 0;
  return e.value != 0 ? e.standard_error / std::abs(e.value) : std::numeric_limits<double>::infinity();
}
}  // namespace

double worst_relative_error(const AlbedoTable& table, const SpecQuantity& quantity) {
  double worst = 0;
  for (const AlbedoQuantity& q : table.quantities) {
    if (!albedo_target_applies(quantity, q.name)) continue;
    for (const Estimate& e : q.cells) worst = std::max(worst, relative_error(e));
    for (const Estimate& e : q.average) worst = std::max(worst, relative_error(e));
  }
  return worst;
}

double vndf_noise_floor(const EllipsoidVndf& measurement) {
  double worst = 0;
  for (const TraceFit& f : measurement.analysis.fits) worst = std::max(worst, f.noise_floor_tv);
  return worst;
}

double vndf_total_variation(const EllipsoidVndf& measurement) {
  double worst = 0;
  for (const TraceFit& f : measurement.analysis.fits) worst = std::max(worst, f.total_variation);
  return worst;
}

}  // namespace microsim::experiment
