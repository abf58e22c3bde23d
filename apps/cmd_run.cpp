// microsim run SPEC --out DIR: carries out an experiment spec's plan (src/experiment/run.h): each runnable
// measurement in rounds until its target is met (a sequential stop on the estimate's error), then
// DIR/results.json (every decision and its reason, the achieved accuracy, the cost, the command and version)
// and DIR/index.html (the report), DIR/albedo-K.csv, DIR/vndf-K.exr (src/experiment/run_directory.h). DIR is
// created if missing; an existing DIR must be empty or hold this same spec's run at the same seed, which is
// then resumed (finished measurements kept, a partial one continued, its pilots not run again).
//
// Exit codes (the run's verdict, src/experiment/verdict.h, decides 0 or 1): 0 done and no statistical test
// rejected (every validation passed, or none ran; a target not met within the rounds is reported in the table
// and results.json, with all_targets_met false, and is not an error), 1 done and a validation rejected (verdict
// fail: its name on stdout, in results.json's `rejected` and the report's headline; enough samples or not),
// 2 bad spec or usage (nothing run, nothing written), 3 internal error, 130 interrupted (during the pilots:
// nothing written; during the runs: what was done written, marked partial, its verdict so far recorded). The
// same for `--merge` and under MPI (rank 0 decides the code and sends it to the other ranks, which return it),
// and for a resumed run (the verdict is derived from the results again: the same code).
#include "command.h"
#include "experiment_report.h"
#include "number_options.h"
#include "mpi_ranks.h"
#include "progress_bar.h"

#include "core/atomic_file.h"
#include "core/parse.h"
#include "experiment/plan.h"
#include "experiment/run.h"
#include "experiment/run_directory.h"
#include "experiment/spec.h"
#include "experiment/shards.h"
#include "experiment/split_rounds.h"
#include "measure/surface_cache.h"
#include "experiment/verdict.h"

#include <fmt/core.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#ifndef MICROSIM_VERSION
#define MICROSIM_VERSION "unknown"
#endif

