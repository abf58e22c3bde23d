// experiment: the masking kind (measurement.h): Smith's closed forms (analytic: exact, once), or G1, G2 and the
// conditional G1 measured on an explicit surface (measure/masking_runs.h MaskingRuns) in rounds of successive
// block ranges of one run until the target standard error is met. The ranks and shards measure shards of a
// round's blocks for every light on the same surface (the run's seed), their exact sums (MaskingSums) added in
// order; a part cancelled part way drops the round, as in one process.
#include "experiment/masking_runs.h"
#include "experiment/masking_surface.h"
#include "experiment/measurement.h"
#include "stats/curve_figure.h"
#include "experiment/report_html.h"
#include "microgeom/assembly.h"

#include "core/wall_clock.h"

#include <fmt/core.h>

#include <chrono>

namespace microsim::experiment {
namespace {

// The closed forms, once (deterministic: resumed, computed again).
class AnalyticMasking final : public Measurement {
public:
  using Measurement::Measurement;
  std::string error_measure() const override { return "none: Smith's closed forms are exact"; }
  void run(const RoundContext&, MeasurementResult& m) const override {
    run_once(m, [&] {
      const auto clock = std::chrono::steady_clock::now();
      m.values = analytic_masking_json(quantity_, material(), decision_);
      m.achieved = 0;
      m.rounds.push_back({0, 0, 0, false, 0, 0, seconds_since(clock), 0});
      m.met = true;
    });
  }
};

class SurfaceMaskingMeasurement final : public Measurement {
public:
  using Measurement::Measurement;
  std::string error_measure() const override {
    return fmt::format("the largest standard error of the measured {}{}", to_string(quantity_.masking),
                       quantity_.masking.conditional ? " (every bin of <v, m> and of height)" : "");
  }
  bool split() const override { return true; }
  // Its rounds are block ranges of one run (of kMaskingRunSamples samples): the first, the planned samples'.
  RoundTask first_round(std::size_t index, std::uint64_t seed) const override {
    return {index, kMaskingRunSamples, round_seed(seed, index, 0),
            BlockRange{0, BlockPlan{first_units(decision_, 1), kSamplesPerBlock}.blocks()},
            masking_surface_seed(seed, decision_.realisation)};
  }
  // The surface of the run's seed from `surfaces` (a build cancelled: a cancelled part), then its shard of the
  // blocks for every light.
  std::string part(const RoundTask& task, const BlockRange& mine, const RunControl& run,
                   SurfaceCache& surfaces) const override {
    const microgeom::Heightfield* field = nullptr;
    try {
      field = &acquire_masking_surface(quantity_, material(), decision_.alpha, task.surface_seed, surfaces, run);
    } catch (const Cancelled&) {
      return masking_round_part(task, mine, std::nullopt);
    }
    const HeightfieldMasking h(quantity_, decision_, *field,
                               masking_surface_text(quantity_, material(), decision_.alpha, task.surface_seed), task.seed);
    return masking_round_part(task, mine, h.measure_round(mine, run));
  }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    const std::uint64_t surface_seed = masking_surface_seed(c.seed, decision_.realisation);
    std::optional<HeightfieldMasking> h;
    try {
      h.emplace(quantity_, decision_,
                acquire_masking_surface(quantity_, material(), decision_.alpha, surface_seed, c.surfaces, c.options.run),
                masking_surface_text(quantity_, material(), decision_.alpha, surface_seed), c.round_seed(0));
    } catch (const Cancelled&) {
      m.partial = true;
      return;
    }
    rounds(c, *h, [&](const BlockRange& blocks) {
      return split_masking_round(c.split(), c.index, *h, surface_seed, blocks, c.options.run);
    }, m);
  }

private:
  // Rounds of blocks until the target standard error is met (the completed rounds of an interrupted run are
  // restored from m.values first).
  void rounds(const RoundContext& c, HeightfieldMasking& h, const MaskingRound& round, MeasurementResult& m) const {
    if (!m.rounds.empty()) h.restore(m.values);
    m.partial = false;
    std::uint64_t n = m.rounds.empty() ? first_units(decision_, c.options.cost_factor)
                                       : next_round_units(m.units, m.achieved, m.target);
    for (int r = int(m.rounds.size()); r < c.options.max_rounds && n > 0; ++r) {
      const auto clock = std::chrono::steady_clock::now();
      const std::uint64_t before = h.samples();
      const std::uint64_t end = h.blocks_done() + BlockPlan{n, kSamplesPerBlock}.blocks();
      if (!h.add_blocks(end, c.options.run, round)) {
        m.partial = true;
        break;
      }
      m.achieved = h.worst_standard_error();
      m.rounds.push_back({h.samples() - before, n, end, false, h.seed(), 0, seconds_since(clock), m.achieved});
      m.units = h.samples();
      m.rays = h.rays();
      m.values = h.values_json();
      n = next_round_units(m.units, m.achieved, m.target);
    }
    m.met = !m.rounds.empty() && !m.partial && m.achieved <= m.target;
  }
};


// ---- its plan: one decision per alpha and view ---------------------------------------------------------------

enum : std::uint64_t { kMaskingPilotSeed = 32 };  // derived_seed purposes of plan_kinds.h are below 32

Decision masking_decision(const SpecQuantity& q, const SpecMaterial& m, std::size_t index,
                          std::pair<double, double> alpha, const Direction& v) {
  Decision d;
  d.quantity = index;
  d.alpha = alpha;
  d.view = v;
  const std::string a = alpha.first == alpha.second ? fmt::format("{}", alpha.first)
                                                    : fmt::format("{},{}", alpha.first, alpha.second);
  d.label = fmt::format("{} masking {} alpha {} theta {} phi {}", q.key, m.name, a, v.theta_deg, v.phi_deg);
  d.model = choose_model(q, m);
  d.runnable = true;
  return d;
}

// The count of a heightfield decision: a pilot of kMaskingPilotBlocks blocks of surface points on the
// built surface gives the largest standard error of the values asked for (~ 1/sqrt(n)); n in whole blocks.
void plan_heightfield_masking(const SpecQuantity& q, const microgeom::Heightfield& field, const std::string& text,
                              std::uint64_t pilot_seed, double build_seconds, const PlanOptions& o, Decision& d) {
  const auto start = std::chrono::steady_clock::now();
  HeightfieldMasking pilot(q, d, field, text, pilot_seed);
  if (!pilot.add_blocks(kMaskingPilotBlocks, o.run)) throw Cancelled("plan: masking pilot");
  d.pilot_error = pilot.worst_standard_error();
  d.pilot_seconds = seconds_since(start);
  d.pilot_units = pilot.samples();
  const std::uint64_t n = units_for_standard_error(d.pilot_units, d.pilot_error, q.target);
  d.units = BlockPlan{n, kSamplesPerBlock}.blocks() * kSamplesPerBlock;
  d.unit = "samples";
  d.count_reason = fmt::format("pilot of {} surface points: largest standard error of {} {:.2e} ~ 1/sqrt(n); "
                               "n = {} x ({:.2e} / {})^2, in whole blocks of {}",
                               d.pilot_units, to_string(q.masking), d.pilot_error, d.pilot_units, d.pilot_error,
                               q.target, kSamplesPerBlock);
  d.model.reason += "; surface: " + text +
                    " (the target is the Monte Carlo error on this one surface: the spread between realisations is not in it)";
  // The surface's build and the scene are paid once per measurement; the sampling scales with the points.
  const double setup = std::max(0.0, d.pilot_seconds - pilot.seconds());
  d.predicted_seconds = build_seconds + setup + predicted_seconds(d.units, d.pilot_units, pilot.seconds());
}


// The decisions of one alpha: per realisation of its surface (one without a surface), per view.
void plan_alpha(const ExperimentSpec& spec, std::size_t index, std::pair<double, double> alpha, const PlanOptions& o,
                SurfaceCache& surfaces, std::vector<Decision>& out) {
  const SpecQuantity& q = spec.quantities[index];
  const SpecMaterial& m = spec.material(q.material);
  const bool traced = choose_model(q, m).model == Model::heightfield;
  const std::uint64_t run_seed = o.seed != 0 ? o.seed : spec.seed;
  for (int k = 0; k < (traced ? q.realisations : 1); ++k) {
    const std::uint64_t seed = masking_surface_seed(run_seed, k);
    const microgeom::Heightfield* field = nullptr;  // from the cache once per realisation, for its views' pilots
    double build_seconds = 0;
    if (traced) {
      const auto start = std::chrono::steady_clock::now();
      field = &acquire_masking_surface(q, m, alpha, seed, surfaces, o.run);
      build_seconds = seconds_since(start);
    }
    for (const Direction& v : q.directions) {
      Decision d = masking_decision(q, m, index, alpha, v);
      d.realisation = k;
      if (q.realisations > 1 && traced) d.label += fmt::format(" realisation {}", k);
      if (field)
        plan_heightfield_masking(q, *field, masking_surface_text(q, m, alpha, seed),
                                 derived_seed(run_seed, kMaskingPilotSeed, out.size()), build_seconds, o, d);
      else
        d.count_reason = "deterministic: Smith's closed form, no samples";
      out.push_back(std::move(d));
    }
  }
}

}  // namespace

