// experiment: plans and results read back from results.json (run.h: plan_from_json, results_from_json), for
// a resumed run. The inverses of results_json.cpp: every member is checked, a missing or malformed one named.
#include "experiment/run.h"

#include <fmt/core.h>

#include <stdexcept>

namespace microsim::experiment {
namespace {

using nlohmann::json;

const json& at(const json& j, const std::string& key, const std::string& where) {
  if (!j.is_object() || !j.contains(key))
    throw std::invalid_argument(fmt::format("results.json: {} has no '{}'", where, key));
  return j.at(key);
}

template <class T> T get(const json& j, const std::string& key, const std::string& where) {
  try {
    return at(j, key, where).get<T>();
  } catch (const json::exception&) {
    throw std::invalid_argument(fmt::format("results.json: {}.{} has the wrong type", where, key));
  }
}

Model model_named(const std::string& name, const std::string& where) {
  for (Model m : {Model::analytic, Model::ellipsoid_oracle, Model::smith_walk, Model::heightfield, Model::analytic_validator})
    if (to_string(m) == name) return m;
  throw std::invalid_argument(fmt::format("results.json: {}.model: unknown model '{}'", where, name));
}

std::size_t quantity_index(const ExperimentSpec& spec, const std::string& key, const std::string& where) {
  for (std::size_t i = 0; i < spec.quantities.size(); ++i)
    if (spec.quantities[i].key == key) return i;
  throw std::invalid_argument(fmt::format("results.json: {}.quantity: '{}' is not a quantity of the spec", where, key));
}

SurfacePlan surface_plan_from_json(const json& j, const std::string& where) {
  SurfacePlan p;
  p.kind = get<std::string>(j, "kind", where);
  p.name = get<std::string>(j, "name", where);
  p.ndf = get<std::string>(j, "ndf", where);
  p.resolution = get<int>(j, "resolution", where);
  p.corr_cells = get<double>(j, "corr_cells", where);
  p.ndf_match = get<std::string>(j, "ndf_match", where);
  p.seed = get<std::uint64_t>(j, "seed", where);
  p.bias = get<double>(j, "bias", where);
  p.hash = get<std::string>(j, "hash", where);
  p.reason = get<std::string>(j, "reason", where);
  return p;
}

Decision decision_from_json(const json& j, const ExperimentSpec& spec, const std::string& where) {
  Decision d;
  d.quantity = quantity_index(spec, get<std::string>(j, "quantity", where), where);
  d.label = get<std::string>(j, "measurement", where);
  d.model = {model_named(get<std::string>(j, "model", where), where), get<std::string>(j, "model_reason", where)};
  if (j.contains("alpha")) d.alpha = get<std::pair<double, double>>(j, "alpha", where);
  if (j.contains("view"))
    d.view = {get<double>(j["view"], "theta_deg", where + ".view"), get<double>(j["view"], "phi_deg", where + ".view")};
  d.units = get<std::uint64_t>(j, "units", where);
  d.unit = get<std::string>(j, "unit", where);
  d.count_reason = get<std::string>(j, "count_reason", where);
  d.order_cap = get<int>(j, "order_cap", where);
  d.cap_reason = get<std::string>(j, "cap_reason", where);
  d.tolerance = j.contains("tolerance") ? get<double>(j, "tolerance", where) : 0.0;
  d.predicted_seconds = get<double>(j, "predicted_seconds", where);
  const json& pilot = at(j, "pilot", where);
  d.pilot_units = get<std::uint64_t>(pilot, "units", where + ".pilot");
  d.pilot_seconds = get<double>(pilot, "seconds", where + ".pilot");
  d.pilot_error = get<double>(pilot, "error", where + ".pilot");
  d.runnable = get<bool>(j, "runnable", where);
  // Sampled per-order lobes (the walk's, a tile's) resolve the orders their plan targeted (a plan of an earlier
  // version has none).
  if (d.runnable && spec.quantities[d.quantity].kind == QuantityKind::scattering && d.model.model != Model::analytic)
    d.targeted_orders = get<std::vector<int>>(j, "targeted_orders", where);
  if (j.contains("not_runnable")) d.not_runnable = get<std::string>(j, "not_runnable", where);
  if (j.contains("surface")) d.surface = surface_plan_from_json(j["surface"], where + ".surface");
  if (j.contains("realisation")) d.realisation = get<int>(j, "realisation", where);
  return d;
}

RoundRecord round_from_json(const json& j, const std::string& where) {
  return {get<std::uint64_t>(j, "units", where),  get<std::uint64_t>(j, "planned", where),
          get<std::uint64_t>(j, "blocks_done", where), get<bool>(j, "partial", where),
          get<std::uint64_t>(j, "seed", where),   get<double>(j, "tolerance", where),
          get<double>(j, "seconds", where),       get<double>(j, "achieved", where)};
}

MeasurementResult measurement_from_json(const json& j, const Decision& d, const std::string& where) {
  MeasurementResult m;
  m.decision = d;
  if (get<std::string>(j, "measurement", where) != d.label)
    throw std::invalid_argument(fmt::format("results.json: {} is not the plan's '{}'", where, d.label));
  m.ran = get<bool>(j, "ran", where);
  m.partial = get<bool>(j, "partial", where);
  m.target = get<double>(j, "target", where);
  m.error_measure = get<std::string>(j, "error_measure", where);
  m.achieved = get<double>(j, "achieved", where);
  m.met = get<bool>(j, "met", where);
  const json& rounds = at(j, "rounds", where);
  for (std::size_t r = 0; r < rounds.size(); ++r) m.rounds.push_back(round_from_json(rounds[r], fmt::format("{}.rounds[{}]", where, r)));
  const json& cost = at(j, "cost", where);
  m.units = get<std::uint64_t>(cost, "units", where + ".cost");
  m.rays = get<std::uint64_t>(cost, "rays", where + ".cost");
  m.seconds = get<double>(cost, "seconds", where + ".cost");
  m.values = at(j, "values", where);
  if (m.values.is_object() && m.values.contains("unbinned"))
    m.unbinned = get<std::vector<std::uint64_t>>(m.values, "unbinned", where + ".values");
  if (j.contains("round_tables")) m.round_tables = get<std::vector<json>>(j, "round_tables", where);
  if (m.round_tables.size() > m.rounds.size())
    throw std::invalid_argument(fmt::format("results.json: {}: more round tables than rounds", where));
  return m;
}

}  // namespace

ExperimentPlan plan_from_json(const nlohmann::json& plan, const ExperimentSpec& spec) {
  ExperimentPlan p;
  const json& decisions = at(plan, "decisions", "plan");
  if (!decisions.is_array()) throw std::invalid_argument("results.json: plan.decisions is not an array");
  for (std::size_t i = 0; i < decisions.size(); ++i)
    p.decisions.push_back(decision_from_json(decisions[i], spec, fmt::format("plan.decisions[{}]", i)));
  p.pilot_seconds = get<double>(plan, "pilot_seconds", "plan");
  p.predicted_seconds = get<double>(plan, "predicted_seconds", "plan");
  return p;
}

ExperimentResults results_from_json(const nlohmann::json& results, const ExperimentPlan& plan) {
  ExperimentResults r;
  const json& measurements = at(results, "measurements", "results");
  if (!measurements.is_array() || measurements.size() > plan.decisions.size())
    throw std::invalid_argument("results.json: results.measurements is not an array of at most the plan's size");
  for (std::size_t i = 0; i < measurements.size(); ++i)
    r.measurements.push_back(measurement_from_json(measurements[i], plan.decisions[i], fmt::format("results.measurements[{}]", i)));
  r.partial = get<bool>(results, "partial", "results");
  r.seconds = get<double>(results, "seconds", "results");
  return r;
}

}  // namespace microsim::experiment
