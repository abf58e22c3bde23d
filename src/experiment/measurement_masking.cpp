// experiment: the masking kind (measurement.h): Smith's closed forms (analytic: exact, once), or G1, G2 and the
// conditional G1 measured on an explicit surface (masking_runs.h HeightfieldMasking) in rounds of successive
// block ranges of one run until the target standard error is met. The ranks and shards measure shards of a
// round's blocks for every light on the same surface (the run's seed), their exact sums (MaskingSums) added in
// order; a part cancelled part way drops the round, as in one process.
#include "experiment/masking_runs.h"
#include "experiment/masking_surface.h"
#include "experiment/measurement.h"

#include "core/wall_clock.h"

#include <fmt/core.h>

#include <chrono>

namespace microsim::experiment {
namespace {

// The closed forms, once (deterministic: resumed, computed again).
class AnalyticMasking final : public Measurement {
public:
  using Measurement::Measurement;
  std::string error_measure() const override { return "none: Smith's closed forms are exact"; }
  void run(const RoundContext&, MeasurementResult& m) const override {
    const auto clock = std::chrono::steady_clock::now();
    m.rounds.clear();
    m.partial = false;
    m.values = analytic_masking_json(quantity_, material(), decision_);
    m.achieved = 0;
    m.rounds.push_back({0, 0, 0, false, 0, 0, seconds_since(clock), 0});
    m.met = true;
  }
};

class SurfaceMaskingMeasurement final : public Measurement {
public:
  using Measurement::Measurement;
  std::string error_measure() const override {
    return fmt::format("the largest standard error of the measured {}{}", to_string(quantity_.masking),
                       quantity_.masking.conditional ? " (every bin of <v, m> and of height)" : "");
  }
  bool split() const override { return true; }
  // Its rounds are block ranges of one run (of kMaskingRunSamples samples): the first, the planned samples'.
  RoundTask first_round(std::size_t index, std::uint64_t seed) const override {
    return {index, kMaskingRunSamples, round_seed(seed, index, 0),
            BlockRange{0, BlockPlan{first_units(decision_, 1), kSamplesPerBlock}.blocks()},
            masking_surface_seed(seed, decision_.realisation)};
  }
  // The surface of the run's seed from `surfaces` (a build cancelled: a cancelled part), then its shard of the
  // blocks for every light.
  std::string part(const RoundTask& task, const BlockRange& mine, const RunControl& run,
                   SurfaceCache& surfaces) const override {
    const microgeom::Heightfield* field = nullptr;
    try {
      field = &acquire_masking_surface(quantity_, material(), decision_.alpha, task.surface_seed, surfaces, run);
    } catch (const Cancelled&) {
      return masking_round_part(task, mine, std::nullopt);
    }
    const HeightfieldMasking h(quantity_, decision_, *field,
                               masking_surface_text(quantity_, material(), decision_.alpha, task.surface_seed), task.seed);
    return masking_round_part(task, mine, h.measure_round(mine, run));
  }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    const std::uint64_t surface_seed = masking_surface_seed(c.seed, decision_.realisation);
    std::optional<HeightfieldMasking> h;
    try {
      h.emplace(quantity_, decision_,
                acquire_masking_surface(quantity_, material(), decision_.alpha, surface_seed, c.surfaces, c.options.run),
                masking_surface_text(quantity_, material(), decision_.alpha, surface_seed), c.round_seed(0));
    } catch (const Cancelled&) {
      m.partial = true;
      return;
    }
    rounds(c, *h, [&](const BlockRange& blocks) {
      return split_masking_round(c.split(), c.index, *h, surface_seed, blocks, c.options.run);
    }, m);
  }

private:
  // Rounds of blocks until the target standard error is met (the completed rounds of an interrupted run are
  // restored from m.values first).
  void rounds(const RoundContext& c, HeightfieldMasking& h, const MaskingRound& round, MeasurementResult& m) const {
    if (!m.rounds.empty()) h.restore(m.values);
    m.partial = false;
    std::uint64_t n = m.rounds.empty() ? first_units(decision_, c.options.cost_factor)
                                       : next_round_units(m.units, m.achieved, m.target);
    for (int r = int(m.rounds.size()); r < c.options.max_rounds && n > 0; ++r) {
      const auto clock = std::chrono::steady_clock::now();
      const std::uint64_t before = h.samples();
      const std::uint64_t end = h.blocks_done() + BlockPlan{n, kSamplesPerBlock}.blocks();
      if (!h.add_blocks(end, c.options.run, round)) {
        m.partial = true;
        break;
      }
      m.achieved = h.worst_standard_error();
      m.rounds.push_back({h.samples() - before, n, end, false, h.seed(), 0, seconds_since(clock), m.achieved});
      m.units = h.samples();
      m.rays = h.rays();
      m.values = h.values_json();
      n = next_round_units(m.units, m.achieved, m.target);
    }
    m.met = !m.rounds.empty() && !m.partial && m.achieved <= m.target;
  }
};


// ---- its plan: one decision per alpha and view ---------------------------------------------------------------

enum : std::uint64_t { kMaskingPilotSeed = 32 };  // derived_seed purposes of plan_kinds.h are below 32

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

void plan_masking_quantity(const ExperimentSpec& spec, std::size_t index, const PlanOptions& o, SurfaceCache& surfaces,
                  std::vector<Decision>& out) {
  for (const auto& alpha : spec.material(spec.quantities[index].material).alphas)
    plan_alpha(spec, index, alpha, o, surfaces, out);
}

std::unique_ptr<Measurement> make_masking_measurement(const ExperimentSpec& spec, const Decision& decision) {
  if (decision.model.model == Model::analytic) return std::make_unique<AnalyticMasking>(spec, decision);
  return std::make_unique<SurfaceMaskingMeasurement>(spec, decision);
}

}  // namespace microsim::experiment