static void plan_masking_quantity(const ExperimentSpec& spec, std::size_t index, const PlanOptions& o, SurfaceCache& surfaces,
                  std::vector<Decision>& out) {
  for (const auto& alpha : spec.material(spec.quantities[index].material).alphas)
    plan_alpha(spec, index, alpha, o, surfaces, out);
}

static std::unique_ptr<Measurement> make_masking_measurement(const ExperimentSpec& spec, const Decision& decision) {
  if (decision.model.model == Model::analytic) return std::make_unique<AnalyticMasking>(spec, decision);
  return std::make_unique<SurfaceMaskingMeasurement>(spec, decision);
}

// ---- its view, and the means over realisations ----------------------------------------------------------------

MaskingView masking_view(const SpecQuantity& q, const Decision& d) {
  MaskingView v{d.view.theta_deg, d.view.phi_deg, {}, q.masking.g1, q.masking.g2, q.masking.conditional, q.bins};
  for (const Direction& l : q.lights) v.lights.emplace_back(l.theta_deg, l.phi_deg);
  return v;
}

nlohmann::json analytic_masking_json(const SpecQuantity& q, const SpecMaterial& m, const Decision& d) {
  return microsim::analytic_masking_json(masking_view(q, d), m.ndf, d.alpha);
}

namespace {

// The mean of one value over realisations ({"value", "standard_error"} each).
nlohmann::json realisation_mean(const std::vector<const nlohmann::json*>& values) {
  const double k = double(values.size());
  double sum = 0, mc = 0;
  for (const nlohmann::json* v : values) {
    sum += v->at("value").get<double>();
    mc += std::pow(v->at("standard_error").get<double>(), 2);
  }
  const double mean = sum / k;
  double spread = 0;
  for (const nlohmann::json* v : values) spread += std::pow(v->at("value").get<double>() - mean, 2);
  return {{"mean", mean}, {"standard_error", std::sqrt(spread / (k - 1) / k)}, {"monte_carlo_error", std::sqrt(mc) / k}};
}

// The same member of every realisation's masking values, by a path of keys and indices.
nlohmann::json mean_of(const std::vector<const nlohmann::json*>& maskings, const nlohmann::json::json_pointer& where) {
  std::vector<const nlohmann::json*> values;
  for (const nlohmann::json* mk : maskings) values.push_back(&mk->at(where));
  return realisation_mean(values);
}

nlohmann::json group_means(const std::string& label, const std::vector<const nlohmann::json*>& maskings) {
  using ptr = nlohmann::json::json_pointer;
  const nlohmann::json& first = *maskings.front();
  nlohmann::json out{{"label", label}, {"realisations", maskings.size()}, {"g1", mean_of(maskings, ptr("/g1"))}};
  if (first.contains("g2")) {
    out["g2"] = nlohmann::json::array();
    for (std::size_t l = 0; l < first["g2"].size(); ++l) {
      nlohmann::json g2 = mean_of(maskings, ptr(fmt::format("/g2/{}", l)));
      g2["light"] = first["g2"][l]["light"];
      out["g2"].push_back(g2);
    }
  }
  if (first.contains("conditional"))
    for (const char* binning : {"by_normal", "by_height"}) {
      out["conditional"][binning] = nlohmann::json::array();
      for (std::size_t b = 0; b < first["conditional"][binning].size(); ++b)
        out["conditional"][binning].push_back(mean_of(maskings, ptr(fmt::format("/conditional/{}/{}", binning, b))));
    }
  return out;
}

// Masking over several realisations (a quantity's `realisations` > 1): per quantity, alpha and view whose
// realisations ran whole (at least two; met or not, so that none is selected by its values), every measured
// value's mean over them with its standard error from their spread (sample standard deviation / sqrt(K): the
// realisations are independent surfaces, so it holds both the spread between surfaces and each one's Monte
// Carlo error) and the Monte Carlo part alone (the root mean square of their standard errors / sqrt(K)). An
// array of {"label", "realisations", "g1", "g2": [...], "conditional": {"by_normal": [...], "by_height": [...]}},
// each value {"mean", "standard_error", "monte_carlo_error"}; empty when no quantity has several.
nlohmann::json masking_realisation_means(const std::vector<MeasurementResult>& measurements) {
  std::map<std::string, std::vector<const nlohmann::json*>> groups;  // by label without " realisation k"
  std::vector<std::string> order;
  for (const MeasurementResult& m : measurements) {
    const Decision& d = m.decision;
    if (!m.ran || m.partial || d.model.model != Model::heightfield || !m.values.contains("masking")) continue;
    const std::string label = d.label.substr(0, d.label.rfind(" realisation "));
    if (label.size() == d.label.size()) continue;  // one realisation
    if (groups[label].empty()) order.push_back(label);
    groups[label].push_back(&m.values.at("masking"));
  }
  nlohmann::json out = nlohmann::json::array();
  for (const std::string& label : order)
    if (groups[label].size() >= 2) out.push_back(group_means(label, groups[label]));
  return out;
}

}  // namespace


