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
  const char* name;      // the spec's `kind`
  const KindSpec* spec;  // its keys and their reader (its file)
  ModelRule model;      // its cheapest sufficient model
  PlanQuantity plan;
  std::unique_ptr<Measurement> (*make)(const ExperimentSpec&, const Decision&);
  KindReport report;  // its section of the report (its file)
};

constexpr KindEntry kKinds[] = {
    {QuantityKind::albedo, "albedo", &albedo_spec, albedo_model, plan_albedo_quantity, make_albedo_measurement, albedo_report},
    {QuantityKind::vndf, "vndf", &vndf_spec, vndf_model, plan_vndf_quantity, make_vndf_measurement, vndf_report},
    {QuantityKind::scattering, "scattering", &scattering_spec, scattering_model, plan_scattering_quantity, make_scattering_measurement, scattering_report},
    {QuantityKind::validation, "validation", &validation_spec, validation_model, plan_validation_quantity, make_validation_measurement, validation_report},
    {QuantityKind::masking, "masking", &masking_spec, masking_model, plan_masking_quantity, make_masking_measurement, masking_report},
};

const KindEntry& kind_entry(QuantityKind kind) {
  for (const KindEntry& e : kKinds)
    if (e.kind == kind) return e;
  throw InternalError(fmt::format("no measurement kind {} in the registry", int(kind)));
}

}  // namespace

std::string to_string(QuantityKind kind) { return kind_entry(kind).name; }

std::optional<QuantityKind> kind_named(std::string_view name) {
  for (const KindEntry& e : kKinds)
    if (e.name == name) return e.kind;
  return std::nullopt;
}

std::string kind_names() {
  std::string names;
  for (const KindEntry& e : kKinds) names += (names.empty() ? "" : ", ") + std::string(e.name);
  return names;
}

const KindSpec& kind_spec(QuantityKind kind) { return *kind_entry(kind).spec; }

KindReport kind_report(const std::string& kind) {
  const std::optional<QuantityKind> k = kind_named(kind);
  return k ? kind_entry(*k).report : nullptr;
}

ModelRule kind_model_rule(QuantityKind kind) { return kind_entry(kind).model; }

PlanQuantity quantity_planner(QuantityKind kind) { return kind_entry(kind).plan; }

std::unique_ptr<Measurement> make_measurement(const ExperimentSpec& spec, const Decision& decision) {
  return kind_entry(spec.quantities.at(decision.quantity).kind).make(spec, decision);
}

}  // namespace microsim::experiment
