// experiment: the registry of measurement kinds (measurement.h MeasurementKind): the only place that chooses a
// kind. A new kind is one file (its entry, its Measurement, its planner, its keys and its report section) and its
// name in the two lines below.
#include "experiment/measurement.h"

#include "core/errors.h"

#include <fmt/core.h>

namespace microsim::experiment {
// Each kind's own file defines its entry (measurement.h MeasurementKind).
extern const MeasurementKind albedo_kind, vndf_kind, scattering_kind, validation_kind, masking_kind, bsdf_kind;

namespace {

constexpr const MeasurementKind* kKinds[] = {
    &albedo_kind, &vndf_kind, &scattering_kind, &validation_kind, &masking_kind, &bsdf_kind,
};

const MeasurementKind* find_kind(std::string_view name) {
  for (const MeasurementKind* e : kKinds)
    if (e->name == name) return e;
  return nullptr;
}

const MeasurementKind& kind_entry(QuantityKind kind) {
  if (const MeasurementKind* e = find_kind(kind.name)) return *e;
  throw InternalError(fmt::format("no measurement kind {} in the registry", kind.name));
}

}  // namespace

std::optional<QuantityKind> kind_named(std::string_view name) {
  if (const MeasurementKind* e = find_kind(name)) return QuantityKind{e->name};
  return std::nullopt;
}

std::string kind_names() {
  std::string names;
  for (const MeasurementKind* e : kKinds) names += (names.empty() ? "" : ", ") + std::string(e->name);
  return names;
}

const KindSpec& kind_spec(QuantityKind kind) { return *kind_entry(kind).spec; }

bool kind_has_views(QuantityKind kind) { return kind_entry(kind).views; }

KindReport kind_report(const std::string& kind) {
  const MeasurementKind* e = find_kind(kind);
  return e ? e->report : nullptr;
}

void add_kind_summaries(const std::vector<MeasurementResult>& measurements, nlohmann::json& results) {
  for (const MeasurementKind* e : kKinds)
    if (e->summary != nullptr) e->summary->results(measurements, results);
}

std::string kind_summary_sections(const nlohmann::json& document, bool before) {
  std::string out;
  for (const MeasurementKind* e : kKinds)
    if (e->summary != nullptr) out += (before ? e->summary->before : e->summary->after)(document);
  return out;
}

const nlohmann::json* kind_test_report(const nlohmann::json& values) {
  if (!values.is_object()) return nullptr;
  for (const MeasurementKind* e : kKinds)
    if (e->test != nullptr && values.contains(e->test) && values.at(e->test).is_object() &&
        values.at(e->test).contains("verdict"))
      return &values.at(e->test);
  return nullptr;
}

bool kind_tests(QuantityKind kind) { return kind_entry(kind).test != nullptr; }

ModelRule kind_model_rule(QuantityKind kind) { return kind_entry(kind).model; }

PlanQuantity quantity_planner(QuantityKind kind) { return kind_entry(kind).plan; }

std::unique_ptr<Measurement> make_measurement(const ExperimentSpec& spec, const Decision& decision) {
  return kind_entry(spec.quantities.at(decision.quantity).kind).make(spec, decision);
}

}  // namespace microsim::experiment
