// microsim check-bsdf --plugin LIB.so: a renderer's BSDF, loaded in process through the C interface of
// include/microsim/bsdf_plugin.h (measure/bsdf_plugin_loader.h: dlopen; ABI 1 or 2), run through the battery of
// measure/bsdf_battery.h against the BSDF it claims (--bsdf, --alpha; --reference: its exact single scattering,
// the Smith walk's multiple scattering, or none). Exit 0 every test passed, 1 one rejected, 2 bad usage or a
// plugin that cannot be loaded, 130 interrupted.
#include "bsdf_options.h"
#include "command.h"
#include "number_options.h"
#include "progress_bar.h"

#include "core/atomic_file.h"
#include "microfacet/roughness.h"
#include "measure/bsdf_battery.h"
#include "measure/bsdf_battery_html.h"
#include "measure/bsdf_plugin_loader.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <memory>
#include <string>
#include <vector>

namespace microsim::app {
namespace {

struct CheckArgs {
  std::string plugin, bsdf, alpha, json, html, arithmetic = "float32", reference = "single-scattering";
  std::vector<std::string> params, views;
  long long samples = 200'000;
  unsigned long long seed = 1;
  double level = 0.01;
};

// The plugin, a load failure as bad usage naming --plugin.
std::unique_ptr<BsdfPlugin> load_plugin(const std::string& path, const std::string& params) {
  try {
    return std::make_unique<BsdfPlugin>(path, params);
  } catch (const PluginLoadError& e) {
    throw UsageError(fmt::format("--plugin '{}': {}", e.path(), e.problem()));
  }
}

void print_table(const BatteryReport& r) {
  fmt::print("convention: {}\n", r.convention);
  fmt::print("{:<12} {:<13} {:>9} {:<9} {}\n", "test", "view", "p", "verdict", "detail");
  for (const BatteryLine& l : r.lines)
    fmt::print("{:<12} {:<13} {:>9} {:<9} {}\n", l.test, l.view, l.p < 0 ? "-" : fmt::format("{:.3g}", l.p),
               l.verdict_word(), l.detail);
  fmt::print("{}\n", r.passed ? "passed" : "REJECTED");
}

// --view THETA[,PHI] (degrees), repeatable; none: the default grid.
std::vector<BatteryView> view_options(const std::vector<std::string>& texts) {
  std::vector<BatteryView> views;
  for (const std::string& t : texts) {
    const std::vector<double> v = parse_double_list("--view", t, {}, 2);
    views.push_back({v[0], v.size() == 2 ? v[1] : 0.0});
  }
  return views;
}

// The plugin against what the BSDF claims; a combination the battery cannot run is a UsageError.
void check_claims(const BsdfPlugin& plugin, const BatteryOptions& o, const std::string& bsdf, const Material& m) {
  if (plugin.channels() != m.channels())
    throw UsageError(fmt::format("--plugin has {} channel(s), --bsdf {} has {}", plugin.channels(), bsdf, m.channels()));
  if (o.reference == BatteryReference::single_scattering && (plugin.stochastic_eval() || !plugin.has_pdf()))
    throw UsageError("--reference single-scattering needs a deterministic eval() and a pdf(): the plugin declares a "
                     "stochastic eval or has no pdf (--reference smith-walk or none)");
  if (const std::string why = battery_refusal(m, plugin.sampled_normals()); !why.empty())
    throw UsageError(fmt::format("--plugin declares MICROSIM_BSDF_NDF_SAMPLING, --bsdf {}: {}", bsdf, why));
}

BatteryReference reference_option(const std::string& text) {
  if (text == "single-scattering") return BatteryReference::single_scattering;
  if (text == "smith-walk") return BatteryReference::smith_walk;
  if (text == "none") return BatteryReference::none;
  throw UsageError(fmt::format("--reference '{}': single-scattering, smith-walk or none", text));
}

int run_check_bsdf(const CheckArgs& a) {
  check_distinct_outputs({{"--plugin", a.plugin}}, {{"--json", a.json}, {"--html", a.html}});
  check_output("--json", a.json);
  check_output("--html", a.html);
  const BatteryReference reference = reference_option(a.reference);
  const std::vector<BatteryView> views = view_options(a.views);
  const Precision arithmetic = arithmetic_option(a.arithmetic);
  const Material m = microfacet_bsdf_option(a.bsdf);
  const auto [ax, ay] = parse_alpha("--alpha", a.alpha);
  const GGX<double> ggx(ax, ay);
  std::string params;
  for (const std::string& p : a.params) params += (params.empty() ? "" : " ") + p;
  const std::unique_ptr<BsdfPlugin> loaded = load_plugin(a.plugin, params);
  const BsdfPlugin& plugin = *loaded;
  BatteryOptions o;
  o.samples = std::uint64_t(a.samples);
  o.seed = a.seed;
  o.level = a.level;
  o.arithmetic = arithmetic;
  o.reference = reference;
  o.views = views;
  check_claims(plugin, o, a.bsdf, m);
  install_interrupt_handler();
  o.run = cli_run_control(0, nullptr);
  BatteryReport r;
  try {
    r = run_bsdf_battery(plugin.under_test(), m, ggx, o);
  } catch (const Cancelled&) {
    return interrupted_nothing_written("check-bsdf");
  }
  if (!a.json.empty()) {
    nlohmann::json j = to_json(r);
    j.update({{"plugin", a.plugin}, {"bsdf", a.bsdf}, {"alpha", a.alpha}, {"level", a.level}});
    write_file_atomically(a.json, j.dump(2) + "\n");
  }
  if (!a.html.empty())
    write_file_atomically(a.html, battery_html(r, "microsim check-bsdf: " + plugin.name(),
                                               {"plugin: " + a.plugin + (params.empty() ? "" : " (" + params + ")"),
                                                "claims: " + a.bsdf + ", GGX alpha " + a.alpha + ", reference " + a.reference,
                                                fmt::format("{} samples per view, seed {}, level {} (Sidak over the "
                                                            "statistical tests)", a.samples, a.seed, a.level)}));
  print_table(r);
  return r.passed ? kExitOk : kExitRejected;
}

CommandRegistration check_bsdf_registration{"check-bsdf", [](CLI::App& app) {
  auto a = std::make_shared<CheckArgs>();
  auto* sub = app.add_subcommand(
      "check-bsdf",
      "Test a renderer's BSDF in process through the C plugin interface (include/microsim/bsdf_plugin.h) against the "
      "BSDF it claims (by default the exact single scattering): its samples per view (directions, returned pdfs, "
      "weights), its eval() and pdf() at the pairs of bsdf-queries, its weights against eval / pdf, non-finite "
      "values; and against itself per view: its directions against its pdf(), its weighted samples against the "
      "integral of its eval() per cell, the white furnace (mean weight against the integral of eval cos). The views: "
      "theta 0, 30, 60, 80, 89.9 deg (120, 150 from inside a dielectric; 89.9 left out for a plugin sampling its "
      "normals from D(m) cos), and for an anisotropic --alpha theta 60, 80 (120) at phi 30 and 60 too. Exit 0 "
      "passed, 1 rejected, 2 bad usage or a plugin that cannot be loaded.");
  sub->add_option("--plugin", a->plugin, "the shared library (.so) defining microsim_bsdf_plugin_entry")->required();
  sub->add_option("--param", a->params, "a key=value parameter passed to the plugin's create() (repeatable)");
  sub->add_option("--bsdf", a->bsdf, "the BSDF it claims: mirror, conductor:ETA,K or dielectric:ETA")->required();
  sub->add_option("--alpha", a->alpha, "its GGX roughness AX or AX,AY")->required();
  add_number_option(sub, "--samples", a->samples, whole(1000, 100'000'000), "samples per view")->default_str("200000");
  add_number_option(sub, "--seed", a->seed, whole(), "seed of the uniforms")->default_str("1");
  add_number_option(sub, "--level", a->level, level(), "family-wise significance level (Sidak over the views)")->default_str("0.01");
  sub->add_option("--arithmetic", a->arithmetic, "the plugin's arithmetic for the eval tolerances: float32 or float64")
      ->capture_default_str();
  sub->add_option("--reference", a->reference,
                  "what its samples and eval() are checked against besides themselves: single-scattering (the exact "
                  "BSDF of --bsdf), smith-walk (the Smith random walk's multiple scattering: its samples, and its "
                  "next-event eval at query pairs) or none (a compensated BSDF: only the tests against itself)")
      ->capture_default_str();
  sub->add_option("--view", a->views,
                  "a view THETA[,PHI] in degrees (over 90: from inside a dielectric), repeatable; replaces the default grid");
  sub->add_option("--json", a->json, "write the report as JSON");
  sub->add_option("--html", a->html, "write the report as HTML (the table and the residual maps, inline SVG)");
  on_selected(sub, [a] { return run_check_bsdf(*a); });
}};

}  // namespace
}  // namespace microsim::app
