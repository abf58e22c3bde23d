// experiment: the bsdf kind (measurement.h): a renderer's BSDF, loaded in process from a plugin
// (include/microsim/bsdf_plugin.h, measure/bsdf_plugin_loader.h), run once through the whole battery of
// `microsim check-bsdf` (measure/bsdf_battery.h) against what it claims: its quantity's material (mirror,
// conductor, dielectric) and that material's one GGX alpha. One decision, no rounds: the battery's budget is the
// spec's samples per view; its verdict is the result (the run's verdict and exit code take it, as a rejected
// validation's). Not shared by ranks (the root loads the plugin). Cancelled: nothing kept, it runs again on
// resumption.
#include "experiment/measurement.h"
#include "experiment/report_html.h"

#include "core/wall_clock.h"
#include "measure/bsdf_battery.h"
#include "measure/bsdf_plugin_loader.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>

namespace microsim::experiment {

// ---- its spec keys ---------------------------------------------------------------------------------------------

namespace {

// create()'s parameters from the table `params` (key = "value"; a number or a boolean as written), by key (a TOML
// table has no order: the same in a JSON spec), space-separated as the plugin interface passes them.
std::string read_plugin_params(const SpecTable& t) {
  if (!t.has("params")) return "";
  if (!t.at("params").is_object()) t.fail("params", "must be a table of key = value");
  std::map<std::string, SpecJson> params;
  for (const auto& [key, value] : t.at("params").items()) params.emplace(key, value);
  std::string joined;
  for (const auto& [key, value] : params) {
    if (!(value.is_string() || value.is_number() || value.is_boolean()))
      t.fail("params", fmt::format("{}: a string, a number or a boolean", key));
    const std::string text = value.is_string() ? value.get<std::string>() : value.dump();
    if (key.find_first_of(" =") != std::string::npos || text.find(' ') != std::string::npos || text.empty())
      t.fail("params", fmt::format("{} = {}: a key without spaces or '=', a value without spaces", key, quote_excerpt(text)));
    joined += (joined.empty() ? "" : " ") + key + "=" + text;
  }
  return joined;
}

// The views, [theta, phi] in degrees (a number: phi 0); none: the battery's default grid. From inside (theta over
// 90) only for a dielectric.
nlohmann::json read_battery_views(const SpecTable& t, const SpecMaterial& m) {
  nlohmann::json views = nlohmann::json::array();
  if (!t.has("views")) return views;
  if (!t.at("views").is_array() || t.at("views").empty()) t.fail("views", "must be a list of thetas or [theta, phi] pairs");
  for (const SpecJson& v : t.at("views")) {
    const bool pair = v.is_array() && v.size() == 2;
    if (!pair && !v.is_number()) t.fail("views", "each view is a theta or a [theta, phi] pair (degrees)");
    const double theta = t.number_value(pair ? v[0] : v, "views"), phi = pair ? t.number_value(v[1], "views") : 0.0;
    if (!(theta >= 0 && theta <= 180) || theta == 90)
      t.fail("views", fmt::format("theta {}: in [0, 180] and not 90 deg", theta));
    if (theta > 90 && !m.facet.transmits()) t.fail("views", fmt::format("theta {}: from inside, only a dielectric", theta));
    views.push_back({theta, phi});
  }
  return views;
}

std::string read_choice(const SpecTable& t, const char* key, const std::string& fallback,
                        const std::vector<std::string>& allowed) {
  const std::string value = t.string(key, fallback);
  if (std::find(allowed.begin(), allowed.end(), value) == allowed.end())
    t.fail(key, fmt::format("{}: {}", quote_excerpt(value), fmt::join(allowed, ", ")));
  return value;
}

// Its claims are its material's (one alpha: the plugin is created once, with its params); its settings go into
// SpecQuantity::settings (and the spec's digest).
void read_bsdf_spec(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m, const std::filesystem::path& spec_dir) {
  if (q.surface.kind != SurfaceChoice::Kind::automatic)
    t.fail("surface", "a plugin's BSDF is tested against the BSDF it claims, not on a surface");
  if (m.ndf != NdfKind::ggx) t.fail("material", fmt::format("material {}: the battery's claims are GGX", quote_excerpt(m.name)));
  if (m.alphas.size() != 1)
    t.fail("material", fmt::format("material {} has {} alphas: a plugin is created once and claims one",
                                   quote_excerpt(m.name), m.alphas.size()));
  const std::filesystem::path plugin = spec_file_path(t.string("plugin"), spec_dir);
  if (!std::filesystem::is_regular_file(plugin)) t.fail("plugin", fmt::format("no plugin file {}", quote_excerpt(plugin.string())));
  q.significance = t.number("significance", 0.01);
  if (!(q.significance > 0 && q.significance < 0.5)) t.fail("significance", fmt::format("{} must be in (0, 0.5)", q.significance));
  q.settings = {{"plugin", plugin.string()},
                {"params", read_plugin_params(t)},
                {"views", read_battery_views(t, m)},
                {"samples", t.integer("samples", 200'000, 1000, 100'000'000)},
                {"significance", q.significance},
                {"reference", read_choice(t, "reference", "single-scattering", {"single-scattering", "smith-walk", "none"})},
                {"arithmetic", read_choice(t, "arithmetic", "float32", {"float32", "float64"})}};
}

}  // namespace

const KindSpec bsdf_spec{"plugin params views samples significance reference arithmetic", read_bsdf_spec, nullptr};

// ---- its model ---------------------------------------------------------------------------------------------------

namespace {
std::string bsdf_alpha_text(const std::pair<double, double>& a) {
  return a.first == a.second ? fmt::format("{}", a.first) : fmt::format("{},{}", a.first, a.second);
}
}  // namespace

static ModelChoice bsdf_model(const SpecQuantity& q, const SpecMaterial& m) {
  const std::string what = fmt::format("a renderer's BSDF (plugin {}) claiming {} at GGX alpha {}",
                                       std::filesystem::path(q.settings.at("plugin").get<std::string>()).filename().string(),
                                       m.facet.describe(), bsdf_alpha_text(m.alphas.front()));
  const std::string reference = q.settings.at("reference");
  if (reference == "smith-walk")
    return {Model::smith_walk, what + ": against the Smith random walk's multiple scattering (Heitz et al. 2016) and "
                                      "against itself, the battery run once"};
  if (reference == "none")
    return {Model::analytic, what + ": against itself only (its eval() and pdf() integrated over cells, the white "
                                    "furnace), the battery run once"};
  return {Model::analytic, what + ": against its exact single scattering (Walter et al. 2007 with Smith masking) and "
                                  "against itself, the battery run once"};
}

// ---- its measurement -------------------------------------------------------------------------------------------

namespace {

BatteryReference battery_reference(const nlohmann::json& settings) {
  const std::string r = settings.at("reference");
  return r == "smith-walk" ? BatteryReference::smith_walk : r == "none" ? BatteryReference::none
                                                                        : BatteryReference::single_scattering;
}

// The battery's options of a bsdf quantity at `samples` per view from `seed`.
BatteryOptions battery_options(const SpecQuantity& q, std::uint64_t samples, std::uint64_t seed, const RunControl& run) {
  BatteryOptions o;
  o.samples = samples;
  o.seed = seed;
  o.level = q.significance;
  o.arithmetic = q.settings.at("arithmetic") == "float64" ? Precision::float64 : Precision::float32;
  o.reference = battery_reference(q.settings);
  for (const nlohmann::json& v : q.settings.at("views")) o.views.push_back({v[0].get<double>(), v[1].get<double>()});
  o.run = run;
  return o;
}

// The quantity's plugin, loaded; one that cannot be loaded, or cannot be run against its claims, is bad input
// naming the spec's key.
std::unique_ptr<BsdfPlugin> load_quantity_plugin(const SpecQuantity& q, const SpecMaterial& m) {
  std::unique_ptr<BsdfPlugin> plugin;
  try {
    plugin = std::make_unique<BsdfPlugin>(q.settings.at("plugin").get<std::string>(), q.settings.at("params").get<std::string>());
  } catch (const PluginLoadError& e) {
    throw std::invalid_argument(fmt::format("{}.plugin: {}", q.key, e.what()));
  }
  if (plugin->channels() != m.facet.channels())
    throw std::invalid_argument(fmt::format("{}.plugin: {} channel(s), its material {} ({}) has {}", q.key, plugin->channels(),
                                            quote_excerpt(m.name), m.facet.describe(), m.facet.channels()));
  if (battery_reference(q.settings) == BatteryReference::single_scattering && (plugin->stochastic_eval() || !plugin->has_pdf()))
    throw std::invalid_argument(fmt::format("{}.reference: single-scattering needs a deterministic eval() and a pdf(): the "
                                            "plugin declares a stochastic eval or has no pdf (smith-walk or none)", q.key));
  return plugin;
}

class BsdfBatteryMeasurement final : public Measurement {
public:
  using Measurement::Measurement;
  std::string error_measure() const override {
    return "none: the battery runs once at its budget (samples per view), its verdict is the result";
  }
  double target() const override { return 0; }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    const std::unique_ptr<BsdfPlugin> plugin = load_quantity_plugin(quantity_, material());
    const std::uint64_t samples = std::uint64_t(std::ceil(double(quantity_.settings.at("samples").get<std::uint64_t>()) *
                                                          c.options.cost_factor));
    const BatteryOptions o = battery_options(quantity_, samples, c.round_seed(0), c.options.run);
    run_once(m, [&] {
      const auto clock = std::chrono::steady_clock::now();
      const BatteryReport r = run_bsdf_battery(plugin->under_test(), material().facet,
                                               GGX<double>(decision_.alpha.first, decision_.alpha.second), o);
      record(r, *plugin, o, seconds_since(clock), m);
    });
  }

private:
  // The battery's report as `check-bsdf --json` writes it, under "battery" (the registry's test member).
  void record(const BatteryReport& r, const BsdfPlugin& plugin, const BatteryOptions& o, double seconds,
              MeasurementResult& m) const {
    const std::size_t views = o.views.empty() ? battery_views(material().facet, GGX<double>(decision_.alpha.first,
                                                                                           decision_.alpha.second)).size()
                                              : o.views.size();
    nlohmann::json j = to_json(r);
    j.update({{"plugin", quantity_.settings.at("plugin")}, {"name", plugin.name()}, {"params", quantity_.settings.at("params")},
              {"bsdf", material().facet.describe()}, {"alpha", bsdf_alpha_text(decision_.alpha)}, {"level", o.level},
              {"samples", o.samples}, {"seed", o.seed}, {"reference", quantity_.settings.at("reference")}});
    m.values = {{"battery", std::move(j)}};
    m.units = m.rays = o.samples * views;
    m.rounds.push_back({m.units, m.units, 0, false, o.seed, 0, seconds, 0});
    m.achieved = 0;
    m.met = true;  // it ran at its budget: its verdict is the result
  }
};

}  // namespace

static std::unique_ptr<Measurement> make_bsdf_measurement(const ExperimentSpec& spec, const Decision& decision) {
  return std::make_unique<BsdfBatteryMeasurement>(spec, decision);
}

// ---- its plan ----------------------------------------------------------------------------------------------

// One decision: the plugin loaded (bad input before anything runs: it does not load, or not against its
// claims), no pilot (the battery's budget is the spec's).
static void plan_bsdf_quantity(const ExperimentSpec& spec, std::size_t index, const PlanOptions&, SurfaceCache&,
                               std::vector<Decision>& out) {
  const SpecQuantity& q = spec.quantities[index];
  const SpecMaterial& m = spec.material(q.material);
  const std::unique_ptr<BsdfPlugin> plugin = load_quantity_plugin(q, m);
  Decision d;
  d.quantity = index;
  d.alpha = m.alphas.front();
  d.label = fmt::format("{} bsdf {} plugin {}", q.key, m.name,
                        std::filesystem::path(q.settings.at("plugin").get<std::string>()).filename().string());
  d.model = choose_model(q, m);
  const std::size_t views = q.settings.at("views").empty()
                                ? battery_views(m.facet, GGX<double>(d.alpha.first, d.alpha.second)).size()
                                : q.settings.at("views").size();
  const std::uint64_t samples = q.settings.at("samples").get<std::uint64_t>();
  d.units = samples * views;
  d.unit = "samples";
  d.count_reason = fmt::format("the battery's budget: {} samples per view at {} view(s){}, its statistical tests "
                               "Sidak-combined at level {} (the plugin, {}, loaded against its claims)", samples, views,
                               q.settings.at("views").empty() ? " (its default grid)" : "", q.significance,
                               plugin->name());
  d.runnable = true;
  out.push_back(std::move(d));
}

// ---- its report section (report_html.h) -----------------------------------------------------------------------

static std::string bsdf_report(const nlohmann::json& values, std::size_t, const ReportHistograms&, const ReportScatters&,
                               const std::string&) {
  if (!values.contains("battery")) return "";
  using namespace html;
  const json& b = member(values, "battery");
  std::string body;
  for (const json& t : member(b, "tests"))
    body += row({esc(text_of(member(t, "test"))), esc(text_of(member(t, "view"))), text_of(member(t, "p")),
                 member(t, "passed").get<bool>() ? "pass" : "<span class=\"notmet\">rejected</span>",
                 esc(text_of(member(t, "detail")))});
  return fmt::format("<p>Plugin <b>{}</b> ({}) claiming {} at alpha {}, reference {}: {} samples per view, verdict "
                     "<b>{}</b> (level {}).</p>\n",
                     esc(text_of(member(b, "name"))), esc(text_of(member(b, "plugin"))), esc(text_of(member(b, "bsdf"))),
                     esc(text_of(member(b, "alpha"))), esc(text_of(member(b, "reference"))),
                     text_of(member(b, "samples")), esc(text_of(member(b, "verdict"))), text_of(member(b, "level"))) +
         table({"test", "view", "p", "verdict", "detail"}, body);
}

// ---- its entry in the registry (measurement_registry.cpp) -------------------------------------------------

extern const MeasurementKind bsdf_kind{"bsdf", &bsdf_spec, false, bsdf_model, plan_bsdf_quantity,
                                       make_bsdf_measurement, bsdf_report, nullptr, "battery"};

}  // namespace microsim::experiment
