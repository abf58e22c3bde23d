// experiment: plans and results as JSON, the content of results.json (run.h: plan_json, results_json), and read
// back for a resumed run (plan_from_json, results_from_json). Each struct's plain members are one table of
// JSON key <-> member, used both to write and to read; on reading every member is checked, a missing or
// malformed one named.
#include "experiment/run.h"
#include "experiment/measurement.h"
#include "experiment/verdict.h"

#include <fmt/core.h>

#include <functional>
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

// One member of a struct S as a JSON key, both ways.
template <class S> struct Field {
  const char* key;
  std::function<json(const S&)> write;
  std::function<void(S&, const json&, const std::string&)> read;
};

template <class S, class T> Field<S> field(const char* key, T S::*member) {
  return {key, [member](const S& s) { return json(s.*member); },
          [key, member](S& s, const json& j, const std::string& where) { s.*member = get<T>(j, key, where); }};
}

template <class S> void write_fields(const S& s, const std::vector<Field<S>>& fields, json& j) {
  for (const Field<S>& f : fields) j[f.key] = f.write(s);
}

template <class S> void read_fields(S& s, const std::vector<Field<S>>& fields, const json& j, const std::string& where) {
  for (const Field<S>& f : fields) f.read(s, j, where);
}

const std::vector<Field<SurfacePlan>> kSurfacePlan = {
    field("kind", &SurfacePlan::kind),   field("name", &SurfacePlan::name),   field("ndf", &SurfacePlan::ndf),
    field("resolution", &SurfacePlan::resolution), field("corr_cells", &SurfacePlan::corr_cells),
    field("ndf_match", &SurfacePlan::ndf_match), field("seed", &SurfacePlan::seed), field("bias", &SurfacePlan::bias),
    field("hash", &SurfacePlan::hash),   field("reason", &SurfacePlan::reason)};

Model model_named(const std::string& name, const std::string& where) {
  for (Model m : {Model::analytic, Model::ellipsoid_oracle, Model::smith_walk, Model::heightfield, Model::analytic_validator})
    if (to_string(m) == name) return m;
  throw std::invalid_argument(fmt::format("results.json: {}.model: unknown model '{}'", where, name));
}

// A decision's members but its quantity and the optional ones (decision_json).
const std::vector<Field<Decision>> kDecision = {
    field("measurement", &Decision::label),
    {"model", [](const Decision& d) { return json(to_string(d.model.model)); },
     [](Decision& d, const json& j, const std::string& w) { d.model.model = model_named(get<std::string>(j, "model", w), w); }},
    {"model_reason", [](const Decision& d) { return json(d.model.reason); },
     [](Decision& d, const json& j, const std::string& w) { d.model.reason = get<std::string>(j, "model_reason", w); }},
    field("units", &Decision::units),
    field("unit", &Decision::unit),
    field("count_reason", &Decision::count_reason),
    field("order_cap", &Decision::order_cap),
    field("cap_reason", &Decision::cap_reason),
    field("predicted_seconds", &Decision::predicted_seconds),
    field("runnable", &Decision::runnable)};
const std::vector<Field<Decision>> kPilot = {
    field("units", &Decision::pilot_units), field("seconds", &Decision::pilot_seconds), field("error", &Decision::pilot_error)};

const std::vector<Field<RoundRecord>> kRound = {
    field("units", &RoundRecord::units),     field("planned", &RoundRecord::planned),
    field("blocks_done", &RoundRecord::blocks_done), field("partial", &RoundRecord::partial),
    field("seed", &RoundRecord::seed),       field("tolerance", &RoundRecord::tolerance),
    field("seconds", &RoundRecord::seconds), field("achieved", &RoundRecord::achieved)};

const std::vector<Field<MeasurementResult>> kMeasurement = {
    field("ran", &MeasurementResult::ran),         field("partial", &MeasurementResult::partial),
    field("target", &MeasurementResult::target),   field("error_measure", &MeasurementResult::error_measure),
    field("achieved", &MeasurementResult::achieved), field("met", &MeasurementResult::met),
    field("values", &MeasurementResult::values)};
const std::vector<Field<MeasurementResult>> kCost = {
    field("units", &MeasurementResult::units), field("rays", &MeasurementResult::rays),
    field("seconds", &MeasurementResult::seconds)};

