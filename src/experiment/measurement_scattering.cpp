// experiment: the scattering kind (measurement.h). Sampled (the Smith walk, Heitz et al. 2016, or paths on an
// explicit tile's Embree scene): rounds of paths, their exact sums added (ScatterHistogram::merge); the TV
// resolved by the largest per-order noise floor of the orders the plan targeted decides (measures.h,
// targeted_order_bins). Analytic (orders single on Smith's surface): the order-1 lobe by cubature, once; its
// error estimate over the albedo is the achieved error (no noise).
#include "experiment/heightfield_measures.h"
#include "experiment/measurement.h"
#include "experiment/measures.h"

#include "core/errors.h"
#include "core/wall_clock.h"
#include "scatter/surface_scatter.h"
#include "stats/scatter_compare.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <limits>

namespace microsim::experiment {
namespace {

nlohmann::json scatter_estimate_json(const Estimate& e) {
  return {{"value", e.value}, {"standard_error", e.standard_error}};
}

nlohmann::json scatter_values(const ScatterHistogram& h, const std::vector<int>& targeted) {
  nlohmann::json orders = nlohmann::json::array();
  for (int k = 0; k < kScatterOrderBins; ++k)
    orders.push_back({{"order", scatter_order_name(k)},
                      {"albedo", scatter_estimate_json(h.albedo(0, k))},
                      {"reflected", scatter_estimate_json(h.albedo(0, k, ScatterSide::reflected))},
                      {"transmitted", scatter_estimate_json(h.albedo(0, k, ScatterSide::transmitted))},
                      {"noise_floor_tv", scatter_order_floor(h, k)},
                      {"targeted", std::find(targeted.begin(), targeted.end(), k) != targeted.end()}});
  return {{"scattering", {{"paths", h.paths()},
                          {"channel", h.channel_name(0)},
                          {"albedo", scatter_estimate_json(h.albedo(0, -1))},
                          {"unfinished", scatter_estimate_json(h.unfinished(0))},
                          {"orders", orders},
                          {"noise_floor_tv", scatter_noise_floor(h, targeted)},
                          {"rows_per_hemisphere", kScatterRows}}}};
}

// Per-order lobes of sampled paths: the walk's or a tile's (paths_on).
class SampledScattering : public Measurement {
public:
  using Measurement::Measurement;
  std::string error_measure() const override {
    return fmt::format("the TV the lobes resolve: the largest per-order TV noise floor of the orders carrying at least "
                       "the target's share of the albedo, over {}", kNoiseShare);
  }
  bool split() const override { return true; }
  RoundTask first_round(std::size_t index, std::uint64_t seed) const override {
    const std::uint64_t units = first_units(decision_, 1);
    return {index, units, round_seed(seed, index, 0), BlockRange{0, BlockPlan{units, kPathsPerBlock}.blocks()}};
  }

protected:
  // The rounds, each split (split_scatter_round) with `paths` running a part.
  void run_paths(const RoundContext& c, const ScatterPaths& paths, MeasurementResult& m) const {
    const ScatterPaths walk = [&](const ScatterOptions& options) {
      return split_scatter_round(c.split(), c.index, paths, options);
    };
    run_histogram_rounds(c, m, std::numeric_limits<std::uint64_t>::max(),
                         [&](const RoundStart& start) { return round(c, start, walk, m); });
  }
  ScatterOptions request(const RoundTask& task, const BlockRange& mine, const RunControl& run) const {
    ScatterOptions options = scatter_request(material(), decision_, task.units, task.seed, run);
    options.blocks = mine;
    return options;
  }

private:
  bool round(const RoundContext& c, const RoundStart& start, const ScatterPaths& walk, MeasurementResult& m) const {
    ScatterOptions options = scatter_request(material(), decision_, start.units, start.seed, c.options.run);
    if (const auto blocks = start.blocks(kPathsPerBlock)) options.blocks = *blocks;
    const auto clock = std::chrono::steady_clock::now();
    const ScatterHistogram r = walk(options);
    m.partial = r.partial;
    if (r.paths() == 0) return false;
    if (m.scatter.binning_id().empty()) m.scatter = r;  // the first gives the binning and channels
    else m.scatter.merge(r);
    m.achieved = resolved_tv(scatter_noise_floor(m.scatter, decision_.targeted_orders));
    m.units += r.paths();
    m.rays += r.paths();
    m.rounds.push_back({start.done + r.paths(), start.units, r.provenance.blocks.end, r.partial, start.seed, 0,
                        seconds_since(clock), m.achieved});
    m.values = scatter_values(m.scatter, decision_.targeted_orders);
    return true;
  }
};

class WalkScattering final : public SampledScattering {
public:
  using SampledScattering::SampledScattering;
  std::string part(const RoundTask& task, const BlockRange& mine, const RunControl& run, SurfaceCache&) const override {
    return scatter_part(smith_walk_scatter(scatter_surface(material(), decision_), request(task, mine, run)));
  }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    const SmithMicrosurface surface = scatter_surface(material(), decision_);
    run_paths(c, [&surface](const ScatterOptions& part) { return smith_walk_scatter(surface, part); }, m);
  }
};

// On a tile (built once through the cache, or read back); its scene kept by the cache between rounds.
class HeightfieldScattering final : public SampledScattering {
public:
  using SampledScattering::SampledScattering;
  std::string part(const RoundTask& task, const BlockRange& mine, const RunControl& run,
                   SurfaceCache& surfaces) const override {
    const microgeom::Heightfield* field = nullptr;
    try {
      field = &decision_surface(decision_, surfaces, run);
    } catch (const Cancelled&) {
      return cancelled_part(mine);  // its build cancelled: a part cancelled before its first block
    }
    return scatter_part(scatter_on_surface(surfaces.scene_for(*field), request(task, mine, run)));
  }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    m.partial = false;
    const microgeom::Heightfield* field = nullptr;
    try {
      field = &decision_surface(decision_, c.surfaces, c.options.run);
    } catch (const Cancelled&) {
      m.partial = true;
      return;
    }
    // The scene is built when the root's own part begins: after the round was sent, while the ranks build theirs.
    run_paths(c, [&c, field](const ScatterOptions& part) { return scatter_on_surface(c.surfaces.scene_for(*field), part); }, m);
  }
};

