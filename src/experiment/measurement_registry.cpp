// experiment: the registry of measurement kinds (measurement.h): the only place that chooses a kind. A new kind
// is one file (its Measurement and its planner) and one line here.
#include "experiment/measurement.h"
#include "experiment/report_html.h"

#include "core/errors.h"

#include <fmt/core.h>

namespace microsim::experiment {
namespace {

struct KindEntry {
  const char* name;      // the spec's `kind` (QuantityKind::name)
  const KindSpec* spec;  // its keys, their reader and its canonical keys (its file)
  bool views;            // its decisions are per alpha and view (results.json's decisions record both)
  ModelRule model;       // its cheapest sufficient model
  PlanQuantity plan;
  std::unique_ptr<Measurement> (*make)(const ExperimentSpec&, const Decision&);
  KindReport report;            // its section of a measurement in the report (its file)
  const KindSummary* summary;   // what it adds to the whole run (null: nothing)
  const char* test;             // the member of its values that reports its test's verdict (null: tests nothing)
};

constexpr KindEntry kKinds[] = {
    {"albedo", &albedo_spec, false, albedo_model, plan_albedo_quantity, make_albedo_measurement, albedo_report, nullptr, nullptr},
    {"vndf", &vndf_spec, true, vndf_model, plan_vndf_quantity, make_vndf_measurement, vndf_report, nullptr, nullptr},
    {"scattering", &scattering_spec, true, scattering_model, plan_scattering_quantity, make_scattering_measurement, scattering_report, nullptr, nullptr},
    {"validation", &validation_spec, true, validation_model, plan_validation_quantity, make_validation_measurement, validation_report, nullptr, "validation"},
    {"masking", &masking_spec, true, masking_model, plan_masking_quantity, make_masking_measurement, masking_report, &masking_summary, nullptr},
    {"bsdf", &bsdf_spec, false, bsdf_model, plan_bsdf_quantity, make_bsdf_measurement, bsdf_report, nullptr, "battery"},
};

const KindEntry* find_kind(std::string_view name) {
  for (const KindEntry& e : kKinds)
    if (e.name == name) return &e;
  return nullptr;
}

const KindEntry& kind_entry(QuantityKind kind) {
  if (const KindEntry* e = find_kind(kind.name)) return *e;
  throw InternalError(fmt::format("no measurement kind {} in the registry", kind.name));
}

}  // namespace

std::optional<QuantityKind> kind_named(std::string_view name) {
  if (const KindEntry* e = find_kind(name)) return QuantityKind{e->name};
  return std::nullopt;
}

std::string kind_names() {
  std::string names;
  for (const KindEntry& e : kKinds) names += (names.empty() ? "" : ", ") + std::string(e.name);
  return names;
}

const KindSpec& kind_spec(QuantityKind kind) { return *kind_entry(kind).spec; }

bool kind_has_views(QuantityKind kind) { return kind_entry(kind).views; }

KindReport kind_report(const std::string& kind) {
  const KindEntry* e = find_kind(kind);
  return e ? e->report : nullptr;
}

void add_kind_summaries(const std::vector<MeasurementResult>& measurements, nlohmann::json& results) {
  for (const KindEntry& e : kKinds)
    if (e.summary != nullptr) e.summary->results(measurements, results);
}

std::string kind_summary_sections(const nlohmann::json& document, bool before) {
  std::string out;
  for (const KindEntry& e : kKinds)
    if (e.summary != nullptr) out += (before ? e.summary->before : e.summary->after)(document);
  return out;
}

const nlohmann::json* kind_test_report(const nlohmann::json& values) {
  if (!values.is_object()) return nullptr;
  for (const KindEntry& e : kKinds)
    if (e.test != nullptr && values.contains(e.test) && values.at(e.test).is_object() && values.at(e.test).contains("verdict"))
      return &values.at(e.test);
  return nullptr;
}

ModelRule kind_model_rule(QuantityKind kind) { return kind_entry(kind).model; }

PlanQuantity quantity_planner(QuantityKind kind) { return kind_entry(kind).plan; }

std::unique_ptr<Measurement> make_measurement(const ExperimentSpec& spec, const Decision& decision) {
  return kind_entry(spec.quantities.at(decision.quantity).kind).make(spec, decision);
}

}  // namespace microsim::experiment
