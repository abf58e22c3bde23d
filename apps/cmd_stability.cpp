// microsim stability: the numerical-stability sweep of the sampler zoo and the analytic functions at the
// extremes (alpha, anisotropy, grazing and below-horizon views, u at the ends of [0, 1), non-finite
// input). Prints a markdown table on stdout (docs/stability.md quotes it); exit 0 when every row is
// within its bound, 1 when some row exceeds it, 2 on bad usage.
#include "command.h"
#include "number_options.h"

#include "stats/histogram_io.h"
#include "progress_bar.h"
#include "validate/stability.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <filesystem>

namespace {

struct Options {
  std::string json_path;
  int random_u = -1;
  std::uint64_t seed = 0;
  bool seed_given = false;
  bool failures_only = false;
};

microsim::app::CommandRegistration reg{"stability", [](CLI::App& app) {
  auto opts = std::make_shared<Options>();
  auto* sub = app.add_subcommand(
      "stability",
      "Numerical stability at the extremes: every sampler (float and double) and every analytic Smith-GGX "
      "function over alpha 1e-4..10, anisotropy 1:1000, theta 0..180 deg (exactly 90 and below the horizon), "
      "u at the ends of [0,1) and non-finite input. Prints the worst-case table (markdown) on stdout; exit 0 "
      "when every row is within its stated bound (docs/stability.md), 1 otherwise.");
  sub->add_option("--json", opts->json_path, "also write the table (with worst configurations and bounds) as JSON");
  microsim::app::add_number_option(sub, "--random-u", opts->random_u, microsim::app::integer(0, 1000000),
                                   "random u per view in addition to the 16 corner pairs, 0..1000000 (default 48)");
  auto* seed = microsim::app::add_number_option(sub, "--seed", opts->seed, microsim::app::whole(),
                                                "seed of the random u (default 20240611)");
  sub->add_flag("--failures-only", opts->failures_only, "print only the rows that exceed their bound");
  microsim::app::on_selected(sub, [opts, seed] {
    microsim::app::check_distinct_outputs({}, {{"--json", opts->json_path}});  // one output, no input: future-proof
    if (!opts->json_path.empty()) {
      const std::filesystem::path parent = std::filesystem::absolute(opts->json_path).parent_path();
      if (!std::filesystem::is_directory(parent))
        throw microsim::app::UsageError(
            fmt::format("--json '{}': directory '{}' does not exist", opts->json_path, parent.string()));
    }
    microsim::StabilityGrid grid = microsim::StabilityGrid::standard();
    if (opts->random_u >= 0) grid.random_u_per_view = opts->random_u;
    if (seed->count() > 0) grid.seed = opts->seed;
    fmt::print(stderr, "stability: sweeping {} alpha pairs x {} thetas x {} phis x ({} + {}) u ...\n",
               grid.alphas.size(), grid.thetas_deg.size(), grid.phis_deg.size(),
               grid.u_values.size() * grid.u_values.size(), grid.random_u_per_view);
    microsim::install_interrupt_handler();  // the sweep (seconds) has no check: Ctrl-C takes effect after it
    const auto start = std::chrono::steady_clock::now();
    const microsim::StabilityTable table = microsim::run_stability_sweep(grid);
    if (microsim::interrupted()) {
      fmt::print(stderr, "stability: interrupted: no table, nothing written\n");
      return microsim::app::kExitInterrupted;
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    fmt::print(stderr, "stability: {} evaluations in {:.1f} s\n", table.total_evaluations(), seconds);

    microsim::StabilityTable shown = table;
    if (opts->failures_only)
      std::erase_if(shown.rows, [](const auto& r) { return microsim::stability_violations(r).empty(); });
    fmt::print("{}", microsim::stability_table_markdown(shown));
    const std::size_t violations = table.violation_count();
    fmt::print("\n{} rows, {} evaluations; {} rows exceed their bound: {}\n", table.rows.size(),
               table.total_evaluations(), violations, violations == 0 ? "PASS" : "FAIL");
    if (!opts->json_path.empty()) microsim::write_text_atomically(opts->json_path, microsim::stability_table_json(table).dump(2) + "\n");
    return violations == 0 ? microsim::app::kExitOk : microsim::app::kExitRejected;
  });
}};

}  // namespace
