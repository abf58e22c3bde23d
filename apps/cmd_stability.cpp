// microsim stability: the numerical-stability sweep of the sampler zoo and the analytic functions at the
// extremes (alpha, anisotropy, grazing and below-horizon views, u at the ends of [0, 1), non-finite
// input). Prints a markdown table on stdout (docs/records/stability.md quotes it); exit 0 when every row is
// within its bound, 1 when some row exceeds it, 2 on bad usage, 130 interrupted (nothing written). With
// --shard K/N only blocks K of N of the sweep (its views, then the non-finite inputs) are swept and --json
// holds the part that `microsim merge` joins with the others into the whole sweep.
#include "command.h"
#include "number_options.h"

#include "core/atomic_file.h"
#include "core/parse.h"
#include "progress_bar.h"
#include "stability_report.h"
#include "validate/stability.h"
#include "validate/stability_part.h"

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
  std::string shard;  // "K/N": blocks K of N of the sweep, written as a part
};

// The sweep's grid: the standard one with --random-u and --seed applied.
microsim::StabilityGrid stability_grid(const Options& o) {
  microsim::StabilityGrid grid = microsim::StabilityGrid::standard();
  if (o.random_u >= 0) grid.random_u_per_view = o.random_u;
  if (o.seed_given) grid.seed = o.seed;
  return grid;
}

// --shard K/N: the sweep's blocks K of N, written to --json as a part for `microsim merge`.
microsim::StabilityRun stability_run(const Options& o, const microsim::StabilityGrid& grid) {
  microsim::StabilityRun run;
  run.run = microsim::cli_run_control(0, nullptr);
  if (o.shard.empty()) return run;
  if (o.json_path.empty())
    throw ma::UsageError(fmt::format("--shard {}: needs --json PART.json (the partial result for `microsim merge`)", o.shard));
  if (o.failures_only) throw ma::UsageError(fmt::format("--shard {} with --failures-only: a shard prints no table", o.shard));
  const std::uint64_t blocks = microsim::stability_blocks(grid);
  const microsim::ShardSpec s = microsim::parse_shard("--shard", o.shard, blocks);  // ParseError: exit 2
  run.blocks = microsim::shard_range(blocks, s.index, s.count);
  return run;
}

int run_stability(const Options& o) {
  ma::check_distinct_outputs({}, {{"--json", o.json_path}});  // one output, no input: future-proof
  ma::check_output("--json", o.json_path);
  const microsim::StabilityGrid grid = stability_grid(o);
  const microsim::StabilityRun run = stability_run(o, grid);
  fmt::print(stderr, "stability: sweeping {} alpha pairs x {} thetas x {} phis x ({} + {}) u{} ...\n", grid.alphas.size(),
             grid.thetas_deg.size(), grid.phis_deg.size(), grid.u_values.size() * grid.u_values.size(),
             grid.random_u_per_view, o.shard.empty() ? "" : ", shard " + o.shard);
  microsim::install_interrupt_handler();
  const auto start = std::chrono::steady_clock::now();
  const microsim::StabilityTable table =
      microsim::run_stability_sweep(grid, microsim::sampler_registry(), /*include_functions=*/true, run);
  if (table.partial) return ma::interrupted_nothing_written("stability", "", "no table");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  fmt::print(stderr, "stability: {} evaluations in {:.1f} s\n", table.total_evaluations(), seconds);
  if (o.shard.empty()) return ma::report_stability(table, o.failures_only, o.json_path);
  microsim::write_file_atomically(o.json_path, microsim::stability_part_json(table).dump() + "\n");
  fmt::print(stderr, "stability: shard {}: blocks {} of {}, written to '{}'; join the parts with `microsim merge "
             "PART.json... --json RESULT.json`\n", o.shard, table.blocks.to_string(), table.total_blocks, o.json_path);
  return ma::kExitOk;
}

ma::CommandRegistration stability_registration{"stability", [](CLI::App& app) {
  auto opts = std::make_shared<Options>();
  auto* sub = app.add_subcommand(
      "stability",
      "Numerical stability at the extremes: every sampler (float and double) and every analytic Smith-GGX "
      "function over alpha 1e-4..10, anisotropy 1:1000, theta 0..180 deg (exactly 90 and below the horizon), "
      "u at the ends of [0,1) and non-finite input. Prints the worst-case table (markdown) on stdout; exit 0 "
      "when every row is within its stated bound (docs/reference/stability.md), 1 otherwise (--shard: 0 when the part is "
      "written).");
  sub->add_option("--json", opts->json_path, "also write the table (with worst configurations and bounds) as JSON");
  ma::add_number_option(sub, "--random-u", opts->random_u, ma::integer(0, 1000000),
                        "random u per view in addition to the 16 corner pairs, 0..1000000 (default 48)");
  auto* seed = ma::add_number_option(sub, "--seed", opts->seed, ma::whole(), "seed of the random u (default 20240611)");
  sub->add_flag("--failures-only", opts->failures_only, "print only the rows that exceed their bound");
  sub->add_option("--shard", opts->shard,
                  "sweep only shard K of N (K/N, 1-based) of the sweep's blocks and write the part to --json, for "
                  "`microsim merge`. The blocks are the grid's views (each with its 16 corner u and its random u "
                  "from CounterRng(seed, view)) and, last, the non-finite inputs. The sweep is mostly deterministic "
                  "(only the random u are Monte Carlo) and takes seconds; it is sharded whole, view by view, because "
                  "that is exact and the merge is then the single sweep bit for bit");
  ma::on_selected(sub, [opts, seed] {
    opts->seed_given = seed->count() > 0;
    return run_stability(*opts);
  });
}};

}  // namespace
