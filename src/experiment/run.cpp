// experiment: the driver of run_experiment (run.h): the measurements in plan order, resumption, cancellation,
// the ranks and the shards; each kind's rounds are its Measurement's (measurement.h).
#include "experiment/measurement.h"

#include "core/errors.h"
#include "core/wall_clock.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace microsim::experiment {
namespace {

enum RunSeedPurpose : std::uint64_t { kRoundSeed = 16 };

// The round to run next: a partial round of a resumed run from its first missing block (its record removed:
// the finished round replaces it), else a new round of at most `max_units`.
RoundStart next_round(const RoundContext& c, MeasurementResult& m, std::uint64_t max_units) {
  if (!m.rounds.empty() && m.rounds.back().partial) {
    const RoundRecord r = m.rounds.back();
    m.rounds.pop_back();
    return {r.planned, r.blocks_done, r.seed, r.units};
  }
  const std::uint64_t n = m.rounds.empty() ? first_units(m.decision, c.options.cost_factor)
                                           : next_round_units(m.units, m.achieved, m.target);
  return {std::min(n, max_units), 0, c.round_seed(int(m.rounds.size())), 0};
}

// A measurement afresh, or continued from `previous` (an interrupted run's); a finished one is kept.
MeasurementResult run_decision(const RoundContext& c, const Decision& d, const MeasurementResult* previous) {
  if (previous != nullptr && (!previous->partial || !d.runnable)) return *previous;
  MeasurementResult m = previous != nullptr ? *previous : MeasurementResult{};
  m.decision = d;
  const std::unique_ptr<Measurement> measurement = make_measurement(c.spec, d);
  m.target = measurement->target();  // as the spec asks it: every achieved error is in its unit
  m.error_measure = measurement->error_measure();
  if (!d.runnable) return m;
  m.ran = true;
  const auto start = std::chrono::steady_clock::now();
  measurement->run(c, m);
  m.seconds += seconds_since(start);
  return m;
}

}  // namespace

std::uint64_t round_seed(std::uint64_t seed, std::size_t index, int round) {
  return derived_seed(seed, kRoundSeed, std::uint64_t(index) * 1024 + std::uint64_t(round));
}

std::uint64_t RoundContext::round_seed(int round) const { return experiment::round_seed(seed, index, round); }

std::uint64_t first_units(const Decision& decision, double cost_factor) {
  return std::max<std::uint64_t>(1, std::uint64_t(std::ceil(double(decision.units) * cost_factor)));
}

RoundTask first_round_task(std::size_t index, std::uint64_t seed, std::uint64_t units, std::uint64_t block_size,
                           int round) {
  return {index, units, round_seed(seed, index, round), BlockRange{0, BlockPlan{units, block_size}.blocks()}};
}

std::optional<BlockRange> RoundStart::blocks(std::uint64_t block_size) const {
  if (first_block == 0) return std::nullopt;
  return BlockRange{first_block, BlockPlan{units, block_size}.blocks()};
}

void run_once(MeasurementResult& m, const std::function<void()>& pass) {
  m.rounds.clear();
  m.partial = false;
  try {
    pass();
  } catch (const Cancelled&) {
    m.partial = true;
  }
}

void run_histogram_rounds(const RoundContext& c, MeasurementResult& m, std::uint64_t max_units,
                          const std::function<bool(const RoundStart&)>& round) {
  m.partial = false;
  while (int(m.rounds.size()) < c.options.max_rounds || (!m.rounds.empty() && m.rounds.back().partial)) {
    const RoundStart start = next_round(c, m, max_units);
    if (start.units == 0 || !round(start) || m.partial) break;
  }
  m.met = !m.rounds.empty() && !m.rounds.back().partial && m.achieved <= m.target;
}

RoundTask Measurement::first_round(std::size_t index, std::uint64_t) const {
  throw InternalError(fmt::format("measurement {} ({}) is not shared by ranks", index, decision_.label));
}

std::string Measurement::part(const RoundTask& task, const BlockRange&, const RunControl&, SurfaceCache&) const {
  throw InternalError(fmt::format("a round of measurement {}, which is not split", task.measurement));
}

void Measurement::read_back(const std::filesystem::path&, MeasurementResult&) const {}

bool is_split(const ExperimentSpec& spec, const Decision& decision) { return make_measurement(spec, decision)->split(); }

bool is_shared_by_ranks(const ExperimentSpec& spec, const Decision& decision) {
  return make_measurement(spec, decision)->shared();
}

Estimate pool_rounds(const std::vector<Estimate>& rounds, const std::vector<std::uint64_t>& units) {
  if (rounds.size() != units.size() || rounds.empty()) throw std::invalid_argument("pool_rounds: sizes differ or none");
  double total = 0, weighted = 0, variance = 0;
  for (std::size_t r = 0; r < rounds.size(); ++r) {
    const double n = double(units[r]);
    total += n;
    weighted += n * rounds[r].value;
    variance += n * n * rounds[r].standard_error * rounds[r].standard_error;
  }
  if (!(total > 0)) throw std::invalid_argument("pool_rounds: no units");
  return {weighted / total, std::sqrt(variance) / total};
}

std::vector<RoundTask> first_split_rounds(const ExperimentSpec& spec, const ExperimentPlan& plan, std::uint64_t seed) {
  std::vector<RoundTask> tasks;
  for (std::size_t i = 0; i < plan.decisions.size(); ++i) {
    const Decision& d = plan.decisions[i];
    if (!d.runnable) continue;
    const std::unique_ptr<Measurement> m = make_measurement(spec, d);
    if (m->shared()) tasks.push_back(m->first_round(i, seed));
  }
  return tasks;
}

ExperimentResults run_experiment(const ExperimentSpec& spec, const ExperimentPlan& plan, const RunOptions& options) {
  ExperimentResults results;
  SurfaceCache memory;  // without the caller's cache: surfaces for this run only
  SurfaceCache& surfaces = options.surfaces != nullptr ? *options.surfaces : memory;
  const std::uint64_t seed = options.seed != 0 ? options.seed : spec.seed;
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < plan.decisions.size(); ++i) {
    if (options.run.cancelled() || results.partial) {  // partial: a rank's part was cancelled (split rounds)
      results.partial = true;
      break;
    }
    const MeasurementResult* previous =
        options.resume != nullptr && i < options.resume->measurements.size() ? &options.resume->measurements[i] : nullptr;
    const RoundContext context{spec, i, seed, options, surfaces};
    results.measurements.push_back(run_decision(context, plan.decisions[i], previous));
    results.partial = results.partial || results.measurements.back().partial;
    if (options.on_measurement) options.on_measurement(results.measurements.back());
  }
  results.seconds = seconds_since(start) + (options.resume != nullptr ? options.resume->seconds : 0);
  return results;
}

}  // namespace microsim::experiment
