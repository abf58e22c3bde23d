// experiment: the decisions of a masking quantity (masking_runs.h: plan_masking): one per alpha and view.
#include "experiment/masking_runs.h"
#include "core/wall_clock.h"
#include "experiment/masking_surface.h"

#include <fmt/core.h>

#include <chrono>

namespace microsim::experiment {
namespace {

enum : std::uint64_t { kMaskingPilotSeed = 32 };  // derived_seed purposes of plan.cpp are below 32

Decision masking_decision(const SpecQuantity& q, const SpecMaterial& m, std::size_t index,
                          std::pair<double, double> alpha, const Direction& v) {
  Decision d;
  d.quantity = index;
  d.alpha = alpha;
  d.view = v;
  const std::string a = alpha.first == alpha.second ? fmt::format("{}", alpha.first)
                                                    : fmt::format("{},{}", alpha.first, alpha.second);
  d.label = fmt::format("{} masking {} alpha {} theta {} phi {}", q.key, m.name, a, v.theta_deg, v.phi_deg);
  d.model = choose_model(q, m);
  d.runnable = true;
  return d;
}

// The count of a heightfield decision: a pilot of kMaskingPilotBlocks blocks of surface points on the
// built surface gives the largest standard error of the values asked for (~ 1/sqrt(n)); n in whole blocks.
void plan_heightfield_masking(const SpecQuantity& q, const microgeom::Heightfield& field, const std::string& text,
                              std::uint64_t pilot_seed, double build_seconds, const PlanOptions& o, Decision& d) {
  const auto start = std::chrono::steady_clock::now();
  HeightfieldMasking pilot(q, d, field, text, pilot_seed);
  if (!pilot.add_blocks(kMaskingPilotBlocks, o.run)) throw Cancelled("plan: masking pilot");
  d.pilot_error = pilot.worst_standard_error();
  d.pilot_seconds = seconds_since(start);
  d.pilot_units = pilot.samples();
  const std::uint64_t n = units_for_standard_error(d.pilot_units, d.pilot_error, q.target);
  d.units = BlockPlan{n, kSamplesPerBlock}.blocks() * kSamplesPerBlock;
  d.unit = "samples";
  d.count_reason = fmt::format("pilot of {} surface points: largest standard error of {} {:.2e} ~ 1/sqrt(n); "
                               "n = {} x ({:.2e} / {})^2, in whole blocks of {}",
                               d.pilot_units, to_string(q.masking), d.pilot_error, d.pilot_units, d.pilot_error,
                               q.target, kSamplesPerBlock);
  d.model.reason += "; surface: " + text +
                    " (the target is the Monte Carlo error on this one surface: the spread between realisations is not in it)";
  // The surface's build and the scene are paid once per measurement; the sampling scales with the points.
  const double setup = std::max(0.0, d.pilot_seconds - pilot.seconds());
  d.predicted_seconds = build_seconds + setup + predicted_seconds(d.units, d.pilot_units, pilot.seconds());
}


// The decisions of one alpha: per realisation of its surface (one without a surface), per view.
void plan_alpha(const ExperimentSpec& spec, std::size_t index, std::pair<double, double> alpha, const PlanOptions& o,
                SurfaceCache& surfaces, std::vector<Decision>& out) {
  const SpecQuantity& q = spec.quantities[index];
  const SpecMaterial& m = spec.material(q.material);
  const bool traced = choose_model(q, m).model == Model::heightfield;
  const std::uint64_t run_seed = o.seed != 0 ? o.seed : spec.seed;
  for (int k = 0; k < (traced ? q.realisations : 1); ++k) {
    const std::uint64_t seed = masking_surface_seed(run_seed, k);
    const microgeom::Heightfield* field = nullptr;  // from the cache once per realisation, for its views' pilots
    double build_seconds = 0;
    if (traced) {
      const auto start = std::chrono::steady_clock::now();
      field = &acquire_masking_surface(q, m, alpha, seed, surfaces, o.run);
      build_seconds = seconds_since(start);
    }
    for (const Direction& v : q.directions) {
      Decision d = masking_decision(q, m, index, alpha, v);
      d.realisation = k;
      if (q.realisations > 1 && traced) d.label += fmt::format(" realisation {}", k);
      if (field)
        plan_heightfield_masking(q, *field, masking_surface_text(q, m, alpha, seed),
                                 derived_seed(run_seed, kMaskingPilotSeed, out.size()), build_seconds, o, d);
      else
        d.count_reason = "deterministic: Smith's closed form, no samples";
      out.push_back(std::move(d));
    }
  }
}

}  // namespace

void plan_masking(const ExperimentSpec& spec, std::size_t index, const PlanOptions& o, SurfaceCache& surfaces,
                  std::vector<Decision>& out) {
  for (const auto& alpha : spec.material(spec.quantities[index].material).alphas)
    plan_alpha(spec, index, alpha, o, surfaces, out);
}

}  // namespace microsim::experiment
