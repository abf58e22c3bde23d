// microsim plan SPEC: the planner's decisions for an experiment spec (src/experiment/plan.h): per measurement
// the cheapest sufficient model and why, the walk's order cap, the count from a short pilot run and the time
// predicted on this machine. Nothing but the pilots is run; --json PATH writes the plan atomically.
//
// Exit codes: 0 planned, 2 bad spec or usage (the key and line named, nothing run), 130 interrupted (nothing
// written).
#include "command.h"
#include "experiment_report.h"
#include "number_options.h"
#include "progress_bar.h"

#include "core/atomic_file.h"
#include "experiment/plan.h"
#include "experiment/run_directory.h"
#include "experiment/spec.h"

#include <fmt/core.h>

#include <memory>
#include <string>

namespace microsim::app {
namespace {

struct PlanArgs {
  std::string spec, json;
  std::uint64_t seed = 0;
  int threads = 0;
};

int run_plan(const PlanArgs& a) {
  check_output("--json", a.json);
  const experiment::ExperimentSpec spec = experiment::load_spec(a.spec);  // SpecError: exit 2, nothing run
  check_distinct_outputs(experiment::spec_input_files(spec), {{"--json", a.json}});  // the spec, dumps, plugins...
  const auto progress = std::make_shared<CliProgress>(true);
  experiment::PlanOptions options;
  options.seed = a.seed;
  options.run = cli_run_control(a.threads, progress);
  install_interrupt_handler();
  fmt::print(stderr, "plan: {} ({} materials, {} quantities): running the pilots\n", spec.name, spec.materials.size(),
             spec.quantities.size());
  const experiment::ExperimentPlan plan = experiment::plan_experiment(spec, options);
  progress->finish();
  print_plan_table(plan, spec);
  if (!a.json.empty()) {
    nlohmann::json doc = {{"spec", experiment::spec_identity_json(spec)}, {"plan", experiment::plan_json(plan, spec)}};
    write_file_atomically(a.json, doc.dump(2) + "\n");
  }
  return kExitOk;
}

CommandRegistration plan_registration{"plan", [](CLI::App& app) {
  auto args = std::make_shared<PlanArgs>();
  auto* sub = app.add_subcommand(
      "plan",
      "The plan of an experiment spec (TOML, or JSON; docs/reference/experiments.md): per measurement the cheapest sufficient "
      "model and its reason, the walk's order cap, the ray or path count from a short pilot's variance and the "
      "predicted time. Runs only the pilots. Exit 0 planned, 2 bad spec (key and line named), 130 interrupted.");
  sub->add_option("SPEC", args->spec, "the experiment spec (.toml, or .json)")->required();
  sub->add_option("--json", args->json, "also write the plan as JSON");
  add_number_option(sub, "--seed", args->seed, whole(), "seed of the pilots (0: the spec's)")->default_str("0");
  add_number_option(sub, "--threads", args->threads, integer(0, kMaxThreads),
                    at_most("worker threads (0: all cores)", kMaxThreads))
      ->default_str("0");
  on_selected(sub, [args] { return run_plan(*args); });
}};

}  // namespace
}  // namespace microsim::app
