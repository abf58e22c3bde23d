// experiment: the registry of measurement kinds (measurement.h): the only place that chooses a kind. A new kind
// is one file (its Measurement and its planner) and one line here.
#include "experiment/measurement.h"
#include "experiment/report_html.h"

#include "core/errors.h"

#include <fmt/core.h>

namespace microsim::experiment {
namespace {

struct KindEntry {
  QuantityKind kind;
  ModelRule model;  // its cheapest sufficient model (plan_rules.cpp)
  PlanQuantity plan;
  std::unique_ptr<Measurement> (*make)(const ExperimentSpec&, const Decision&);
  KindReport report;  // its section of the report (report_sections.cpp)
};

constexpr KindEntry kKinds[] = {
    {QuantityKind::albedo, albedo_or_scattering_model, plan_albedo_quantity, make_albedo_measurement, albedo_report},
    {QuantityKind::vndf, vndf_model, plan_vndf_quantity, make_vndf_measurement, vndf_report},
    {QuantityKind::scattering, albedo_or_scattering_model, plan_scattering_quantity, make_scattering_measurement, scattering_report},
    {QuantityKind::validation, validation_model, plan_validation_quantity, make_validation_measurement, validation_report},
    {QuantityKind::masking, masking_model, plan_masking_quantity, make_masking_measurement, masking_report},
};

const KindEntry& kind_entry(QuantityKind kind) {
  for (const KindEntry& e : kKinds)
    if (e.kind == kind) return e;
  throw InternalError(fmt::format("no measurement kind '{}' in the registry", to_string(kind)));
}

}  // namespace

KindReport kind_report(const std::string& kind) {
  for (const KindEntry& e : kKinds)
    if (to_string(e.kind) == kind) return e.report;
  return nullptr;
}

ModelRule kind_model_rule(QuantityKind kind) { return kind_entry(kind).model; }

PlanQuantity quantity_planner(QuantityKind kind) { return kind_entry(kind).plan; }

std::unique_ptr<Measurement> make_measurement(const ExperimentSpec& spec, const Decision& decision) {
  return kind_entry(spec.quantities.at(decision.quantity).kind).make(spec, decision);
}

}  // namespace microsim::experiment
