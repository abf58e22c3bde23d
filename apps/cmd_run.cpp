// microsim run SPEC --out DIR: carries out an experiment spec's plan (src/experiment/run.h): each runnable
// measurement in rounds until its target is met (a sequential stop on the estimate's error), then
// DIR/results.json (every decision and its reason, the achieved accuracy, the cost, the command and version)
// and DIR/index.html (the report), DIR/albedo-K.csv, DIR/vndf-K.exr (src/experiment/run_directory.h). DIR is
// created if missing; an existing DIR must be empty or hold this same spec's run at the same seed, which is
// then resumed (finished measurements kept, a partial one continued, its pilots not run again).
//
// Exit codes: 0 done (a target not met within the rounds is reported in the table and results.json, with
// all_targets_met false), 2 bad spec or usage (nothing run, nothing written), 130 interrupted (during the
// pilots: nothing written; during the runs: what was done written, marked partial).
#include "command.h"
#include "experiment_report.h"
#include "number_options.h"
#include "progress_bar.h"

#include "core/atomic_file.h"
#include "experiment/plan.h"
#include "experiment/run.h"
#include "experiment/run_directory.h"
#include "experiment/spec.h"

#include <fmt/core.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#ifndef MICROSIM_VERSION
#define MICROSIM_VERSION "unknown"
#endif

namespace microsim::app {
namespace {

namespace fs = std::filesystem;

struct RunArgs {
  std::string spec, out;
  std::uint64_t seed = 0;
  int threads = 0;
  bool dry_run = false;
};

std::string reproduce_command(const RunArgs& a) {
  return fmt::format("microsim run {} --out {}{}{}", a.spec, a.out, a.seed ? fmt::format(" --seed {}", a.seed) : "",
                     a.threads ? fmt::format(" --threads {}", a.threads) : "");
}

// The plan: an earlier run's (resumed: its pilots are not run again), or from the pilots.
experiment::ExperimentPlan plan_of(const experiment::ExperimentSpec& spec, const std::optional<experiment::PreviousRun>& previous,
                                   const experiment::PlanOptions& options) {
  if (previous) {
    std::size_t done = 0;
    for (const auto& m : previous->results.measurements) done += m.partial ? 0 : 1;
    fmt::print(stderr, "run: {}: resuming: {} of {} measurements done{}\n", spec.name, done,
               previous->plan.decisions.size(), previous->results.partial ? "" : " (the run was complete)");
    return previous->plan;
  }
  fmt::print(stderr, "run: {}: planning (pilots)\n", spec.name);
  return experiment::plan_experiment(spec, options);  // Cancelled: nothing written
}

int run_experiment_command(const RunArgs& a) {
  const experiment::ExperimentSpec spec = experiment::load_spec(a.spec);  // SpecError: exit 2, nothing run
  check_distinct_outputs({{"SPEC", a.spec}}, {{"--out", (fs::path(a.out) / "results.json").string()}});
  const std::uint64_t seed = a.seed != 0 ? a.seed : spec.seed;
  const std::optional<experiment::PreviousRun> previous = experiment::load_previous_run(a.out, spec, seed);
  const auto progress = std::make_shared<CliProgress>(true);
  experiment::PlanOptions plan_options;
  plan_options.seed = a.seed;
  plan_options.run = cli_run_control(a.threads, progress);
  install_interrupt_handler();
  const experiment::ExperimentPlan plan = plan_of(spec, previous, plan_options);
  progress->finish();
  print_plan_table(plan, spec);
  if (a.dry_run) return kExitOk;  // the plan and its predicted time; nothing written
  experiment::RunOptions options;
  options.seed = a.seed;
  options.run = plan_options.run;
  options.resume = previous ? &previous->results : nullptr;
  std::size_t done = 0;  // the overall progress: measurements done, and the plan's predicted time of the rest
  options.on_measurement = [&](const experiment::MeasurementResult& m) {
    progress->finish();
    print_measurement_line(m);
    print_overall_line(plan, ++done);
  };
  const experiment::ExperimentResults results = experiment::run_experiment(spec, plan, options);
  progress->finish();
  print_results_table(results);
  experiment::write_run_directory(a.out, spec, plan, results, {reproduce_command(a), MICROSIM_VERSION, seed});
  fmt::print(stderr, "run: wrote {} and {}\n", (fs::path(a.out) / "results.json").string(),
             (fs::path(a.out) / "index.html").string());
  if (results.partial) {
    fmt::print(stderr, "run: interrupted: results marked partial; run the same command again to resume\n");
    return kExitInterrupted;
  }
  return kExitOk;
}

CommandRegistration run_registration{"run", [](CLI::App& app) {
  auto args = std::make_shared<RunArgs>();
  auto* sub = app.add_subcommand(
      "run",
      "Carry out an experiment spec (docs/experiments.md): plan it (pilots), then run each measurement in rounds "
      "until its target accuracy is met, and write DIR/results.json (decisions, reasons, achieved accuracy, cost, "
      "command, version), the report DIR/index.html, DIR/albedo-K.csv and DIR/vndf-K.exr. Run again with the same "
      "seed, it resumes an interrupted run. Runs albedo (analytic, smith-walk) and vndf (ellipsoid oracle) "
      "measurements; others are planned and reported as not run. Exit 0 done, 2 bad spec or usage (nothing run), "
      "130 interrupted (partial results written).");
  sub->add_option("SPEC", args->spec, "the experiment spec (.toml, or .json)")->required();
  sub->add_option("--out", args->out, "the results directory (created; empty, or holding this spec's run at this seed: resumed)")->required();
  sub->add_flag("--dry-run", args->dry_run, "plan only (the pilots run): print the plan and its predicted time, write nothing");
  add_number_option(sub, "--seed", args->seed, whole(), "seed of the pilots and rounds (0: the spec's)")->default_str("0");
  add_number_option(sub, "--threads", args->threads, integer(0, kMaxThreads),
                    at_most("worker threads (0: all cores)", kMaxThreads))
      ->default_str("0");
  on_selected(sub, [args] { return run_experiment_command(*args); });
}};

}  // namespace
}  // namespace microsim::app