// ---- its model --------------------------------------------------------------------------------------------------

// Masking: Smith's closed forms unless the quantity needs a surface (conditional masking: Smith assumes
// masking independent of the facet and of height, so only an explicit surface has it) or names one.
static ModelChoice masking_model(const SpecQuantity& q, const SpecMaterial& m) {
  const std::string ndf = to_string(m.ndf);
  if (q.surface.kind != SurfaceChoice::Kind::automatic)
    return {Model::heightfield,
            fmt::format("the spec names a surface ({} {}): its own masking is measured by tracing it (measure_masking), "
                        "in rounds to the target standard error, beside Smith's prediction with the analytic NDF "
                        "and with the surface's own NDF",
                        q.surface.kind == SurfaceChoice::Kind::assembly ? "assembly" : "heightmap", q.surface.name)};
  if (q.masking.conditional)
    return {Model::heightfield,
            fmt::format("conditional masking (G1 given <v, m> or height) is not in the Smith model, which assumes "
                        "masking independent of both: it needs an explicit surface; none is named, so the {} "
                        "assembly (built to {}) is built per alpha at {}^2 with a correlation length of N/64 cells "
                        "(4 to 16: 64 correlation lengths per tile, masking_surface.h), and traced in rounds to the "
                        "target standard error",
                        microgeom::plain_assembly(m.ndf), ndf, q.resolution)};
  return {Model::analytic,
          fmt::format("G1 and G2 of the Smith model have closed forms: G1 = 1 / (1 + Lambda(v)) (Heitz 2014, eq. 43), "
                      "height-correlated G2 = 1 / (1 + Lambda(v) + Lambda(l)) (eq. 99; separable G1 G1, eq. 98, "
                      "beside it) with the {} Lambda: exact, no noise, no surface to build",
                      ndf)};
}