json decision_json(const Decision& d, const ExperimentSpec& spec) {
  const SpecQuantity& q = spec.quantities[d.quantity];
  json j = {{"quantity", q.key}, {"kind", to_string(q.kind)}, {"material", q.material}, {"target", q.target}};
  write_fields(d, kDecision, j);
  write_fields(d, kPilot, j["pilot"]);
  // A kind without views may still be planned at one alpha (a BSDF's battery): resume and merge read it back.
  if (kind_has_views(q.kind) || d.alpha.first > 0) j["alpha"] = {d.alpha.first, d.alpha.second};
  if (kind_has_views(q.kind)) j["view"] = {{"theta_deg", d.view.theta_deg}, {"phi_deg", d.view.phi_deg}};
  if (d.tolerance > 0) j["tolerance"] = d.tolerance;
  if (!d.targeted_orders.empty()) j["targeted_orders"] = d.targeted_orders;
  if (!d.runnable) j["not_runnable"] = d.not_runnable;
  if (!d.surface.kind.empty()) write_fields(d.surface, kSurfacePlan, j["surface"]);
  if (d.realisation > 0) j["realisation"] = d.realisation;
  return j;
}

std::size_t quantity_index(const ExperimentSpec& spec, const std::string& key, const std::string& where) {
  for (std::size_t i = 0; i < spec.quantities.size(); ++i)
    if (spec.quantities[i].key == key) return i;
  throw std::invalid_argument(fmt::format("results.json: {}.quantity: '{}' is not a quantity of the spec", where, key));
}

Decision decision_from_json(const json& j, const ExperimentSpec& spec, const std::string& where) {
  Decision d;
  d.quantity = quantity_index(spec, get<std::string>(j, "quantity", where), where);
  d.tests = kind_tests(spec.quantities[d.quantity].kind);
  read_fields(d, kDecision, j, where);
  read_fields(d, kPilot, at(j, "pilot", where), where + ".pilot");
  if (j.contains("alpha")) d.alpha = get<std::pair<double, double>>(j, "alpha", where);
  if (j.contains("view"))
    d.view = {get<double>(j["view"], "theta_deg", where + ".view"), get<double>(j["view"], "phi_deg", where + ".view")};
  d.tolerance = j.contains("tolerance") ? get<double>(j, "tolerance", where) : 0.0;
  if (j.contains("targeted_orders")) d.targeted_orders = get<std::vector<int>>(j, "targeted_orders", where);
  if (j.contains("not_runnable")) d.not_runnable = get<std::string>(j, "not_runnable", where);
  if (j.contains("surface")) read_fields(d.surface, kSurfacePlan, j["surface"], where + ".surface");
  if (j.contains("realisation")) d.realisation = get<int>(j, "realisation", where);
  return d;
}

json measurement_json(const MeasurementResult& m) {
  json rounds = json::array();
  for (const RoundRecord& r : m.rounds) write_fields(r, kRound, rounds.emplace_back());
  json j = {{"measurement", m.decision.label}, {"rounds", rounds}, {"cost", {{"unit", m.decision.unit}}}};
  write_fields(m, kMeasurement, j);
  write_fields(m, kCost, j["cost"]);
  if (!m.round_tables.empty()) j["round_tables"] = m.round_tables;
  return j;
}

MeasurementResult measurement_from_json(const json& j, const Decision& d, const std::string& where) {
  MeasurementResult m;
  m.decision = d;
  if (get<std::string>(j, "measurement", where) != d.label)
    throw std::invalid_argument(fmt::format("results.json: {} is not the plan's '{}'", where, d.label));
  read_fields(m, kMeasurement, j, where);
  const json& rounds = at(j, "rounds", where);
  for (std::size_t r = 0; r < rounds.size(); ++r)
    read_fields(m.rounds.emplace_back(), kRound, rounds[r], fmt::format("{}.rounds[{}]", where, r));
  read_fields(m, kCost, at(j, "cost", where), where + ".cost");
  if (m.values.is_object() && m.values.contains("unbinned"))
    m.unbinned = get<std::vector<std::uint64_t>>(m.values, "unbinned", where + ".values");
  if (j.contains("round_tables")) m.round_tables = get<std::vector<json>>(j, "round_tables", where);
  if (m.round_tables.size() > m.rounds.size())
    throw std::invalid_argument(fmt::format("results.json: {}: more round tables than rounds", where));
  return m;
}

}  // namespace

nlohmann::json plan_json(const ExperimentPlan& plan, const ExperimentSpec& spec) {
  json decisions = json::array();
  for (const Decision& d : plan.decisions) decisions.push_back(decision_json(d, spec));
  return {{"decisions", decisions}, {"pilot_seconds", plan.pilot_seconds}, {"predicted_seconds", plan.predicted_seconds}};
}

nlohmann::json results_json(const ExperimentResults& results) {
  json measurements = json::array();
  for (const MeasurementResult& m : results.measurements) measurements.push_back(measurement_json(m));
  // all_targets_met: every measurement that ran has enough samples; the verdict (verdict.h): what the tests found.
  json out{{"measurements", measurements},
           {"partial", results.partial},
           {"all_targets_met", all_targets_met(results)},
           {"seconds", results.seconds}};
  out.update(verdict_json(run_verdict(results)));  // derived: not read back (a resumed run derives it again)
  add_kind_summaries(results.measurements, out);  // derived: not read back
  return out;
}

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
