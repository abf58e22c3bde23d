// experiment: carrying out a plan (`microsim run`): every runnable decision in rounds until its target is met,
// a sequential stop on the estimate's own error (never a fixed count). Each kind's rounds are its Measurement's
// (measurement.h; one file per kind, measurement_registry.cpp chooses it); this driver runs them in plan order.
// At most kMaxRounds rounds: a target not met then is reported as such (met = false), never hidden.
// Cancellation (run.cancel): the round in progress is dropped (a histogram's round keeps its completed blocks,
// the block runner's prefix: a shorter run of that seed, recorded as a partial round), what the completed
// rounds measured is kept and the results are marked partial. Same seed, same results, whatever the thread
// count, ranks or shards (each round is a block-runner call of its own seed; the round sizes follow from the
// results). Resumption (RunOptions::resume, an interrupted run of the same spec, plan and seed): a finished
// measurement is kept as it is; a partial one continues as its kind says (a histogram from its sums, its
// partial round traced on from its first missing block: the uninterrupted run's counts, bit for bit). Never
// prints.
#pragma once

#include "core/estimate.h"
#include "experiment/plan.h"
#include "experiment/ranks.h"
#include "experiment/split_rounds.h"
#include "stats/histogram_io.h"
#include "stats/scatter_expectation.h"
#include "stats/scatter_histogram.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <string>
#include <vector>

namespace microsim::experiment {

struct RoundRecord {
  std::uint64_t units = 0;  // paths per cell, rays; 0 for a deterministic round
  std::uint64_t planned = 0;      // the units the round was asked for (a partial VNDF round: more than units)
  std::uint64_t blocks_done = 0;  // VNDF: the round's blocks [0, blocks_done) are in the counts
  bool partial = false;           // cancelled part way (VNDF: resumable from blocks_done)
  std::uint64_t seed = 0;
  double tolerance = 0;     // analytic rounds
  double seconds = 0;
  double achieved = 0;      // the error after this round, in the target's unit
};

struct MeasurementResult {
  Decision decision;
  double target = 0;            // the spec's target: relative SE, a TV to resolve (achieved: resolved_tv) or detect
  std::string error_measure;    // what `achieved` is
  double achieved = 0;
  bool met = false;
  bool ran = false;             // false: not runnable in this version (decision.not_runnable says why)
  bool partial = false;         // cancelled during its rounds
  std::vector<RoundRecord> rounds;
  std::uint64_t units = 0;      // summed over the rounds (paths per cell, rays)
  std::uint64_t rays = 0;       // every ray or path traced or walked (albedo: units x cells)
  double seconds = 0;
  nlohmann::json values;        // what was measured (an albedo table, a VNDF analysis)
  std::string csv;              // albedo: the table as CSV (scatter/albedo_table_io.h), else ""
  // What a resumed run continues from (not in `values`): VNDF: the summed counts (with the analytic
  // probabilities: the report's figure) and unbinned hits; walk albedo: each completed round's table.
  TracedHistogram histogram;
  std::vector<std::uint64_t> unbinned;
  ScatterHistogram scatter;  // scattering: the rounds' walks summed (exact sums)
  ScatterExpectation expectation;  // analytic scattering: the order-1 lobe
  std::vector<nlohmann::json> round_tables;  // albedo_table_json of each round
};

struct ExperimentResults {
  std::vector<MeasurementResult> measurements;
  bool partial = false;
  double seconds = 0;
};

struct RunOptions {
  std::uint64_t seed = 0;  // 0: the spec's
  RunControl run;
  // The results of an interrupted run of the same spec, plan and seed, to continue (see the header); null:
  // start afresh.
  const ExperimentResults* resume = nullptr;
  // The first round's units are the planned units times this (the honesty check: a run at 4x the planned
  // cost must not move the results by more than the target); 1 normally.
  double cost_factor = 1;
  // Rounds at most (a fixed-cost run: 1); a target not met then is reported as such.
  int max_rounds = kMaxRounds;
  // The ranks the VNDF and scattering rounds are split over (split_rounds.h; this process is the root, and
  // the others serve_rounds); null: this process alone. Same results either way, bit for bit.
  Ranks* ranks = nullptr;
  // The first rounds run by shard jobs (`run --shard K/N`, shards.h), taken from their parts; null: none.
  const StoredRounds* stored = nullptr;
  // Where the explicit surfaces of heightfield decisions are built once or read back (surface_cache.h: the
  // plan's cache, DIR/surfaces); null: a cache in memory for this call.
  SurfaceCache* surfaces = nullptr;
  // Called after each measurement (complete, partial or skipped), on the calling thread.
  std::function<void(const MeasurementResult&)> on_measurement;
};

ExperimentResults run_experiment(const ExperimentSpec& spec, const ExperimentPlan& plan, const RunOptions& options);

// The first round of every measurement the ranks share (Measurement::first_round) as run_experiment starts it
// afresh at `seed` (the run's: options.seed, or the spec's): units, seed and blocks. What shard jobs run.
std::vector<RoundTask> first_split_rounds(const ExperimentSpec& spec, const ExperimentPlan& plan, std::uint64_t seed);

// Independent rounds of n_r units with means m_r and standard errors se_r pooled as one run of sum n_r units:
// mean sum n_r m_r / N, standard error sqrt(sum n_r^2 se_r^2) / N. Pure; throws std::invalid_argument when
// the sizes differ or nothing was run.
Estimate pool_rounds(const std::vector<Estimate>& rounds, const std::vector<std::uint64_t>& units);

// results.json's members for a plan and for results (the CLI adds the command, version and spec).
nlohmann::json plan_json(const ExperimentPlan& plan, const ExperimentSpec& spec);
nlohmann::json results_json(const ExperimentResults& results);

// The inverses, for a resumed run: the plan of a document's "plan" member for this spec, and the results of
// its "results" member for that plan (the VNDF histograms are not in the JSON: the caller reads them, see
// run_directory.h). Throw std::invalid_argument naming the first member that is missing or malformed.
ExperimentPlan plan_from_json(const nlohmann::json& plan, const ExperimentSpec& spec);
ExperimentResults results_from_json(const nlohmann::json& results, const ExperimentPlan& plan);

}  // namespace microsim::experiment