// ---- its spec keys ---------------------------------------------------------------------------------------------

namespace {

// `what`: one name or a list of g1, g2, conditional (default g1), each at most once.
MaskingWhat masking_what(const SpecTable& t) {
  if (!t.has("what")) return {true, false, false};
  const SpecJson& v = t.at("what");
  if (v.is_array() && v.empty()) t.fail("what", "must not be empty");
  MaskingWhat w;
  for (const SpecJson& item : v.is_array() ? v : SpecJson::array({v})) {
    if (!item.is_string()) t.fail("what", "a list of g1, g2, conditional");
    const std::string name = item.get<std::string>();
    bool* flag = name == "g1" ? &w.g1 : name == "g2" ? &w.g2 : name == "conditional" ? &w.conditional : nullptr;
    if (flag == nullptr) t.fail("what", fmt::format("{} is not a masking quantity (g1, g2, conditional)", quote_excerpt(name)));
    if (*flag) t.fail("what", fmt::format("{} is listed twice", name));
    *flag = true;
  }
  return w;
}

// G2's lights: light_theta (required with g2, in [0, 90)) x light_phi (default [0]); refused without g2.
std::vector<Direction> masking_lights(const SpecTable& t, bool g2) {
  for (const char* key : {"light_theta", "light_phi"})
    if (!g2 && t.has(key)) t.fail(key, "lights apply to g2 (what = [\"g2\", ...])");
  if (!g2) return {};
  if (!t.has("light_theta")) t.fail("light_theta", "g2 needs its lights: light_theta = [...] (degrees; light_phi default [0])");
  std::vector<Direction> out;
  for (double theta : t.numbers("light_theta")) {
    if (!(theta >= 0 && theta < 90))
      t.fail("light_theta", fmt::format("theta {} deg is at or below the horizon or not an angle (a light takes [0, 90))", theta));
    for (double phi : t.has("light_phi") ? t.numbers("light_phi") : std::vector<double>{0.0}) out.push_back({theta, phi});
  }
  return out;
}

// The surface of a masking quantity: a built one (an assembly, or conditional masking on auto) takes a
// resolution; a heightmap is one surface (one alpha); an assembly is built to the material's NDF.
void check_masking_surface(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m) {
  const bool built = q.surface.kind == SurfaceChoice::Kind::assembly ||
                     (q.surface.kind == SurfaceChoice::Kind::automatic && q.masking.conditional);
  if (t.has("resolution") && !built)
    t.fail("resolution", q.surface.kind == SurfaceChoice::Kind::heightmap
                             ? "a heightmap has its own resolution"
                             : "the analytic Smith model has no surface (resolution applies to an assembly or to conditional masking)");
  q.resolution = int(t.integer("resolution", kDefaultMaskingResolution, kMinMaskingResolution, kMaxMaskingResolution));
  if ((q.resolution & (q.resolution - 1)) != 0) t.fail("resolution", fmt::format("{} must be a power of two", q.resolution));
  if (t.has("realisations") && !built)
    t.fail("realisations", q.surface.kind == SurfaceChoice::Kind::heightmap
                               ? "a heightmap is one realisation"
                               : "the analytic Smith model has no surface (realisations apply to an assembly or to conditional masking)");
  q.realisations = int(t.integer("realisations", 1, 1, kMaxMaskingRealisations));
  if (q.surface.kind == SurfaceChoice::Kind::heightmap && m.alphas.size() != 1)
    t.fail("surface", fmt::format("a heightmap is one surface: material {} must have one alpha (it has {})",
                                  quote_excerpt(m.name), m.alphas.size()));
  if (q.surface.kind != SurfaceChoice::Kind::assembly) return;
  if (microgeom::find_assembly(q.surface.name)->reference != m.ndf)
    t.fail("surface", fmt::format("assembly {} is built to {}, material {} is {}", q.surface.name,
                                  to_string(microgeom::find_assembly(q.surface.name)->reference),
                                  quote_excerpt(m.name), to_string(m.ndf)));
}

void read_masking(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m) {
  q.masking = masking_what(t);
  q.lights = masking_lights(t, q.masking.g2);
  if (t.has("bins") && !q.masking.conditional) t.fail("bins", "bins apply to conditional masking");
  q.bins = int(t.integer("bins", 10, 2, 100));
  check_masking_surface(t, q, m);
}

void read_masking_spec(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m, const std::filesystem::path&) {
  q.target = read_target(t, "target_standard_error", 0.5, "a standard error of a masking probability below 0.5");
  q.directions = read_directions(t, false);
  read_masking(t, q, m);
}

nlohmann::json masking_canonical(const SpecQuantity& q) {
  nlohmann::json lights = nlohmann::json::array();
  for (const Direction& l : q.lights) lights.push_back({l.theta_deg, l.phi_deg});
  nlohmann::json j{{"what", to_string(q.masking)}, {"lights", lights}, {"bins", q.bins}, {"resolution", q.resolution}};
  if (q.realisations > 1) j["realisations"] = q.realisations;  // one realisation: the digest of earlier versions
  return j;
}

}  // namespace

