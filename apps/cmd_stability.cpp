// microsim stability: the numerical-stability sweep of the sampler zoo and the analytic functions at the
// extremes (alpha, anisotropy, grazing and below-horizon views, u at the ends of [0, 1), non-finite
// input). Prints a markdown table on stdout (docs/stability.md quotes it); exit 0 when every row is
// within its bound, 1 when some row exceeds it, 2 on bad usage.
#include "command.h"
#include "number_options.h"

#include "core/atomic_file.h"
#include "progress_bar.h"
#include "validate/stability.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <chrono>

namespace {

namespace ma = microsim::app;

struct Options {
  std::string json_path;
  int random_u = -1;
  std::uint64_t seed = 0;
  bool seed_given = false;
  bool failures_only = false;
};

// The sweep's grid: the standard one with --random-u and --seed applied.
microsim::StabilityGrid stability_grid(const Options& o) {
  microsim::StabilityGrid grid = microsim::StabilityGrid::standard();
  if (o.random_u >= 0) grid.random_u_per_view = o.random_u;
  if (o.seed_given) grid.seed = o.seed;
  return grid;
}

// Prints the table (only the rows over their bound with --failures-only) and the verdict line.
void print_table(const microsim::StabilityTable& table, bool failures_only) {
  microsim::StabilityTable shown = table;
  if (failures_only) std::erase_if(shown.rows, [](const auto& r) { return microsim::stability_violations(r).empty(); });
  fmt::print("{}", microsim::stability_table_markdown(shown));
  const std::size_t violations = table.violation_count();
  fmt::print("\n{} rows, {} evaluations; {} rows exceed their bound: {}\n", table.rows.size(),
             table.total_evaluations(), violations, violations == 0 ? "PASS" : "FAIL");
}

int run_stability(const Options& o) {
  ma::check_distinct_outputs({}, {{"--json", o.json_path}});  // one output, no input: future-proof
  ma::check_output("--json", o.json_path);
  const microsim::StabilityGrid grid = stability_grid(o);
  fmt::print(stderr, "stability: sweeping {} alpha pairs x {} thetas x {} phis x ({} + {}) u ...\n", grid.alphas.size(),
             grid.thetas_deg.size(), grid.phis_deg.size(), grid.u_values.size() * grid.u_values.size(),
             grid.random_u_per_view);
  microsim::install_interrupt_handler();  // the sweep (seconds) has no check: Ctrl-C takes effect after it
  const auto start = std::chrono::steady_clock::now();
  const microsim::StabilityTable table = microsim::run_stability_sweep(grid);
  if (microsim::interrupted()) return ma::interrupted_nothing_written("stability", "", "no table");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  fmt::print(stderr, "stability: {} evaluations in {:.1f} s\n", table.total_evaluations(), seconds);
  print_table(table, o.failures_only);
  if (!o.json_path.empty())
    microsim::write_file_atomically(o.json_path, microsim::stability_table_json(table).dump(2) + "\n");
  return table.violation_count() == 0 ? ma::kExitOk : ma::kExitRejected;
}

ma::CommandRegistration reg{"stability", [](CLI::App& app) {
  auto opts = std::make_shared<Options>();
  auto* sub = app.add_subcommand(
      "stability",
      "Numerical stability at the extremes: every sampler (float and double) and every analytic Smith-GGX "
      "function over alpha 1e-4..10, anisotropy 1:1000, theta 0..180 deg (exactly 90 and below the horizon), "
      "u at the ends of [0,1) and non-finite input. Prints the worst-case table (markdown) on stdout; exit 0 "
      "when every row is within its stated bound (docs/stability.md), 1 otherwise.");
  sub->add_option("--json", opts->json_path, "also write the table (with worst configurations and bounds) as JSON");
  ma::add_number_option(sub, "--random-u", opts->random_u, ma::integer(0, 1000000),
                        "random u per view in addition to the 16 corner pairs, 0..1000000 (default 48)");
  auto* seed = ma::add_number_option(sub, "--seed", opts->seed, ma::whole(), "seed of the random u (default 20240611)");
  sub->add_flag("--failures-only", opts->failures_only, "print only the rows that exceed their bound");
  ma::on_selected(sub, [opts, seed] {
    opts->seed_given = seed->count() > 0;
    return run_stability(*opts);
  });
}};

}  // namespace
