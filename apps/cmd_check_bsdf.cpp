// microsim check-bsdf --plugin LIB.so: a renderer's BSDF, loaded in process through the C interface of
// include/microsim/bsdf_plugin.h (dlopen; ABI 1 or 2), run through the battery of measure/bsdf_battery.h against
// the BSDF it claims (--bsdf, --alpha; --reference: its exact single scattering, the Smith walk's multiple
// scattering, or none). Exit 0 every test passed, 1 one rejected, 2 bad usage or a plugin that cannot be loaded,
// 130 interrupted.
#include "bsdf_options.h"
#include "command.h"
#include "number_options.h"
#include "progress_bar.h"

#include "microsim/bsdf_plugin.h"
#include "core/atomic_file.h"
#include "microfacet/roughness.h"
#include "measure/bsdf_battery.h"
#include "measure/bsdf_battery_html.h"

#include <dlfcn.h>
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

// The loaded library and one BSDF it created; both released in reverse order.
class LoadedPlugin {
public:
  LoadedPlugin(const std::string& path, const std::string& params) {
    library_ = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!library_) throw UsageError(fmt::format("--plugin '{}': {}", path, dlerror()));
    const auto entry = reinterpret_cast<microsim_bsdf_plugin_entry_fn>(dlsym(library_, "microsim_bsdf_plugin_entry"));
    if (!entry) throw UsageError(fmt::format("--plugin '{}': no microsim_bsdf_plugin_entry", path));
    api_ = entry();
    if (!api_ || api_->abi_version < 1 || api_->abi_version > MICROSIM_BSDF_PLUGIN_ABI)
      throw UsageError(fmt::format("--plugin '{}': not of ABI version 1 to {}", path, MICROSIM_BSDF_PLUGIN_ABI));
    if (api_->channels < 1 || api_->channels > MICROSIM_BSDF_MAX_CHANNELS)
      throw UsageError(fmt::format("--plugin '{}': {} channels", path, api_->channels));
    if (!api_->create || !api_->destroy || !api_->sample || !api_->eval || (!api_->pdf && api_->abi_version < 2))
      throw UsageError(fmt::format("--plugin '{}': a function pointer is NULL", path));
    self_ = api_->create(params.c_str());
    if (!self_) throw UsageError(fmt::format("--plugin '{}': create(\"{}\") refused the parameters", path, params));
  }
  ~LoadedPlugin() {
    if (self_) api_->destroy(self_);
    if (library_) dlclose(library_);
  }
  LoadedPlugin(const LoadedPlugin&) = delete;
  LoadedPlugin& operator=(const LoadedPlugin&) = delete;
  const microsim_bsdf_plugin& api() const { return *api_; }
  // The flags of ABI 2; a version-1 plugin's struct ends before them.
  int flags() const { return api_->abi_version >= 2 ? api_->flags : 0; }
  void* self() const { return self_; }

private:
  void* library_ = nullptr;
  const microsim_bsdf_plugin* api_ = nullptr;
  void* self_ = nullptr;
};

// The plugin as a BSDF under test: each row one call.
BsdfUnderTest under_test(const LoadedPlugin& p) {
  BsdfUnderTest b;
  b.name = p.api().name ? p.api().name : "plugin";
  b.channels = p.api().channels;
  b.convention = {p.api().transport == 1 ? TransportMode::importance : TransportMode::radiance,
                  p.api().masking == 1 ? MaskingForm::separable : MaskingForm::height_correlated};
  b.stochastic_eval = (p.flags() & MICROSIM_BSDF_STOCHASTIC_EVAL) != 0;
  const auto raw = [](const Vec3<double>& v, double out[3]) { out[0] = v.x(), out[1] = v.y(), out[2] = v.z(); };
  const std::size_t c = std::size_t(b.channels);
  b.sample = [&p, raw, c](std::span<const Vec3<double>> wi, std::span<const double> u, std::span<Vec3<double>> wo,
                          std::span<double> pdf, std::span<double> weight, std::span<unsigned char> kept) {
    for (std::size_t i = 0; i < wi.size(); ++i) {
      double in[3], out[3] = {0, 0, 0};
      raw(wi[i], in);
      kept[i] = (unsigned char)(p.api().sample(p.self(), in, &u[3 * i], out, &pdf[i], &weight[c * i]) != 0);
      wo[i] = Vec3<double>(out[0], out[1], out[2]);
    }
  };
  b.eval = [&p, raw, c](std::span<const Vec3<double>> wi, std::span<const Vec3<double>> wo, std::span<double> value) {
    for (std::size_t i = 0; i < wi.size(); ++i) {
      double in[3], out[3];
      raw(wi[i], in), raw(wo[i], out);
      p.api().eval(p.self(), in, out, &value[c * i]);
    }
  };
  if (!p.api().pdf) return b;  // no closed-form density
  b.pdf = [&p, raw](std::span<const Vec3<double>> wi, std::span<const Vec3<double>> wo, std::span<double> pdf) {
    for (std::size_t i = 0; i < wi.size(); ++i) {
      double in[3], out[3];
      raw(wi[i], in), raw(wo[i], out);
      pdf[i] = p.api().pdf(p.self(), in, out);
    }
  };
  return b;
}