const KindSpec masking_spec{"what target_standard_error theta theta_range phi light_theta light_phi bins resolution "
                            "realisations", read_masking_spec, masking_canonical};

// ---- its report section (report_html.h) -----------------------------------------------------------------------

namespace html {
namespace {

// A member's text, or "-" when absent.
std::string optional_number(const json& j, const char* key) { return j.contains(key) ? report_number(j[key]) : "-"; }

std::string difference_text(const json& j, const char* key) {
  return j.contains(key) ? estimate_text(j[key]) : "-";
}

// One row of a masking table: the value +- its standard error beside Smith's predictions and the differences.
std::vector<std::string> masking_row(const std::string& name, const json& v) {
  return {esc(name), estimate_text(v), optional_number(v, "smith_analytic"), optional_number(v, "smith_own_ndf"),
          difference_text(v, "difference"), difference_text(v, "difference_own_ndf")};
}

const std::vector<std::string> kMaskingHeader{"quantity", "value", "Smith (analytic NDF)", "Smith (own NDF)",
                                              "value - Smith (analytic)", "value - Smith (own NDF)"};

std::string light_text(const json& l) {
  return fmt::format("l = (theta {}, phi {})", report_number(member(l, "theta_deg")), report_number(member(l, "phi_deg")));
}

// Measured values with error bars against Smith's predictions (analytic NDF, own NDF) along x.
std::string masking_curves_figure(const std::string& title, const std::string& subtitle, const CurveAxes& axes,
                                  const std::vector<double>& x, const std::vector<const json*>& points) {
  Curve measured{"measured", x, {}, {}}, analytic{"Smith, analytic NDF", x, {}, {}}, own{"Smith, own NDF", x, {}, {}};
  for (const json* p : points) {
    measured.y.push_back(member(*p, "value").get<double>());
    measured.error.push_back(member(*p, "standard_error").get<double>());
    analytic.y.push_back(p->value("smith_analytic", std::nan("")));
    own.y.push_back(p->value("smith_own_ndf", std::nan("")));
  }
  const bool traced = std::any_of(own.y.begin(), own.y.end(), [](double y) { return std::isfinite(y); });
  if (!traced) analytic.label = "Smith's closed form (exact)";  // the analytic model: nothing measured
  std::vector<Curve> curves{analytic};
  if (traced) curves = {measured, analytic, own};
  return "<figure>" + curve_figure_svg(title, subtitle, axes, curves) + "</figure>\n";
}

std::string masking_bins_section(const json& bins, const std::string& what, const std::string& label) {
  std::string body;
  std::vector<double> x;
  std::vector<const json*> points;
  for (std::size_t i = 0; i < bins.size(); ++i) {
    const json& b = bins[i];
    std::vector<std::string> cells = masking_row(fmt::format("bin {}: [{}, {}]", i, report_number(member(b, "lo")),
                                                             report_number(member(b, "hi"))), b);
    cells.insert(cells.begin() + 1, {report_number(member(b, "share")), text_of(member(b, "samples"))});
    body += row(cells);
    x.push_back(0.5 * (member(b, "lo").get<double>() + member(b, "hi").get<double>()));
    points.push_back(&b);
  }
  std::vector<std::string> header = kMaskingHeader;
  header[0] = "bin of " + what;
  header.insert(header.begin() + 1, {"share", "samples"});
  std::string out = fmt::format("<h4>G1(v | {})</h4>\n", esc(what)) + table(header, body);
  if (!points.empty())
    out += masking_curves_figure(label + ": G1(v | " + what + ")", "error bars: one standard error", {what, "G1(v | bin)"}, x, points);
  return out;
}

std::string masking_g2_figure(const json& g2, const std::string& label) {
  std::vector<double> x;
  std::vector<const json*> points;
  for (const json& g : g2) {
    x.push_back(member(member(g, "light"), "theta_deg").get<double>());
    points.push_back(&g);
  }
  if (points.size() < 2) return "";
  return masking_curves_figure(label + ": G2(v, l)", "against the light's theta (every light phi on one axis); error bars: one standard error",
                               {"theta_l (deg)", "G2(v, l)"}, x, points);
}

std::string masking_values(const json& values, const std::string& label) {
  const json& mk = member(values, "masking");
  const bool traced = text_of(member(mk, "model")) == "heightfield";
  std::string out = traced ? fmt::format("<p>Traced on {} (Smith's analytic NDF: {}): {} surface points, {} shadow rays; "
                                         "leak ratio {} (must be 1).</p>\n",
                                         esc(text_of(member(mk, "surface"))), esc(text_of(member(mk, "reference"))),
                                         text_of(member(mk, "samples")), text_of(member(mk, "rays")),
                                         estimate_text(member(mk, "leak_ratio")))
                           : fmt::format("<p>Smith's closed forms ({} NDF): Lambda(v) = {}; exact (standard error 0).</p>\n",
                                         esc(text_of(member(mk, "ndf"))), report_number(member(mk, "lambda")));
  std::string body;
  if (mk.contains("g1")) body += row(masking_row("G1(v)", mk["g1"]));
  if (mk.contains("g2"))
    for (const json& g : mk["g2"]) body += row(masking_row("G2(v, l), " + light_text(member(g, "light")), g));
  if (!body.empty()) out += table(kMaskingHeader, body);
  if (mk.contains("g2")) out += masking_g2_figure(mk["g2"], label);
  if (mk.contains("conditional")) {
    out += masking_bins_section(member(mk["conditional"], "by_normal"), "<v, m>", label);
    out += masking_bins_section(member(mk["conditional"], "by_height"), "height", label);
  }
  return out;
}

// G1(v) against theta_v per masking quantity, alpha and view phi (the masking curves against Smith), from
// the measurements that ran and measured G1; a curve needs two views.
std::string masking_curves_section_html(const json& document) {
  const json& decisions = member(member(document, "plan"), "decisions");
  const json& measurements = member(member(document, "results"), "measurements");
  std::map<std::string, std::pair<std::vector<double>, std::vector<const json*>>> curves;
  for (std::size_t i = 0; i < measurements.size() && i < decisions.size(); ++i) {
    const json& d = decisions[i];
    const json& values = member(measurements[i], "values");
    if (text_of(member(d, "kind")) != "masking" || !values.is_object() || !values.contains("masking") ||
        !values["masking"].contains("g1"))
      continue;
    const std::string key = fmt::format("{} alpha ({}, {}), phi_v {}", text_of(member(d, "quantity")),
                                        report_number(member(d, "alpha")[0]), report_number(member(d, "alpha")[1]),
                                        report_number(member(member(d, "view"), "phi_deg")));
    curves[key].first.push_back(member(member(d, "view"), "theta_deg").get<double>());
    curves[key].second.push_back(&values["masking"]["g1"]);
  }
  std::string out;
  for (const auto& [key, points] : curves)
    if (points.first.size() >= 2)
      out += masking_curves_figure("G1(v): " + key, "measured against Smith (analytic model: the closed form); error bars: one standard error",
                                   {"theta_v (deg)", "G1(v)"}, points.first, points.second);
  return out.empty() ? "" : "<h2>Masking curves</h2>\n" + out;
}

// Masking over several realisations (results.masking_realisations): per group, each value's mean, its standard
// error from the spread of the realisations and the Monte Carlo part alone.
std::string realisations_section_html(const json& document) {
  const json& results = member(document, "results");
  if (!results.contains("masking_realisations")) return "";
  std::string out = "<h2>Masking over realisations</h2>\n<p>Each value's mean over independent surfaces, its standard "
                    "error from their spread (surface-to-surface and Monte Carlo), and the Monte Carlo part alone.</p>\n";
  const auto value_row = [](const std::string& name, const json& v) {
    return row({esc(name), report_number(member(v, "mean")), report_number(member(v, "standard_error")),
                report_number(member(v, "monte_carlo_error"))});
  };
  for (const json& g : results["masking_realisations"]) {
    std::string body = value_row("G1", member(g, "g1"));
    if (g.contains("g2"))
      for (const json& v : g["g2"]) body += value_row("G2, light " + member(v, "light").dump(), v);
    if (g.contains("conditional"))
      for (const char* binning : {"by_normal", "by_height"})
        for (std::size_t b = 0; b < g["conditional"][binning].size(); ++b)
          body += value_row(fmt::format("G1 {} bin {}", binning, b + 1), g["conditional"][binning][b]);
    out += fmt::format("<h3>{} ({} realisations)</h3>\n", esc(text_of(member(g, "label"))), text_of(member(g, "realisations")));
    out += table({"value", "mean", "standard error (spread)", "Monte Carlo part"}, body);
  }
  return out;
}

}  // namespace
}  // namespace html

static std::string masking_report(const nlohmann::json& values, std::size_t, const ReportHistograms&, const ReportScatters&,
                                  const std::string& label) {
  return values.contains("masking") ? html::masking_values(values, label) : "";
}

namespace {
void add_realisation_means(const std::vector<MeasurementResult>& measurements, nlohmann::json& results) {
  const nlohmann::json means = masking_realisation_means(measurements);
  if (!means.empty()) results["masking_realisations"] = means;
}
}  // namespace

const KindSummary masking_summary{add_realisation_means, html::masking_curves_section_html, html::realisations_section_html};

// ---- its entry in the registry (measurement_registry.cpp) -------------------------------------------------

extern const MeasurementKind masking_kind{"masking", &masking_spec, true, masking_model, plan_masking_quantity,
                                          make_masking_measurement, masking_report, &masking_summary, nullptr};

}  // namespace microsim::experiment
