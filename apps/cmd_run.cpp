// microsim run SPEC --out DIR: carries out an experiment spec's plan (src/experiment/run.h): each runnable
// measurement in rounds until its target is met (a sequential stop on the estimate's error), then
// DIR/results.json (every decision and its reason, the achieved accuracy, the cost, the command and version)
// and DIR/albedo-K.csv per albedo table. DIR is created if missing; an existing DIR must be empty or hold
// this same spec's results (a rerun), never another spec's.
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
#include "experiment/spec.h"

#include <fmt/core.h>

#include <filesystem>
#include <fstream>
#include <memory>
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

// The digest recorded in DIR/results.json, or "" when it has none that can be read.
std::string recorded_digest(const fs::path& results) {
  std::ifstream in(results);
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object() || !j.contains("spec") || !j["spec"].is_object()) return "";
  const auto digest = j["spec"].find("digest");
  return digest != j["spec"].end() && digest->is_string() ? digest->get<std::string>() : "";
}

// An existing DIR must be a directory, empty or holding this spec's results.json.
void check_out_dir(const fs::path& dir, const experiment::ExperimentSpec& spec) {
  if (!fs::exists(dir)) {
    const fs::path parent = dir.has_parent_path() ? dir.parent_path() : fs::path(".");
    if (!fs::is_directory(parent)) throw UsageError(fmt::format("--out {}: its parent is not a directory", quote_excerpt(dir.string())));
    return;
  }
  if (!fs::is_directory(dir)) throw UsageError(fmt::format("--out {}: not a directory", quote_excerpt(dir.string())));
  if (fs::is_empty(dir)) return;
  const fs::path results = dir / "results.json";
  if (!fs::exists(results))
    throw UsageError(fmt::format("--out {}: not empty and holds no results.json: refusing to write into it",
                                 quote_excerpt(dir.string())));
  const std::string digest = recorded_digest(results);
  if (digest != experiment::spec_digest(spec))
    throw UsageError(fmt::format("--out {}: holds the results of another spec (digest '{}', this spec's {}): "
                                 "refusing to overwrite them", quote_excerpt(dir.string()), digest,
                                 experiment::spec_digest(spec)));
}

std::string reproduce_command(const RunArgs& a) {
  return fmt::format("microsim run {} --out {}{}{}", a.spec, a.out, a.seed ? fmt::format(" --seed {}", a.seed) : "",
                     a.threads ? fmt::format(" --threads {}", a.threads) : "");
}

void write_results(const RunArgs& a, const experiment::ExperimentSpec& spec, const experiment::ExperimentPlan& plan,
                   const experiment::ExperimentResults& results) {
  const fs::path dir(a.out);
  fs::create_directories(dir);
  for (std::size_t i = 0; i < results.measurements.size(); ++i)
    if (!results.measurements[i].csv.empty())
      write_file_atomically(dir / fmt::format("albedo-{}.csv", i), results.measurements[i].csv);
  const nlohmann::json doc = {{"command", reproduce_command(a)},
                              {"version", MICROSIM_VERSION},
                              {"spec", spec_identity_json(spec)},
                              {"seed", a.seed != 0 ? a.seed : spec.seed},
                              {"plan", experiment::plan_json(plan, spec)},
                              {"results", experiment::results_json(results)},
                              {"partial", results.partial}};
  write_file_atomically(dir / "results.json", doc.dump(2) + "\n");
}

int run_experiment_command(const RunArgs& a) {
  const experiment::ExperimentSpec spec = experiment::load_spec(a.spec);  // SpecError: exit 2, nothing run
  check_distinct_outputs({{"SPEC", a.spec}}, {{"--out", (fs::path(a.out) / "results.json").string()}});
  check_out_dir(a.out, spec);
  const auto progress = std::make_shared<CliProgress>(true);
  experiment::PlanOptions plan_options;
  plan_options.seed = a.seed;
  plan_options.run = cli_run_control(a.threads, progress);
  install_interrupt_handler();
  fmt::print(stderr, "run: {}: planning (pilots)\n", spec.name);
  const experiment::ExperimentPlan plan = experiment::plan_experiment(spec, plan_options);  // Cancelled: nothing written
  progress->finish();
  print_plan_table(plan, spec);
  if (a.dry_run) return kExitOk;  // the plan and its predicted time; nothing written
  experiment::RunOptions options;
  options.seed = a.seed;
  options.run = plan_options.run;
  options.on_measurement = [&](const experiment::MeasurementResult& m) {
    progress->finish();
    print_measurement_line(m);
  };
  const experiment::ExperimentResults results = experiment::run_experiment(spec, plan, options);
  progress->finish();
  print_results_table(results);
  write_results(a, spec, plan, results);
  if (results.partial) {
    fmt::print(stderr, "run: interrupted: {} written, marked partial\n", (fs::path(a.out) / "results.json").string());
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
      "command, version) and DIR/albedo-K.csv. Runs albedo (analytic, smith-walk) and vndf (ellipsoid oracle) "
      "measurements; others are planned and reported as not run. Exit 0 done, 2 bad spec or usage (nothing run), "
      "130 interrupted (partial results written).");
  sub->add_option("SPEC", args->spec, "the experiment spec (.toml, or .json)")->required();
  sub->add_option("--out", args->out, "the results directory (created; empty, or holding this spec's results)")->required();
  sub->add_flag("--dry-run", args->dry_run, "plan only (the pilots run): print the plan and its predicted time, write nothing");
  add_number_option(sub, "--seed", args->seed, whole(), "seed of the pilots and rounds (0: the spec's)")->default_str("0");
  add_number_option(sub, "--threads", args->threads, integer(0, kMaxThreads),
                    at_most("worker threads (0: all cores)", kMaxThreads))
      ->default_str("0");
  on_selected(sub, [args] { return run_experiment_command(*args); });
}};

}  // namespace
}  // namespace microsim::app
