// microsim compare-scattering A.exr B.exr [C.exr]: two or three scattering results side by side, order by
// order (stats/scatter_compare.h): explicit surfaces, the Smith random walk, the analytic single scattering
// (a file of `microsim scatter --model analytic`, or --analytic: computed for the configuration the first
// file's notes record). Per pair, channel and order (1, 2, 3, 4, 5+ and the total; an expectation has order 1
// only): the total-variation distance of the shapes with its noise floor, the albedo difference with its
// standard error and p-value, and the weighted chi-square homogeneity test of the shapes (Gagunashvili 2010,
// "Chi-square tests for comparing weighted histograms", NIM A 614, 287). The verdict holds every test at the
// family-wise level --level (Sidak). Too little data for a test is an error, never a pass.
//
// Two or three files of `microsim trace vndf` (traced direction histograms) are compared binning by binning
// instead (compare_traced.h): the visible normals of two assemblies of one NDF, say.
//
// Exit codes: 0 every test passed, 1 a test rejected, 2 bad usage or input, or too little data (nothing
// written), 130 interrupted during --analytic (nothing written).
#include "command.h"
#include "compare_traced.h"
#include "number_options.h"
#include "progress_bar.h"

#include "core/atomic_file.h"
#include "measure/compare_scattering.h"

#include <fmt/core.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace microsim::app {
namespace {

struct CompareArgs {
  std::vector<std::string> files;
  bool analytic = false;
  std::string json, svg, orders;  // empty: every order (scatter files)
  double level = 0.01;
  int threads = 0;
};

int run_compare(const CompareArgs& a) {
  std::vector<PathOption> files;
  for (const std::string& f : a.files) files.push_back({"input", f});
  check_distinct_outputs(files, {{"--json", a.json}, {"--svg", a.svg}});
  if (!a.svg.empty() && std::filesystem::path(a.svg).extension() != ".svg")
    throw UsageError(fmt::format("--svg '{}': must be an .svg file", a.svg));
  check_output("--json", a.json);
  check_output("--svg", a.svg);
  install_interrupt_handler();
  CompareScatteringResult r;
  try {
    r = compare_scattering_files({a.files, a.analytic, a.orders, a.level}, cli_run_control(a.threads, nullptr));
  } catch (const Cancelled&) {
    return interrupted_nothing_written("compare-scattering", "during --analytic");
  }
  if (!a.json.empty()) write_file_atomically(a.json, to_json(r).dump(2) + "\n");
  if (!a.svg.empty())
    write_file_atomically(a.svg, r.scatter ? scatter_comparison_figure(*r.scatter) : traced_comparison_figure(*r.traced));
  if (r.scatter) print_scatter_comparison(*r.scatter);
  else print_traced_comparison(*r.traced);
  return r.rejected() ? kExitRejected : kExitOk;
}

CommandRegistration compare_scattering_registration{"compare-scattering", [](CLI::App& app) {
  auto args = std::make_shared<CompareArgs>();
  auto* sub = app.add_subcommand(
      "compare-scattering",
      "Compare two or three scattering results (scatter EXR files: explicit surface, Smith walk, analytic single "
      "scattering) order by order: total-variation distance of the shapes, albedo difference with its error, and the "
      "weighted chi-square homogeneity test (Gagunashvili 2010). Two or three traced histograms of `microsim trace vndf` "
      "(two assemblies of one NDF, say) are compared binning by binning the same way (the fraction of rays that hit in "
      "place of the albedo). Exit 0 passed, 1 rejected, 2 bad input or too little data (nothing written).");
  sub->add_option("files", args->files,
                  "scatter EXR files (2 or 3; 1 or 2 with --analytic), or 2 or 3 traced histograms (trace vndf --out)")
      ->required();
  sub->add_flag("--analytic", args->analytic,
                "add the analytic single scattering of the first file's configuration (its notes: ndf, alpha, theta, "
                "phi, material)");
  sub->add_option("--orders", args->orders, "scatter files: orders to compare, a list of 1, 2, 3, 4, 5+, total")
      ->default_str("1,2,3,4,5+,total");
  add_number_option(sub, "--level", args->level, level(), "family-wise significance level of the verdict")->default_str("0.01");
  add_number_option(sub, "--threads", args->threads, integer(0, kMaxThreads),
                    at_most("threads of the --analytic cubature (0: all cores)", kMaxThreads))
      ->default_str("0");
  sub->add_option("--json", args->json, "write the comparison as JSON");
  sub->add_option("--svg", args->svg, "write the figure (per-order lobes side by side, shape residual maps)");
  on_selected(sub, [args] { return run_compare(*args); });
}};

}  // namespace
}  // namespace microsim::app