// The cubature once (deterministic; resumed: run again).
class AnalyticScattering final : public Measurement {
public:
  using Measurement::Measurement;
  std::string error_measure() const override {
    return "the cubature's summed error estimate over the order-1 albedo (to first order a bound on the lobe's TV error)";
  }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    m.rounds.clear();
    m.partial = false;
    const auto clock = std::chrono::steady_clock::now();
    try {
      m.expectation = analytic_scatter_lobe(material(), decision_, c.options.run);
    } catch (const Cancelled&) {
      m.partial = true;
      return;
    }
    m.achieved = analytic_lobe_error(m.expectation, decision_.view);
    m.rounds.push_back({0, 0, 0, false, 0, 0, seconds_since(clock), m.achieved});
    m.met = m.achieved <= m.target;
    m.values = values(m.expectation, m.achieved);
  }

private:
  nlohmann::json values(const ScatterExpectation& lobe, double relative_error) const {
    const Direction& view = decision_.view;
    const auto exact = [](double value) { return nlohmann::json{{"value", value}, {"standard_error", 0.0}}; };
    return {{"analytic_scattering", {{"channel", lobe.channel_names.at(0)},
                                     {"albedo", exact(expectation_albedo(lobe, view))},
                                     {"reflected", exact(expectation_albedo(lobe, view, ScatterSide::reflected))},
                                     {"transmitted", exact(expectation_albedo(lobe, view, ScatterSide::transmitted))},
                                     {"error_estimate", lobe.error_estimate.at(0)},
                                     {"relative_error", relative_error},
                                     {"rows_per_hemisphere", kScatterRows}}}};
  }
};

}  // namespace

std::unique_ptr<Measurement> make_scattering_measurement(const ExperimentSpec& spec, const Decision& decision) {
  if (decision.model.model == Model::analytic) return std::make_unique<AnalyticScattering>(spec, decision);
  if (decision.model.model == Model::heightfield) return std::make_unique<HeightfieldScattering>(spec, decision);
  return std::make_unique<WalkScattering>(spec, decision);
}

}  // namespace microsim::experiment
