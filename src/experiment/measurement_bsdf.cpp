// experiment: the bsdf kind (measurement.h): a renderer's BSDF, loaded in process from a plugin
// (include/microsim/bsdf_plugin.h, measure/bsdf_plugin_loader.h), run once through the whole battery of
// `microsim check-bsdf` (measure/bsdf_battery.h) against what it claims: its quantity's material (mirror,
// conductor, dielectric) and that material's one GGX alpha. Or the same BSDF given as files (the files form: a
// sample dump of one view and its eval file at the same rows, optionally the eval file at the view's cell points),
// checked against itself as `microsim check-bsdf-files` checks them (measure/bsdf_file_check.h). One decision, no
// rounds: the battery's budget is the spec's samples per view (the files': their rows); its verdict is the result
// (the run's verdict and exit code take it, as a rejected validation's). Not shared by ranks (the root loads the
// plugin, reads the files). Cancelled: nothing kept, it runs again on resumption.
#include "experiment/measurement.h"
#include "experiment/plan_kinds.h"
#include "experiment/report_html.h"

#include "core/wall_clock.h"
#include "measure/bsdf_battery.h"
#include "measure/bsdf_file_check.h"
#include "measure/bsdf_plugin_loader.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
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

// A view's theta (degrees) under `key`: in [0, 180] and not 90; from inside (over 90) only for a dielectric.
void check_view_theta(const SpecTable& t, const char* key, double theta, const SpecMaterial& m) {
  if (!(theta >= 0 && theta <= 180) || theta == 90) t.fail(key, fmt::format("theta {}: in [0, 180] and not 90 deg", theta));
  if (theta > 90 && !m.facet.transmits()) t.fail(key, fmt::format("theta {}: from inside, only a dielectric", theta));
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
    check_view_theta(t, "views", theta, m);
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

// The keys of each form (significance is both's): a plugin's, and the files' (check-bsdf-files' inputs).
const std::vector<std::string> kPluginKeys{"plugin", "params", "views", "samples", "reference", "arithmetic"};
const std::vector<std::string> kFileKeys{"dump", "eval", "cells", "columns", "eval_columns", "frame", "lost", "albedo",
                                         "theta", "phi"};

// A file named under `key` (relative to the spec's folder), which must exist.
std::string read_existing_file(const SpecTable& t, const char* key, const std::filesystem::path& spec_dir) {
  const std::filesystem::path path = spec_file_path(t.string(key), spec_dir);
  if (!std::filesystem::is_regular_file(path)) t.fail(key, fmt::format("no {} file {}", key, quote_excerpt(path.string())));
  return path.string();
}

// The files' columns as check-bsdf-files reads them: the dump's x, y, z, pdf and a weight per channel, the eval
// file's wi, wo, value (a channel each) and pdf.
void read_file_columns(const SpecTable& t, nlohmann::json& settings) {
  const std::string columns = t.string("columns", "x,y,z,pdf,weight"), eval = t.string("eval_columns", "wi,wo,value,pdf");
  std::string problem;
  try {
    problem = dump_columns_problem(SampleColumns::parse(columns));
  } catch (const std::invalid_argument& e) {
    problem = e.what();
  }
  if (!problem.empty()) t.fail("columns", fmt::format("{}: {}", quote_excerpt(columns), problem));
  try {
    problem = eval_columns_problem(EvalColumns::parse(eval));
  } catch (const std::invalid_argument& e) {
    problem = e.what();
  }
  if (!problem.empty()) t.fail("eval_columns", fmt::format("{}: {}", quote_excerpt(eval), problem));
  settings["columns"] = columns;
  settings["eval_columns"] = eval;
}

// The files form: a sample dump of one view (theta, phi) and its eval file at the same rows, the eval file at the
// view's cell points (cells, optional), their columns and frame, the samples the dump left out (lost) and the
// albedo the BSDF claims (optional), as check-bsdf-files takes them.
nlohmann::json read_bsdf_files(const SpecTable& t, const SpecMaterial& m, const std::filesystem::path& spec_dir) {
  nlohmann::json s{{"dump", read_existing_file(t, "dump", spec_dir)}, {"eval", read_existing_file(t, "eval", spec_dir)},
                   {"cells", t.has("cells") ? read_existing_file(t, "cells", spec_dir) : std::string()}};
  read_file_columns(t, s);
  s["frame"] = read_choice(t, "frame", "z-up", {"z-up", "y-up"});
  const double theta = t.number("theta"), phi = t.number("phi", 0.0);
  check_view_theta(t, "theta", theta, m);
  s["theta"] = theta;
  s["phi"] = phi;
  s["lost"] = t.integer("lost", 0, 0, std::numeric_limits<std::int64_t>::max());
  s["albedo"] = nullptr;
  if (t.has("albedo")) {
    const double albedo = t.number("albedo");
    if (!(albedo >= 0 && albedo <= 10)) t.fail("albedo", fmt::format("{} must be in [0, 10]", albedo));
    s["albedo"] = albedo;
  }
  return s;
}

// The plugin form: its file, create()'s params and the battery's options.
nlohmann::json read_bsdf_plugin(const SpecTable& t, const SpecMaterial& m, const std::filesystem::path& spec_dir) {
  const std::filesystem::path plugin = spec_file_path(t.string("plugin"), spec_dir);
  if (!std::filesystem::is_regular_file(plugin)) t.fail("plugin", fmt::format("no plugin file {}", quote_excerpt(plugin.string())));
  return {{"plugin", plugin.string()},
          {"params", read_plugin_params(t)},
          {"views", read_battery_views(t, m)},
          {"samples", t.integer("samples", 200'000, 1000, 100'000'000)},
          {"reference", read_choice(t, "reference", "single-scattering", {"single-scattering", "smith-walk", "none"})},
          {"arithmetic", read_choice(t, "arithmetic", "float32", {"float32", "float64"})}};
}

// A plugin or files (dump and eval), not both: each form's keys refused in the other.
bool read_files_form(const SpecTable& t) {
  const bool files = t.has("dump") || t.has("eval");
  if (files && t.has("plugin")) t.fail(t.has("dump") ? "dump" : "eval", "a plugin or files (dump and eval), not both");
  if (!files && !t.has("plugin")) t.fail("plugin", "missing (required): a plugin, or files (dump and eval)");
  for (const std::string& key : files ? kPluginKeys : kFileKeys)
    if (t.has(key))
      t.fail(key, files ? fmt::format("a plugin's key ({}), not of the files form (dump and eval)", fmt::join(kPluginKeys, ", "))
                        : fmt::format("a key of the files form ({}), not of a plugin's", fmt::join(kFileKeys, ", ")));
  return files;
}

// Its claims are its material's (one alpha: the plugin is created once, with its params; files are of one BSDF);
// its settings go into SpecQuantity::settings (and the spec's digest).
void read_bsdf_spec(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m, const std::filesystem::path& spec_dir) {
  if (q.surface.kind != SurfaceChoice::Kind::automatic)
    t.fail("surface", "a renderer's BSDF is tested against itself and the BSDF it claims, not on a surface");
  if (m.ndf != NdfKind::ggx) t.fail("material", fmt::format("material {}: the battery's claims are GGX", quote_excerpt(m.name)));
  if (m.alphas.size() != 1)
    t.fail("material", fmt::format("material {} has {} alphas: a renderer's BSDF under test claims one",
                                   quote_excerpt(m.name), m.alphas.size()));
  const bool files = read_files_form(t);
  q.significance = t.number("significance", 0.01);
  if (!(q.significance > 0 && q.significance < 0.5)) t.fail("significance", fmt::format("{} must be in (0, 0.5)", q.significance));
  q.settings = files ? read_bsdf_files(t, m, spec_dir) : read_bsdf_plugin(t, m, spec_dir);
  q.settings["significance"] = q.significance;
}

bool files_form(const SpecQuantity& q) { return q.settings.contains("dump"); }

}  // namespace

const KindSpec bsdf_spec{"plugin params views samples significance reference arithmetic dump eval cells columns "
                         "eval_columns frame lost albedo theta phi", read_bsdf_spec, nullptr};

// ---- its model ---------------------------------------------------------------------------------------------------

namespace {
std::string bsdf_alpha_text(const std::pair<double, double>& a) {
  return a.first == a.second ? fmt::format("{}", a.first) : fmt::format("{},{}", a.first, a.second);
}
}  // namespace

static ModelChoice bsdf_model(const SpecQuantity& q, const SpecMaterial& m) {
  if (files_form(q))
    return {Model::analytic,
            fmt::format("a renderer's BSDF as files ({}, {}) claiming {} at GGX alpha {}: against itself, as "
                        "check-bsdf-files checks them (each weight against eval / pdf, the white furnace{}), once",
                        std::filesystem::path(q.settings.at("dump").get<std::string>()).filename().string(),
                        std::filesystem::path(q.settings.at("eval").get<std::string>()).filename().string(),
                        m.facet.describe(), bsdf_alpha_text(m.alphas.front()),
                        q.settings.at("cells") == "" ? "" : "; the cells: the density and the integral of eval per cell")};
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
  if (const std::string why = battery_refusal(m.facet, plugin->sampled_normals()); !why.empty())
    throw std::invalid_argument(fmt::format("{}.plugin: declares MICROSIM_BSDF_NDF_SAMPLING: {}", q.key, why));
  return plugin;
}

// The files of a files-form quantity checked as check-bsdf-files checks them; a file whose rows do not match is bad
// input naming the spec's key of the file the message names (the dump's by default).
BatteryReport check_quantity_files(const SpecQuantity& q, const RunControl& run) {
  const nlohmann::json& s = q.settings;
  BsdfFileCheckOptions o;
  o.frame = s.at("frame") == "y-up" ? SampleFrame::y_up : SampleFrame::z_up;
  o.lost = s.at("lost").get<std::uint64_t>();
  o.level = q.significance;
  if (!s.at("albedo").is_null()) o.albedo = s.at("albedo").get<double>();
  o.cells = std::filesystem::path(s.at("cells").get<std::string>());
  o.run = run;
  try {
    return check_bsdf_files(std::filesystem::path(s.at("dump").get<std::string>()),
                            SampleColumns::parse(s.at("columns").get<std::string>()),
                            std::filesystem::path(s.at("eval").get<std::string>()),
                            EvalColumns::parse(s.at("eval_columns").get<std::string>()),
                            direction_from_degrees(s.at("theta").get<double>(), s.at("phi").get<double>()), o);
  } catch (const SampleFileError& e) {
    const std::string what = e.what();
    std::string key = "dump";
    for (const char* k : {"eval", "cells"})
      if (s.at(k) != "" && what.rfind(s.at(k).get<std::string>(), 0) == 0) key = k;
    throw std::invalid_argument(fmt::format("{}.{}: {}", q.key, key, what));
  }
}

// The rows of a files-form quantity's dump (read through: bad input naming `.dump` before anything runs).
std::uint64_t quantity_dump_rows(const SpecQuantity& q, const RunControl& run) {
  try {
    DirectionSampleReader reader(std::filesystem::path(q.settings.at("dump").get<std::string>()),
                                 SampleColumns::parse(q.settings.at("columns").get<std::string>()));
    return count_dump_rows(reader, run);
  } catch (const SampleFileError& e) {
    throw std::invalid_argument(fmt::format("{}.dump: {}", q.key, e.what()));
  }
}

// A files-form quantity: the files' battery once, its report as `check-bsdf-files --json` writes it (with the
// material's claims) under "battery".
class BsdfFilesMeasurement final : public Measurement {
public:
  using Measurement::Measurement;
  std::string error_measure() const override {
    return "none: the files are checked once, every row; their battery's verdict is the result";
  }
  double target() const override { return 0; }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    run_once(m, [&] {
      const auto clock = std::chrono::steady_clock::now();
      const BatteryReport r = check_quantity_files(quantity_, c.options.run);
      const nlohmann::json& s = quantity_.settings;
      nlohmann::json j = to_json(r);
      j.update({{"dump", s.at("dump")}, {"eval", s.at("eval")}, {"theta", s.at("theta")}, {"phi", s.at("phi")},
                {"level", quantity_.significance}});
      if (s.at("cells") != "") j["cells"] = s.at("cells");
      j.update({{"bsdf", material().facet.describe()}, {"alpha", bsdf_alpha_text(decision_.alpha)}});
      m.values = {{"battery", std::move(j)}};
      m.units = m.rays = decision_.units;
      m.rounds.push_back({m.units, m.units, 0, false, 0, 0, seconds_since(clock), 0});
      m.achieved = 0;
      m.met = true;  // every row checked: its verdict is the result
    });
  }
};

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
    const std::size_t views =
        o.views.empty() ? battery_views(material().facet, GGX<double>(decision_.alpha.first, decision_.alpha.second),
                                        plugin.sampled_normals()).size()
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
  if (files_form(spec.quantities.at(decision.quantity))) return std::make_unique<BsdfFilesMeasurement>(spec, decision);
  return std::make_unique<BsdfBatteryMeasurement>(spec, decision);
}