std::string plugin_name(const LoadedPlugin& p) { return p.api().name ? p.api().name : "plugin"; }

void print_table(const BatteryReport& r) {
  fmt::print("{:<12} {:<13} {:>9} {:<9} {}\n", "test", "view", "p", "verdict", "detail");
  for (const BatteryLine& l : r.lines)
    fmt::print("{:<12} {:<13} {:>9} {:<9} {}\n", l.test, l.view, l.p < 0 ? "-" : fmt::format("{:.3g}", l.p),
               l.passed ? "pass" : "REJECTED", l.detail);
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
void check_claims(const LoadedPlugin& plugin, const BatteryOptions& o, const std::string& bsdf, int channels) {
  if (plugin.api().channels != channels)
    throw UsageError(fmt::format("--plugin has {} channel(s), --bsdf {} has {}", plugin.api().channels, bsdf, channels));
  const bool stochastic = (plugin.flags() & MICROSIM_BSDF_STOCHASTIC_EVAL) != 0;
  if (o.reference == BatteryReference::single_scattering && (stochastic || !plugin.api().pdf))
    throw UsageError("--reference single-scattering needs a deterministic eval() and a pdf(): the plugin declares a "
                     "stochastic eval or has no pdf (--reference smith-walk or none)");
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
  const LoadedPlugin plugin(a.plugin, params);
  BatteryOptions o;
  o.samples = std::uint64_t(a.samples);
  o.seed = a.seed;
  o.level = a.level;
  o.arithmetic = arithmetic;
  o.reference = reference;
  o.views = views;
  check_claims(plugin, o, a.bsdf, m.channels());
  install_interrupt_handler();
  o.run = cli_run_control(0, nullptr);
  BatteryReport r;
  try {
    r = run_bsdf_battery(under_test(plugin), m, ggx, o);
  } catch (const Cancelled&) {
    return interrupted_nothing_written("check-bsdf");
  }
  if (!a.json.empty()) {
    nlohmann::json j = to_json(r);
    j.update({{"plugin", a.plugin}, {"bsdf", a.bsdf}, {"alpha", a.alpha}, {"level", a.level}});
    write_file_atomically(a.json, j.dump(2) + "\n");
  }
  if (!a.html.empty())
    write_file_atomically(a.html, battery_html(r, "microsim check-bsdf: " + plugin_name(plugin),
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
      "theta 0, 30, 60, 80, 89.9 deg (120, 150 from inside a dielectric), and for an anisotropic --alpha theta 60, 80 "
      "(120) at phi 30 and 60 too. Exit 0 passed, 1 rejected, 2 bad usage or a plugin that cannot be loaded.");
  sub->add_option("--plugin", a->plugin, "the shared library (.so) defining microsim_bsdf_plugin_entry")->required();
  sub->add_option("--param", a->params, "a key=value parameter passed to the plugin's create() (repeatable)");
  sub->add_option("--bsdf", a->bsdf, "the BSDF it claims: mirror, conductor:ETA,K or dielectric:ETA")->required();
  sub->add_option("--alpha", a->alpha, "its GGX roughness AX or AX,AY")->required();
  add_number_option(sub, "--samples", a->samples, whole(1000, 100'000'000), "samples per view")->default_str("200000");
  add_number_option(sub, "--seed", a->seed, whole(), "seed of the uniforms")->default_str("1");
  add_number_option(sub, "--level", a->level, real(), "family-wise significance level (Sidak over the views)")->default_str("0.01");
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
