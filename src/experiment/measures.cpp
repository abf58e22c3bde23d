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

namespace {

const nlohmann::json& table_member(const nlohmann::json& j, const std::string& key) {
  if (!j.is_object() || !j.contains(key)) throw std::invalid_argument(fmt::format("albedo table JSON: no '{}'", key));
  return j.at(key);
}

std::vector<double> numbers_of(const nlohmann::json& j, const std::string& what) {
  if (!j.is_array()) throw std::invalid_argument(fmt::format("albedo table JSON: '{}' is not an array", what));
  std::vector<double> v;
  for (const nlohmann::json& x : j) {
    if (!x.is_number() && !x.is_null())
      throw std::invalid_argument(fmt::format("albedo table JSON: '{}' holds a non-number", what));
    v.push_back(x.is_null() ? std::numeric_limits<double>::quiet_NaN() : x.get<double>());
  }
  return v;
}

std::vector<Estimate> estimates_of(const nlohmann::json& values, const nlohmann::json& errors, const std::string& what) {
  const std::vector<double> v = numbers_of(values, what), e = numbers_of(errors, what + " error");
  if (v.size() != e.size()) throw std::invalid_argument(fmt::format("albedo table JSON: '{}' sizes differ", what));
  std::vector<Estimate> out;
  for (std::size_t i = 0; i < v.size(); ++i) out.push_back({v[i], e[i]});
  return out;
}

AlbedoQuantity quantity_from_json(const std::string& name, const nlohmann::json& q) {
  AlbedoQuantity out{name, {}, estimates_of(table_member(q, "average"), table_member(q, "average_error"), name)};
  const nlohmann::json &values = table_member(q, "value"), &errors = table_member(q, "error");
  if (!values.is_array() || !errors.is_array() || values.size() != errors.size())
    throw std::invalid_argument(fmt::format("albedo table JSON: '{}' rows differ", name));
  for (std::size_t a = 0; a < values.size(); ++a)
    for (const Estimate& e : estimates_of(values[a], errors[a], name)) out.cells.push_back(e);
  return out;
}

}  // namespace

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

AlbedoTable albedo_table_from_json(const nlohmann::json& j, const AlbedoTableRequest& request) {
  AlbedoTable t;
  t.request = request;
  t.alphas = numbers_of(table_member(j, "alphas"), "alphas");
  t.mus = numbers_of(table_member(j, "mus"), "mus");
  t.mu_weights = numbers_of(table_member(j, "mu_weights"), "mu_weights");
  t.row_seconds = numbers_of(table_member(j, "row_seconds"), "row_seconds");
  t.seconds = table_member(j, "seconds").get<double>();
  t.partial = table_member(j, "partial").get<bool>();
  for (const nlohmann::json& name : table_member(j, "quantity_names")) {
    const std::string n = name.get<std::string>();
    t.quantities.push_back(quantity_from_json(n, table_member(table_member(j, "quantities"), n)));
    if (t.quantities.back().cells.size() != t.alphas.size() * t.mus.size())
      throw std::invalid_argument(fmt::format("albedo table JSON: '{}' has {} cells, not alphas x mus", n,
                                              t.quantities.back().cells.size()));
  }
  return t;
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
  r.run = run;
  return r;
}

}  // namespace microsim::experiment