// ---- its plan ----------------------------------------------------------------------------------------------

namespace {

// The files form's decision: every row of the dump (read through: bad input before anything runs).
Decision plan_bsdf_files(const SpecQuantity& q, const SpecMaterial& m, std::size_t index, const PlanOptions& o) {
  const nlohmann::json& s = q.settings;
  const std::string dump = std::filesystem::path(s.at("dump").get<std::string>()).filename().string();
  Decision d;
  d.quantity = index;
  d.alpha = m.alphas.front();
  d.label = fmt::format("{} bsdf {} files {}", q.key, m.name, dump);
  d.model = choose_model(q, m);
  d.units = quantity_dump_rows(q, o.run);
  d.unit = "samples";
  const bool cells = s.at("cells") != "";
  const bool albedo = !s.at("albedo").is_null();
  d.count_reason = fmt::format("the dump's {} rows (read from {}) and the eval file's at the same rows, all checked as "
                               "check-bsdf-files checks them at theta {} phi {}: each weight against eval / pdf, the "
                               "furnace{}{}{}", d.units, dump, s.at("theta").get<double>(), s.at("phi").get<double>(),
                               albedo ? " against the claimed albedo" : " (reported: no albedo claimed)",
                               cells ? "; the cells: density, integral and furnace per cell" : "",
                               albedo || cells ? fmt::format(", the statistical tests Sidak-combined at level {}",
                                                             q.significance) : std::string());
  d.runnable = true;
  return d;
}

}  // namespace

