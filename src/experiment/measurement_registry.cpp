// experiment: the registry of measurement kinds (measurement.h): the only place that chooses a kind. A new kind
// is one file (its Measurement and its planner) and one line here.
#include "experiment/measurement.h"

#include "core/errors.h"

#include <fmt/core.h>

namespace microsim::experiment {
namespace {

struct KindEntry {
  QuantityKind kind;
  PlanQuantity plan;
  std::unique_ptr<Measurement> (*make)(const ExperimentSpec&, const Decision&);
};

constexpr KindEntry kKinds[] = {
    {QuantityKind::albedo, plan_albedo_quantity, make_albedo_measurement},
    {QuantityKind::vndf, plan_view_quantity, make_vndf_measurement},
    {QuantityKind::scattering, plan_view_quantity, make_scattering_measurement},
    {QuantityKind::validation, plan_view_quantity, make_validation_measurement},
    {QuantityKind::masking, plan_masking, make_masking_measurement},
};

const KindEntry& kind_entry(QuantityKind kind) {
  for (const KindEntry& e : kKinds)
    if (e.kind == kind) return e;
  throw InternalError(fmt::format("no measurement kind '{}' in the registry", to_string(kind)));
}

}  // namespace

PlanQuantity quantity_planner(QuantityKind kind) { return kind_entry(kind).plan; }

std::unique_ptr<Measurement> make_measurement(const ExperimentSpec& spec, const Decision& decision) {
  return kind_entry(spec.quantities.at(decision.quantity).kind).make(spec, decision);
}

}  // namespace microsim::experiment
