// experiment: plans and results as JSON (run.h: plan_json, results_json), the content of results.json.
#include "experiment/run.h"
#include "experiment/masking_runs.h"
#include "experiment/verdict.h"

namespace microsim::experiment {
namespace {

nlohmann::json surface_plan_json(const SurfacePlan& p) {
  return {{"kind", p.kind},           {"name", p.name},   {"ndf", p.ndf},   {"resolution", p.resolution},
          {"corr_cells", p.corr_cells}, {"ndf_match", p.ndf_match}, {"seed", p.seed}, {"bias", p.bias},
          {"hash", p.hash},           {"reason", p.reason}};
}

nlohmann::json decision_json(const Decision& d, const ExperimentSpec& spec) {
  const SpecQuantity& q = spec.quantities[d.quantity];
  nlohmann::json j = {{"measurement", d.label},
                      {"quantity", q.key},
                      {"kind", to_string(q.kind)},
                      {"material", q.material},
                      {"target", q.target},
                      {"model", to_string(d.model.model)},
                      {"model_reason", d.model.reason},
                      {"units", d.units},
                      {"unit", d.unit},
                      {"count_reason", d.count_reason},
                      {"order_cap", d.order_cap},
                      {"cap_reason", d.cap_reason},
                      {"predicted_seconds", d.predicted_seconds},
                      {"pilot", {{"units", d.pilot_units}, {"seconds", d.pilot_seconds}, {"error", d.pilot_error}}},
                      {"runnable", d.runnable}};
  if (q.kind != QuantityKind::albedo) {
    j["alpha"] = {d.alpha.first, d.alpha.second};
    j["view"] = {{"theta_deg", d.view.theta_deg}, {"phi_deg", d.view.phi_deg}};
  }
  if (d.tolerance > 0) j["tolerance"] = d.tolerance;
  if (!d.targeted_orders.empty()) j["targeted_orders"] = d.targeted_orders;
  if (!d.runnable) j["not_runnable"] = d.not_runnable;
  if (!d.surface.kind.empty()) j["surface"] = surface_plan_json(d.surface);
  if (d.realisation > 0) j["realisation"] = d.realisation;
  return j;
}

nlohmann::json measurement_json(const MeasurementResult& m) {
  nlohmann::json rounds = nlohmann::json::array();
  for (const RoundRecord& r : m.rounds)
    rounds.push_back({{"units", r.units}, {"planned", r.planned}, {"blocks_done", r.blocks_done},
                      {"partial", r.partial}, {"seed", r.seed}, {"tolerance", r.tolerance}, {"seconds", r.seconds},
                      {"achieved", r.achieved}});
  nlohmann::json j = {{"measurement", m.decision.label},
          {"ran", m.ran},
          {"partial", m.partial},
          {"target", m.target},
          {"error_measure", m.error_measure},
          {"achieved", m.achieved},
          {"met", m.met},
          {"rounds", rounds},
          {"cost", {{"units", m.units}, {"unit", m.decision.unit}, {"rays", m.rays}, {"seconds", m.seconds}}},
          {"values", m.values}};
  if (!m.round_tables.empty()) j["round_tables"] = m.round_tables;
  return j;
}

}  // namespace

nlohmann::json plan_json(const ExperimentPlan& plan, const ExperimentSpec& spec) {
  nlohmann::json decisions = nlohmann::json::array();
  for (const Decision& d : plan.decisions) decisions.push_back(decision_json(d, spec));
  return {{"decisions", decisions}, {"pilot_seconds", plan.pilot_seconds}, {"predicted_seconds", plan.predicted_seconds}};
}

nlohmann::json results_json(const ExperimentResults& results) {
  nlohmann::json measurements = nlohmann::json::array();
  for (const MeasurementResult& m : results.measurements) measurements.push_back(measurement_json(m));
  // all_targets_met: every measurement that ran has enough samples; the verdict (verdict.h): what the tests found.
  nlohmann::json out{{"measurements", measurements},
                     {"partial", results.partial},
                     {"all_targets_met", all_targets_met(results)},
                     {"seconds", results.seconds}};
  out.update(verdict_json(run_verdict(results)));  // derived: not read back (a resumed run derives it again)
  const nlohmann::json means = masking_realisation_means(results.measurements);
  if (!means.empty()) out["masking_realisations"] = means;  // derived: not read back
  return out;
}

}  // namespace microsim::experiment
