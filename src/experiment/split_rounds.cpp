// experiment: the rounds of run_experiment split over ranks (split_rounds.h).
#include "experiment/split_rounds.h"

#include "core/errors.h"
#include "core/wall_clock.h"
#include "measure/masking_runs.h"
#include "experiment/measurement.h"
#include "experiment/surface_albedo.h"
#include "validate/validation_part.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <optional>
#include <stdexcept>
#include <type_traits>

namespace microsim::experiment {
namespace {

// ---- messages ---------------------------------------------------------------------------------------------

std::string stop_message(int exit_code) { return nlohmann::json{{"stop", exit_code}}.dump(); }

nlohmann::json parse_message(const std::string& text) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw InternalError(fmt::format("a message from the root is not JSON: {}", e.what()));
  }
}

}  // namespace

std::string task_message(const RoundTask& task) { return nlohmann::json{{"round", round_task_json(task)}}.dump(); }

const std::vector<std::string>* stored_parts(const StoredRounds* stored, const RoundTask& task) {
  if (stored == nullptr) return nullptr;
  for (std::size_t t = 0; t < stored->tasks.size(); ++t)
    if (stored->tasks[t] == task) return &stored->parts[t];
  return nullptr;
}

void check_part_count(const std::vector<std::string>& parts, int ranks) {
  if (parts.size() != std::size_t(ranks))
    throw InternalError(fmt::format("a split round gathered {} parts from {} ranks", parts.size(), ranks));
}

std::optional<std::vector<SurfaceMasking>> split_masking_round(const RoundSplit& split, std::size_t measurement,
                                                               const MaskingRuns& h, std::uint64_t surface_seed,
                                                               const BlockRange& blocks, const RunControl& run) {
  using Sums = std::optional<std::vector<SurfaceMasking>>;
  const RoundTask task{measurement, kMaskingRunSamples, h.seed(), blocks, surface_seed};
  return split_round<Sums>(
      split, task,
      [&](const std::optional<BlockRange>& mine) { return h.measure_round(mine ? *mine : blocks, run); },
      [&](const Sums& own, const BlockRange& mine) { return masking_round_part(task, mine, own); },
      [&](Sums own, const std::vector<std::string>& parts, int first) {
        return combine_masking_parts(std::move(own), parts, task, first);
      });
}

ValidationReport split_validation(const RoundSplit& split, std::size_t measurement, const ValidationCase& validation,
                                  const ValidationOptions& options) {
  const BlockRange round{0, BlockPlan{options.samples, kSampleBlock}.blocks()};
  const RoundTask task{measurement, options.samples, options.seed, round};
  const bool ranks = split.ranks != nullptr && split.ranks->size() > 1;
  const SamplerInfo& sampler = *validation.sampler;
  if (stored_parts(split.stored, task) == nullptr && !ranks)
    return validate_sampler(sampler, validation.ggx(), validation.wi(), options);
  const auto start = std::chrono::steady_clock::now();
  require_samples_for_any_test(options.samples);  // before the cubature, as validate_sampler
  const auto reference = claimed_reference(sampler, validation.ggx(), validation.wi(), options.rows);
  require_samples(options.samples, *reference);
  const ValidationRun run = drawn_validation_run(validation, options);
  using Part = std::optional<ValidationPart>;
  const battery::Tally tally = split_round<Part, battery::Tally>(
      split, task,  // never alone here (validate_sampler above): `mine` is always a block range
      [&](const std::optional<BlockRange>& mine) { return own_validation_part(run, *mine); },
      [&](const Part& own, const BlockRange& mine) { return validation_round_part(task, mine, own); },
      [&](Part own, const std::vector<std::string>& parts, int first) {
        return merged_validation_tally(own, parts, task, first);
      });
  ValidationReport r = report_drawn_samples(sampler, *reference, tally, options);
  r.seconds = seconds_since(start);
  return r;
}

void send_plan(Ranks& ranks, const ExperimentSpec& spec, const ExperimentPlan& plan) {
  if (ranks.size() > 1) ranks.broadcast(nlohmann::json{{"plan", plan_json(plan, spec)}, {"spec_digest", spec_digest(spec)}}.dump());
}

void send_stop(Ranks& ranks, int exit_code) {
  if (ranks.size() > 1) ranks.broadcast(stop_message(exit_code));
}

std::string run_part(const ExperimentSpec& spec, const ExperimentPlan& plan, const RoundTask& task, int rank, int ranks,
                     const RunControl& run, SurfaceCache& surfaces) {
  if (task.measurement >= plan.decisions.size())
    throw InternalError(fmt::format("a round of measurement {}: the plan has {}", task.measurement, plan.decisions.size()));
  const std::unique_ptr<Measurement> m = make_measurement(spec, plan.decisions[task.measurement]);
  if (!m->shared()) throw InternalError(fmt::format("a round of measurement {}, which is not split", task.measurement));
  return m->part(task, rank_blocks(task.blocks, rank, ranks), run, surfaces);
}

namespace {

// The plan the root sent, for this rank's spec (which must be the root's).
ExperimentPlan received_plan(const nlohmann::json& message, const ExperimentSpec& spec, int rank) {
  const auto root_digest = message.at("spec_digest").get<std::string>();
  if (spec_digest(spec) != root_digest)
    throw std::invalid_argument(fmt::format("rank {}: the spec {} is not rank 0's (digest {} here, {} there): every rank "
                                            "must read the same spec",
                                            rank, spec.source, spec_digest(spec), root_digest));
  return plan_from_json(message.at("plan"), spec);
}

}  // namespace

int serve_rounds(Ranks& ranks, const std::function<ExperimentSpec()>& load_spec, const RunControl& run,
                 SurfaceCache& surfaces) {
  nlohmann::json message = parse_message(ranks.broadcast(""));
  if (message.contains("stop")) return message.at("stop").get<int>();
  const ExperimentSpec spec = load_spec();
  ExperimentPlan plan;
  try {
    plan = received_plan(message, spec, ranks.rank());
  } catch (const nlohmann::json::exception& e) {
    throw InternalError(fmt::format("rank {}: the plan from the root is malformed: {}", ranks.rank(), e.what()));
  }
  for (;;) {
    message = parse_message(ranks.broadcast(""));
    if (message.contains("stop")) return message.at("stop").get<int>();
    std::string part;
    try {
      part = run_part(spec, plan, round_task_from_json(message.at("round")), ranks.rank(), ranks.size(), run, surfaces);
    } catch (const nlohmann::json::exception& e) {
      throw InternalError(fmt::format("rank {}: a round from the root is malformed: {}", ranks.rank(), e.what()));
    }
    ranks.gather(part);
  }
}

}  // namespace microsim::experiment