// One decision: the plugin loaded (bad input before anything runs: it does not load, or not against its
// claims), no pilot (the battery's budget is the spec's); or the files' rows counted.
static void plan_bsdf_quantity(const ExperimentSpec& spec, std::size_t index, const PlanOptions& options,
                               SurfaceCache&, std::vector<Decision>& out) {
  const SpecQuantity& q = spec.quantities[index];
  const SpecMaterial& m = spec.material(q.material);
  if (files_form(q)) {
    out.push_back(plan_bsdf_files(q, m, index, options));
    return;
  }
  const std::unique_ptr<BsdfPlugin> plugin = load_quantity_plugin(q, m);
  Decision d;
  d.quantity = index;
  d.alpha = m.alphas.front();
  d.label = fmt::format("{} bsdf {} plugin {}", q.key, m.name,
                        std::filesystem::path(q.settings.at("plugin").get<std::string>()).filename().string());
  d.model = choose_model(q, m);
  const std::size_t views = q.settings.at("views").empty()
                                ? battery_views(m.facet, GGX<double>(d.alpha.first, d.alpha.second),
                                                plugin->sampled_normals()).size()
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
  std::string head;
  if (b.contains("dump"))
    head = fmt::format("<p>Files <b>{}</b> and <b>{}</b>{} of a BSDF claiming {} at alpha {}, view theta {} phi {}, "
                       "checked against themselves (check-bsdf-files): verdict <b>{}</b> (level {}).</p>\n",
                       esc(text_of(member(b, "dump"))), esc(text_of(member(b, "eval"))),
                       b.contains("cells") ? ", cells <b>" + esc(text_of(member(b, "cells"))) + "</b>" : "",
                       esc(text_of(member(b, "bsdf"))), esc(text_of(member(b, "alpha"))), text_of(member(b, "theta")),
                       text_of(member(b, "phi")), esc(text_of(member(b, "verdict"))), text_of(member(b, "level")));
  else
    head = fmt::format("<p>Plugin <b>{}</b> ({}) claiming {} at alpha {}, reference {}: {} samples per view, verdict "
                       "<b>{}</b> (level {}).</p>\n",
                       esc(text_of(member(b, "name"))), esc(text_of(member(b, "plugin"))), esc(text_of(member(b, "bsdf"))),
                       esc(text_of(member(b, "alpha"))), esc(text_of(member(b, "reference"))),
                       text_of(member(b, "samples")), esc(text_of(member(b, "verdict"))), text_of(member(b, "level")));
  for (const json& t : member(b, "tests"))
    body += row({esc(text_of(member(t, "test"))), esc(text_of(member(t, "view"))), text_of(member(t, "p")),
                 !member(t, "passed").get<bool>() ? "<span class=\"notmet\">rejected</span>"
                 : t.value("tested", true)        ? "pass"
                                                  : "reported",
                 esc(text_of(member(t, "detail")))});
  return head + table({"test", "view", "p", "verdict", "detail"}, body);
}

// ---- its entry in the registry (measurement_registry.cpp) -------------------------------------------------

extern const MeasurementKind bsdf_kind{"bsdf", &bsdf_spec, false, bsdf_model, plan_bsdf_quantity,
                                       make_bsdf_measurement, bsdf_report, nullptr, "battery"};

}  // namespace microsim::experiment