namespace microsim::app {
namespace {

namespace fs = std::filesystem;

struct RunArgs {
  std::string spec, out;
  std::string shard;               // --shard K/N: this job's shard of the first rounds (shards.h)
  std::vector<std::string> merge;  // --merge PART...: the shards' directories
  std::uint64_t seed = 0;
  int threads = 0;
  bool dry_run = false;
};

std::string reproduce_command(const RunArgs& a) {
  return fmt::format("microsim run {} --out {}{}{}", a.spec, a.out, a.seed ? fmt::format(" --seed {}", a.seed) : "",
                     a.threads ? fmt::format(" --threads {}", a.threads) : "");
}

// The shards of `--merge`, checked (one job: same spec, seed, plan and N, each K once); UsageError naming the
// problem. Their first rounds are taken from their parts; everything else runs here.
experiment::StoredRounds merged_shards(const RunArgs& a, const experiment::ExperimentSpec& spec, std::uint64_t seed,
                                       const nlohmann::json& inputs, experiment::ExperimentPlan& plan) {
  std::vector<experiment::ShardParts> shards;
  try {
    for (const std::string& dir : a.merge) shards.push_back(experiment::read_shard_directory(dir, spec, seed, inputs));
    plan = experiment::plan_from_json(shards.front().plan, spec);
    return experiment::merge_shards(shards, a.merge);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
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
  return experiment::plan_experiment(spec, options);  // Cancelled: no results written (built tiles are kept)
}

// The exit code of a written run: 130 interrupted (resumable; its verdict may already be fail), 1 when a
// validation rejected (the verdict fail), else 0 (every test passed, or none ran).
int run_exit_code(const experiment::ExperimentResults& results) {
  if (results.partial) return kExitInterrupted;
  return experiment::run_verdict(results).verdict == experiment::Verdict::fail ? kExitRejected : kExitOk;
}

// DIR's files and the summary; the exit code (run_exit_code).
int write_results(const RunArgs& a, const experiment::ExperimentSpec& spec, const experiment::ExperimentPlan& plan,
                  const experiment::ExperimentResults& results, std::uint64_t seed, const nlohmann::json& inputs) {
  print_results_table(results);
  experiment::write_run_directory(a.out, spec, plan, results, {reproduce_command(a), MICROSIM_VERSION, seed, inputs});
  fmt::print(stderr, "run: wrote {} and {}\n", (fs::path(a.out) / "results.json").string(),
             (fs::path(a.out) / "index.html").string());
  const int code = run_exit_code(results);
  if (code == kExitInterrupted)
    fmt::print(stderr, "run: interrupted: results marked partial; run the same command{} again to resume\n",
               a.merge.empty() ? "" : " without --merge (the shards' rounds are in --out)");
  if (code == kExitRejected) fmt::print(stderr, "run: a validation rejected: exit {}\n", kExitRejected);
  return code;
}

// The plan: the shards' (`--merge`: `stored` receives their first rounds), an earlier run's, or the pilots'.
experiment::ExperimentPlan plan_or_shards(const RunArgs& a, const experiment::ExperimentSpec& spec, std::uint64_t seed,
                                          const nlohmann::json& inputs,
                                          const std::optional<experiment::PreviousRun>& previous,
                                          const experiment::PlanOptions& options, experiment::StoredRounds& stored) {
  if (a.merge.empty()) return plan_of(spec, previous, options);
  if (previous) throw UsageError(fmt::format("--merge: --out {} holds a run: the merge writes a new one", a.out));
  experiment::ExperimentPlan plan;
  stored = merged_shards(a, spec, seed, inputs, plan);
  return plan;
}

// The run writes its files under --out (results, report, figures, surfaces, parts): no file the spec reads may
// lie there. UsageError naming the spec's key.
void check_inputs_outside(const experiment::ExperimentSpec& spec, const std::string& out) {
  const fs::path dir = fs::weakly_canonical(fs::absolute(out));
  for (const PathOption& in : experiment::spec_input_files(spec)) {
    const fs::path rel = fs::weakly_canonical(fs::absolute(in.path)).lexically_relative(dir);
    if (!rel.empty() && *rel.begin() != "..")
      throw UsageError(fmt::format("{} '{}' lies inside --out {}: the run writes there; keep its inputs outside",
                                   in.option, in.path.string(), out));
  }
}

// The run on the root (alone, or rank 0 of an MPI job: `ranks` then serve its rounds). `plan_sent`: whether
// the other ranks got the plan (after that, an error must abort the job: they may be inside a round).
int run_experiment_command(const RunArgs& a, experiment::Ranks& ranks, bool& plan_sent) {
  const experiment::ExperimentSpec spec = experiment::load_spec(a.spec);  // SpecError: exit 2, nothing run
  check_distinct_outputs({{"SPEC", a.spec}}, {{"--out", (fs::path(a.out) / "results.json").string()}});
  check_inputs_outside(spec, a.out);
  const std::uint64_t seed = a.seed != 0 ? a.seed : spec.seed;
  const nlohmann::json inputs = experiment::input_digests(spec);  // once: compared on resume, then recorded
  const std::optional<experiment::PreviousRun> previous = experiment::load_previous_run(a.out, spec, seed, inputs);
  const auto progress = std::make_shared<CliProgress>(true);
  experiment::PlanOptions plan_options;
  plan_options.seed = a.seed;
  plan_options.run = cli_run_control(a.threads, progress);
  // Explicit surfaces: built once, in DIR/surfaces (a dry run keeps them in memory: nothing written).
  SurfaceCache surfaces(a.dry_run ? fs::path{} : fs::path(a.out) / "surfaces");
  plan_options.surfaces = &surfaces;
  install_interrupt_handler();
  experiment::StoredRounds stored;
  experiment::ExperimentPlan plan;
  try {
    plan = plan_or_shards(a, spec, seed, inputs, previous, plan_options, stored);
  } catch (const Cancelled&) {
    if (surfaces.builds() == 0 || a.dry_run) throw;  // nothing written: the common message
    progress->finish();
    fmt::print(stderr, "run: interrupted while planning: no results written; the {} surface(s) built so far are kept "
               "in {} for the next run\n", surfaces.builds(), (fs::path(a.out) / "surfaces").string());
    experiment::send_stop(ranks, kExitInterrupted);
    return kExitInterrupted;
  }
  progress->finish();
  print_plan_table(plan, spec);
  if (a.dry_run) {  // the plan and its predicted time; nothing written
    experiment::send_stop(ranks, kExitOk);
    return kExitOk;
  }
  experiment::send_plan(ranks, spec, plan);
  plan_sent = true;
  experiment::RunOptions options;
  options.seed = a.seed;
  options.run = plan_options.run;
  options.resume = previous ? &previous->results : nullptr;
  options.ranks = &ranks;
  options.stored = a.merge.empty() ? nullptr : &stored;
  options.surfaces = &surfaces;
  std::size_t done = 0;  // the overall progress: measurements done, and the plan's predicted time of the rest
  options.on_measurement = [&](const experiment::MeasurementResult& m) {
    progress->finish();
    print_measurement_line(m);
    print_overall_line(plan, ++done);
  };
  const experiment::ExperimentResults results = experiment::run_experiment(spec, plan, options);
  progress->finish();
  const int code = write_results(a, spec, plan, results, seed, inputs);
  experiment::send_stop(ranks, code);
  return code;
}

// ---- under an MPI launcher (apps/mpi_ranks.h; docs/guide/experiments-and-clusters.md) ----------------------------------------------

// Rank 0: the run; an error before the plan went out stops the other ranks with its exit code, after it
// aborts the job (MPI_Abort with the code: the other ranks may be inside a round).
int run_as_root(const RunArgs& a, MpiSession& mpi) {
  bool plan_sent = false;
  try {
    return run_experiment_command(a, mpi.ranks(), plan_sent);
  } catch (...) {
    const int code = report_error(std::current_exception());
    if (plan_sent) mpi.abort(code);
    experiment::send_stop(mpi.ranks(), code);
    return code;
  }
}

// Ranks 1..: silent; they run their shards of the root's rounds and return the root's exit code. Their own
// error (a spec that differs from the root's, a failure in a shard) is printed with the rank and aborts the job.
// Explicit surfaces: the root's files in DIR/surfaces where this rank sees them, else built here in memory (the
// root alone writes DIR).
int serve_as_rank(const RunArgs& a, MpiSession& mpi) {
  try {
    RunControl run = cli_run_control(a.threads, nullptr);
    SurfaceCache surfaces(fs::path(a.out) / "surfaces", CacheFiles::read_only);
    return experiment::serve_rounds(mpi.ranks(), [&] { return experiment::load_spec(a.spec); }, run, surfaces);
  } catch (...) {
    mpi.abort(report_error(std::current_exception(), fmt::format("microsim run (rank {})", mpi.ranks().rank())));
  }
}

// Started by a launcher without MPI compiled in: every process would run the whole experiment into one DIR.
int refuse_without_mpi(const LaunchedRank& launched) {
  if (launched.rank == 0)
    fmt::print(stderr,
               "microsim: error: run: started by an MPI launcher ({}={}) but MPI is not compiled in (CMake found no MPI, "
               "or MICROSIM_MPI=OFF): refusing to run the whole experiment in every process; run it without mpirun, "
               "or split it with --shard K/N (docs/guide/experiments-and-clusters.md)\n",
               launched.variable, launched.rank);
  return kExitUsage;
}

// ---- a job array's shard (`--shard K/N`; src/experiment/shards.h) --------------------------------------------

constexpr std::uint64_t kMaxShards = 100000;

int run_one_shard(const RunArgs& a) {
  if (!a.merge.empty() || a.dry_run) throw UsageError("--shard runs one shard of a job array: not with --merge or --dry-run");
  const ShardSpec s = parse_shard("--shard", a.shard, kMaxShards);  // ParseError: exit 2
  const experiment::ExperimentSpec spec = experiment::load_spec(a.spec);
  check_distinct_outputs({{"SPEC", a.spec}}, {{"--out", (fs::path(a.out) / "shard.json").string()}});
  check_inputs_outside(spec, a.out);
  if (fs::exists(a.out) && (!fs::is_directory(a.out) || !fs::is_empty(a.out)))
    throw UsageError(fmt::format("--out {}: a shard's directory must be new or empty", a.out));
  const std::uint64_t seed = a.seed != 0 ? a.seed : spec.seed;
  const auto progress = std::make_shared<CliProgress>(true);
  experiment::PlanOptions plan_options;
  plan_options.seed = a.seed;
  plan_options.run = cli_run_control(a.threads, progress);
  SurfaceCache surfaces;  // explicit surfaces in memory: built once, for the plan and the rounds
  plan_options.surfaces = &surfaces;
  install_interrupt_handler();
  fmt::print(stderr, "run: {}: planning (pilots)\n", spec.name);
  const experiment::ExperimentPlan plan = experiment::plan_experiment(spec, plan_options);
  progress->finish();
  print_plan_table(plan, spec);
  const experiment::ShardParts shard = experiment::run_shard(spec, plan, seed, s.index, s.count, plan_options.run, surfaces);
  progress->finish();
  experiment::write_shard_directory(a.out, spec, shard);
  fmt::print(stderr, "run: shard {}/{}: the first rounds of {} measurements written to {}; when all {} are done: "
             "microsim run {} --out DIR --merge PART...{}\n", s.index, s.count, shard.tasks.size(), a.out, s.count, a.spec,
             a.seed ? fmt::format(" --seed {}", a.seed) : "");
  return kExitOk;
}

int run_command(const RunArgs& a) {
  const std::optional<LaunchedRank> launched = mpi_launch();
  if (!a.shard.empty()) {
    if (launched && launched->size != 1) throw UsageError("--shard is for job arrays without MPI: not under mpirun or srun");
    return run_one_shard(a);
  }
  if (!launched || (!mpi_compiled_in() && launched->size == 1)) {
    experiment::SingleProcess alone;
    bool plan_sent = false;
    return run_experiment_command(a, alone, plan_sent);
  }
  if (!mpi_compiled_in()) return refuse_without_mpi(*launched);
  MpiSession mpi;
  install_interrupt_handler();
  install_termination_handler();  // mpirun turns Ctrl-C into SIGTERM for every rank
  return mpi.ranks().rank() == 0 ? run_as_root(a, mpi) : serve_as_rank(a, mpi);
}

CommandRegistration run_registration{"run", [](CLI::App& app) {
  auto args = std::make_shared<RunArgs>();
  auto* sub = app.add_subcommand(
      "run",
      "Carry out an experiment spec (docs/reference/experiments.md): plan it (pilots), then run each measurement in rounds "
      "until its target accuracy is met, and write DIR/results.json (decisions, reasons, achieved accuracy, cost, "
      "command, version), the report DIR/index.html, DIR/albedo-K.csv, DIR/vndf-K.exr, DIR/scattering-K.exr and "
      "DIR/validation-K.exr. Run again with the same seed, it resumes an interrupted run. Runs albedo (analytic, "
      "smith-walk), vndf (ellipsoid oracle), scattering (smith-walk; order 1 analytic) and validation (a zoo sampler "
      "or a dump) and masking (G1, G2 by Smith's closed forms; conditional masking or a named surface traced on the "
      "explicit heightfield) measurements; the other kinds' that need an explicit heightfield are planned and "
      "reported as not run. Exit 0 "
      "done and no test rejected, 1 a validation rejected (verdict fail: named on stdout, in results.json and the "
      "report's headline), 2 bad spec or usage (nothing run), 3 internal error, "
      "130 interrupted (partial results written). " +
          std::string(mpi_compiled_in()
                          ? "MPI is compiled in: under mpirun or srun every VNDF and scattering round and every "
                            "validation of a zoo sampler is split over the "
                            "ranks, bit for bit the one-process results (docs/guide/experiments-and-clusters.md)."
                          : "MPI is not compiled in: a run under mpirun or srun is refused (docs/guide/experiments-and-clusters.md)."));
  sub->add_option("SPEC", args->spec, "the experiment spec (.toml, or .json)")->required();
  sub->add_option("--out", args->out, "the results directory (created; empty, or holding this spec's run at this seed: resumed)")->required();
  sub->add_option("--shard", args->shard,
                  "K/N: run block shard K of N of the first round of every VNDF and scattering measurement (a job "
                  "array without MPI) into --out PART (new or empty); then --merge (docs/guide/experiments-and-clusters.md)");
  sub->add_option("--merge", args->merge,
                  "PART...: the N shard directories of one job: their first rounds combined (bit for bit the "
                  "one-process rounds), the sequential stop decided on them, further rounds and the other "
                  "measurements run here; --out must be new or empty")
      ->expected(1, -1);
  sub->add_flag("--dry-run", args->dry_run, "plan only (the pilots run): print the plan and its predicted time, write nothing");
  add_number_option(sub, "--seed", args->seed, whole(), "seed of the pilots and rounds (0: the spec's)")->default_str("0");
  add_number_option(sub, "--threads", args->threads, integer(0, kMaxThreads),
                    at_most("worker threads (0: all cores)", kMaxThreads))
      ->default_str("0");
  on_selected(sub, [args] { return run_command(*args); });
}};

}  // namespace
}  // namespace microsim::app
