// experiment: plan_experiment: each quantity planned by its kind's planner (measurement_registry.cpp), and
// the pieces the kinds' planners share (plan_kinds.h).
#include "experiment/heightfield_measures.h"
#include "core/wall_clock.h"
#include "experiment/masking_runs.h"
#include "experiment/measures.h"
#include "experiment/measurement.h"
#include "experiment/plan_kinds.h"
#include "experiment/split_rounds.h"
#include "experiment/surface_albedo.h"
#include "measure/surface_cache.h"

#include "validate/compare.h"
#include "validate/sample_io.h"
#include "validate/validation_part.h"
#include "scatter/smith_walk.h"
#include "scatter/surface_scatter.h"
#include "stats/binning.h"
#include "stats/scatter_compare.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <chrono>
#include <filesystem>
#include <functional>
#include <string_view>
#include <vector>

namespace microsim::experiment {

std::uint64_t plan_seed(const ExperimentSpec& spec, const PlanOptions& options) {
  return options.seed != 0 ? options.seed : spec.seed;
}

namespace {

std::string alpha_text(const std::pair<double, double>& a) {
  return a.first == a.second ? fmt::format("{}", a.first) : fmt::format("{},{}", a.first, a.second);
}

}  // namespace

std::uint64_t paths_to_bound_bias(double threshold) { return std::uint64_t(std::ceil(6.0 / threshold)); }

std::pair<int, std::string> walk_order_cap(const CapPilot& pilot, double relative_target, const std::string& where) {
  std::vector<CapProbe> probes;
  const double threshold = kBiasShare * relative_target;
  for (int cap = 4; cap <= kMaxOrderCap; cap *= 2) {
    probes.push_back(pilot(cap));
    if (const auto chosen = order_cap_for(probes, threshold))
      return {*chosen, fmt::format("{}: {} orders leave {:.2e} +- {:.1e} of E on the surface (worst), below {} x "
                                   "target = {:.2e}{}",
                                   where, *chosen, probes.back().unfinished, probes.back().unfinished_se, kBiasShare,
                                   threshold, probes.size() > 1 ? fmt::format("; {} orders left {:.2e}", probes[probes.size() - 2].cap, probes[probes.size() - 2].unfinished) : "")};
  }
  return {kMaxOrderCap, fmt::format("{}: no cap up to {} leaves less than {} x target on the surface: the largest "
                                    "cap, its bias reported", where, kMaxOrderCap, kBiasShare)};
}

bool take_surface(const SurfaceDecision& s, Decision& d) {
  d.surface = s.plan;
  if (s.runnable) return true;
  d.count_reason = "no tile: " + s.why;
  d.not_runnable = s.why;
  return false;
}

namespace {

// The tile of a heightfield decision (the trade table's size, or the user's), built (or read) through the
// cache, then the kind's pilot on it.
void plan_heightfield_view(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, SurfaceCache& cache,
                           const ViewPlanners& kind, Decision& d) {
  if (kind.refusal != nullptr) {
    d.not_runnable = kind.refusal(q);
    if (!d.not_runnable.empty()) return;
  }
  if (!take_surface(plan_surface(q, d, plan_seed(spec, o), cache, kind.sees_heights), d)) return;
  const auto start = std::chrono::steady_clock::now();
  const std::size_t built = cache.builds();
  const microgeom::Heightfield& field = decision_surface(d, cache, o.run);
  const double surface_seconds = seconds_since(start);
  kind.tile(spec, q, o, field, cache, d);
  d.surface.reason += cache.builds() > built
                          ? fmt::format("; built in {:.3g} s during the plan (kept for the run)", surface_seconds)
                          : fmt::format("; not built: {} ({:.3g} s)", q.surface.kind == SurfaceChoice::Kind::heightmap
                                                                         ? "the user's file" : "shared or read back", surface_seconds);
  d.runnable = true;
}

}  // namespace

void plan_views(const ExperimentSpec& spec, std::size_t index, const PlanOptions& o, SurfaceCache& cache,
                const ViewPlanners& kind, std::vector<Decision>& out) {
  const SpecQuantity& q = spec.quantities[index];
  const SpecMaterial& m = spec.material(q.material);
  for (const auto& alpha : m.alphas)
    for (const Direction& v : q.directions) {
      Decision d;
      d.quantity = index;
      d.alpha = alpha;
      d.view = v;
      d.label = fmt::format("{} {} {} alpha {} theta {} phi {}", q.key, to_string(q.kind), m.name, alpha_text(alpha),
                            v.theta_deg, v.phi_deg);
      d.model = choose_model(q, m);
      if (d.model.model == Model::heightfield) plan_heightfield_view(spec, q, o, cache, kind, d);
      else kind.smith(spec, q, o, d);
      out.push_back(std::move(d));
    }
}

std::uint64_t count_dump_rows(DirectionSampleReader& reader, const RunControl& run) {
  std::vector<Vec3<double>> block(kSampleFileBlock);
  std::vector<double> pdfs(reader.columns().has_pdf() ? block.size() : 0);
  std::vector<double> weights(block.size() * std::size_t(reader.columns().channels()));
  while (reader.read(block, pdfs, weights) > 0)
    if (run.cancelled()) throw Cancelled("plan: reading a dump");
  return reader.rows_read();
}

ExperimentPlan plan_experiment(const ExperimentSpec& spec, const PlanOptions& options) {
  ExperimentPlan plan;
  SurfaceCache memory;  // without the caller's cache: surfaces for this plan only
  SurfaceCache& surfaces = options.surfaces != nullptr ? *options.surfaces : memory;
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < spec.quantities.size(); ++i) {
    if (options.run.cancelled()) throw Cancelled("plan");
    const std::size_t first = plan.decisions.size();
    quantity_planner(spec.quantities[i].kind)(spec, i, options, surfaces, plan.decisions);
    for (std::size_t k = first; k < plan.decisions.size(); ++k) plan.decisions[k].tests = kind_tests(spec.quantities[i].kind);
  }
  plan.pilot_seconds = seconds_since(start);
  for (const Decision& d : plan.decisions) plan.predicted_seconds += d.predicted_seconds;
  return plan;
}

}  // namespace microsim::experiment
