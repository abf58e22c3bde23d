// experiment: the scattering kind (measurement.h). Sampled (the Smith walk, Heitz et al. 2016, or paths on an
// explicit tile's Embree scene): rounds of paths, their exact sums added (ScatterHistogram::merge); the TV
// resolved by the largest per-order noise floor of the orders the plan targeted decides (measures.h,
// targeted_order_bins). Analytic (orders single on Smith's surface): the order-1 lobe by cubature, once; its
// error estimate over the albedo is the achieved error (no noise).
#include "experiment/plan_kinds.h"
#include "experiment/heightfield_measures.h"
#include "experiment/measurement.h"
#include "stats/scatter_figure.h"
#include "experiment/report_html.h"
#include "experiment/measures.h"

#include "core/errors.h"
#include "core/wall_clock.h"
#include "stats/scatter_compare.h"
#include "stats/scatter_io.h"
#include "stats/scatter_merge.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <limits>

namespace microsim::experiment {
// ---- its parts and split rounds (parts.h, split_rounds.h) ----------------------------------------------------

namespace {

using nlohmann::json;

// A scattering round's part: its histogram's part form (stats/scatter_merge.h scatter_part_json: every exact sum).
std::string scatter_part(const RoundTask& task, const ScatterHistogram& h) {
  return round_part(task, h.provenance.blocks, h.partial, scatter_part_json(h, {}));
}

// The parts (from `first` on; the root's own is rank 0's) added to `own` in rank order: the one-process round.
ScatterHistogram combine_scatter_parts(ScatterHistogram own, const std::vector<std::string>& parts,
                                       const RoundTask& task, int first) {
  check_start(own.provenance.blocks, own.partial, task.blocks, first, int(parts.size()));
  const auto add = [&](const json& s, const BlockRange& blocks, int) {
    add_scatter_part(own, read_scatter_part(s).histogram);
    own.provenance.blocks.end = blocks.end;
  };
  if (!own.partial && !add_parts(parts, task, first, add)) own.partial = true;
  return own;
}

// A scattering round (`paths`: the Smith walk's, or a tile's; run_part runs the same on the other ranks), split.
ScatterHistogram split_scatter_round(const RoundSplit& split, std::size_t measurement, const ScatterPaths& paths,
                                     const ScatterOptions& options) {
  const RoundTask task{measurement, options.paths, options.seed, round_blocks(options.blocks, options.paths, kPathsPerBlock)};
  return split_round<ScatterHistogram>(
      split, task,
      [&](const std::optional<BlockRange>& blocks) { return paths(with_blocks(options, blocks)); },
      [&](const ScatterHistogram& own, const BlockRange&) { return scatter_part(task, own); },
      [&](ScatterHistogram own, const std::vector<std::string>& parts, int first) {
        return combine_scatter_parts(std::move(own), parts, task, first);
      });
}

}  // namespace

namespace {

// The channel-0 order-1 albedo of an expectation: all of it, or what leaves on one side of the surface
// (reflected: the hemisphere of the light's own side). The cubature's summed error estimate over the albedo
// (analytic_lobe_error) bounds, to first order, the TV between the computed normalised lobe and the exact one
// (TV = 1/2 sum |p_i - q_i| <= sum |error_i| / W): 0 for an exact lobe, infinite for albedo 0 with an error.
double expectation_albedo(const ScatterExpectation& lobe, const Direction& view, ScatterSide side) {
  // Reflected light leaves into the hemisphere it came from: the upper one for light from above.
  const bool upper = (view.theta_deg < 90) == (side == ScatterSide::reflected);
  double sum = 0;
  for (std::size_t b = 0; b < lobe.bins(); ++b)
    if (lobe.reflection_bins[b] == upper) sum += lobe.order1[0][b];
  return sum;
}

double expectation_albedo(const ScatterExpectation& lobe, const Direction& view) {
  return expectation_albedo(lobe, view, ScatterSide::reflected) + expectation_albedo(lobe, view, ScatterSide::transmitted);
}

double analytic_lobe_error(const ScatterExpectation& lobe, const Direction& view) {
  const double error = lobe.error_estimate.empty() ? 0 : lobe.error_estimate[0];
  if (error == 0) return 0;
  const double albedo = expectation_albedo(lobe, view);
  return albedo > 0 ? error / albedo : std::numeric_limits<double>::infinity();
}

nlohmann::json scatter_estimate_json(const Estimate& e) {
  return {{"value", e.value}, {"standard_error", e.standard_error}};
}

nlohmann::json scatter_values(const ScatterHistogram& h, const std::vector<int>& targeted) {
  nlohmann::json orders = nlohmann::json::array();
  for (int k = 0; k < kScatterOrderBins; ++k)
    orders.push_back({{"order", scatter_order_name(k)},
                      {"albedo", scatter_estimate_json(h.albedo(0, k))},
                      {"reflected", scatter_estimate_json(h.albedo(0, k, ScatterSide::reflected))},
                      {"transmitted", scatter_estimate_json(h.albedo(0, k, ScatterSide::transmitted))},
                      {"noise_floor_tv", scatter_order_floor(h, k)},
                      {"targeted", std::find(targeted.begin(), targeted.end(), k) != targeted.end()}});
  return {{"scattering", {{"paths", h.paths()},
                          {"channel", h.channel_name(0)},
                          {"albedo", scatter_estimate_json(h.albedo(0, -1))},
                          {"unfinished", scatter_estimate_json(h.unfinished(0))},
                          {"orders", orders},
                          {"noise_floor_tv", scatter_noise_floor(h, targeted)},
                          {"rows_per_hemisphere", kScatterRows}}}};
}

// The walk's sums or the lobe, from the EXR run_directory.cpp wrote.
void read_scatter_back(const std::filesystem::path& exr, MeasurementResult& m) {
  ScatterFile file = read_scatter_exr(exr);
  m.scatter = std::move(file.histogram);
  m.expectation = std::move(file.expectation);
}

// Per-order lobes of sampled paths: the walk's or a tile's (paths_on).
class SampledScattering : public Measurement {
public:
  using Measurement::Measurement;
  std::string error_measure() const override {
    return fmt::format("the TV the lobes resolve: the largest per-order TV noise floor of the orders carrying at least "
                       "the target's share of the albedo, over {}", kNoiseShare);
  }
  bool split() const override { return true; }
  RoundTask first_round(std::size_t index, std::uint64_t seed) const override {
    return first_round_task(index, seed, first_units(decision_, 1), kPathsPerBlock);
  }
  void read_back(const std::filesystem::path& exr, MeasurementResult& m) const override {
    if (m.values.contains("scattering")) read_scatter_back(exr, m);
  }

protected:
  // The rounds, each split (split_scatter_round) with `paths` running a part.
  void run_paths(const RoundContext& c, const ScatterPaths& paths, MeasurementResult& m) const {
    const ScatterPaths walk = [&](const ScatterOptions& options) {
      return split_scatter_round(c.split(), c.index, paths, options);
    };
    run_histogram_rounds(c, m, std::numeric_limits<std::uint64_t>::max(),
                         [&](const RoundStart& start) { return round(c, start, walk, m); });
  }
  ScatterOptions request(const RoundTask& task, const BlockRange& mine, const RunControl& run) const {
    ScatterOptions options = scatter_request(material(), decision_, task.units, task.seed, run);
    options.blocks = mine;
    return options;
  }

private:
  bool round(const RoundContext& c, const RoundStart& start, const ScatterPaths& walk, MeasurementResult& m) const {
    ScatterOptions options = scatter_request(material(), decision_, start.units, start.seed, c.options.run);
    if (const auto blocks = start.blocks(kPathsPerBlock)) options.blocks = *blocks;
    const auto clock = std::chrono::steady_clock::now();
    const ScatterHistogram r = walk(options);
    m.partial = r.partial;
    if (r.paths() == 0) return false;
    if (m.scatter.binning_id().empty()) m.scatter = r;  // the first gives the binning and channels
    else m.scatter.merge(r);
    m.achieved = resolved_tv(scatter_noise_floor(m.scatter, decision_.targeted_orders));
    m.units += r.paths();
    m.rays += r.paths();
    m.rounds.push_back({start.done + r.paths(), start.units, r.provenance.blocks.end, r.partial, start.seed, 0,
                        seconds_since(clock), m.achieved});
    m.values = scatter_values(m.scatter, decision_.targeted_orders);
    return true;
  }
};

class WalkScattering final : public SampledScattering {
public:
  using SampledScattering::SampledScattering;
  std::string part(const RoundTask& task, const BlockRange& mine, const RunControl& run, SurfaceCache&) const override {
    return scatter_part(task, paths()(request(task, mine, run)));
  }
  void run(const RoundContext& c, MeasurementResult& m) const override { run_paths(c, paths(), m); }

private:
  ScatterPaths paths() const { return smith_walk_paths(scatter_surface(material(), decision_), walk_kernel_of(quantity_)); }
};

// On a tile (built once through the cache, or read back); its scene kept by the cache between rounds.
class HeightfieldScattering final : public SampledScattering {
public:
  using SampledScattering::SampledScattering;
  std::string part(const RoundTask& task, const BlockRange& mine, const RunControl& run,
                   SurfaceCache& surfaces) const override {
    const microgeom::Heightfield* field = decision_surface_or_null(decision_, surfaces, run);
    if (field == nullptr) return cancelled_part(task, mine);  // its build cancelled: a part cancelled before its first block
    return scatter_part(task, surface_paths(surfaces.scene_for(*field))(request(task, mine, run)));
  }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    const microgeom::Heightfield* field = decision_surface_or_null(decision_, c.surfaces, c.options.run);
    m.partial = field == nullptr;  // its build cancelled
    if (field == nullptr) return;
    // The scene is built when the root's own part begins: after the round was sent, while the ranks build theirs.
    run_paths(c, [&c, field](const ScatterOptions& part) { return surface_paths(c.surfaces.scene_for(*field))(part); }, m);
  }
};

// The cubature once (deterministic; resumed: run again).
class AnalyticScattering final : public Measurement {
public:
  using Measurement::Measurement;
  std::string error_measure() const override {
    return "the cubature's summed error estimate over the order-1 albedo (to first order a bound on the lobe's TV error)";
  }
  void read_back(const std::filesystem::path& exr, MeasurementResult& m) const override {
    if (m.values.contains("analytic_scattering")) read_scatter_back(exr, m);
  }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    run_once(m, [&] {
      const auto clock = std::chrono::steady_clock::now();
      m.expectation = analytic_scatter_lobe(material(), decision_, c.options.run);
      m.achieved = analytic_lobe_error(m.expectation, decision_.view);
      m.rounds.push_back({0, 0, 0, false, 0, 0, seconds_since(clock), m.achieved});
      m.met = m.achieved <= m.target;
      m.values = values(m.expectation, m.achieved);
    });
  }

private:
  nlohmann::json values(const ScatterExpectation& lobe, double relative_error) const {
    const Direction& view = decision_.view;
    const auto exact = [](double value) { return nlohmann::json{{"value", value}, {"standard_error", 0.0}}; };
    return {{"analytic_scattering", {{"channel", lobe.channel_names.at(0)},
                                     {"albedo", exact(expectation_albedo(lobe, view))},
                                     {"reflected", exact(expectation_albedo(lobe, view, ScatterSide::reflected))},
                                     {"transmitted", exact(expectation_albedo(lobe, view, ScatterSide::transmitted))},
                                     {"error_estimate", lobe.error_estimate.at(0)},
                                     {"relative_error", relative_error},
                                     {"rows_per_hemisphere", kScatterRows}}}};
  }
};


// ---- its plan ----------------------------------------------------------------------------------------------

// The walk of one view (a scattering measurement).
CapPilot view_cap_pilot(const ScatterPaths& walk, const ScatterOptions& view) {
  return [walk, view](int cap) {
    ScatterOptions o = view;
    o.max_order = cap;
    const ScatterHistogram h = walk(o);
    if (h.partial) throw Cancelled("plan: order-cap pilot");
    const double albedo = std::max(h.albedo(0, -1).value, 1e-300);
    Estimate u = h.unfinished(0);
    if (u.value == 0) u.standard_error = 1.5 / double(o.paths);  // none left: the rule of three
    return CapProbe{cap, u.value / albedo, u.standard_error / albedo};
  };
}

// A scattering pilot (`walk`: the Smith walk, or paths on a tile) run as its first quarter of blocks and the
// rest, merged: the whole pilot bit for bit, and its quarter for extrapolated_scatter_floor. Under 2 blocks,
// `quarter` is the whole pilot.
struct QuarteredPilot {
  ScatterHistogram quarter, whole;
};

QuarteredPilot run_quartered_pilot(const ScatterPaths& walk, const ScatterOptions& request) {
  const std::uint64_t blocks = BlockPlan{request.paths, kPathsPerBlock}.blocks();
  if (blocks < 2) {
    ScatterHistogram whole = walk(request);
    return {whole, whole};
  }
  ScatterOptions first = request, rest = request;
  first.blocks = BlockRange{0, std::max<std::uint64_t>(1, blocks / 4)};
  rest.blocks = BlockRange{first.blocks->end, blocks};
  QuarteredPilot pilot{walk(first), {}};
  pilot.whole = pilot.quarter;
  pilot.whole.merge(walk(rest));
  return pilot;
}

// The count of a walk's per-order lobes: a pilot of pilot_rays paths at the planned cap gives each order's
// TV noise floor, extrapolated to its 1/sqrt(n) law (extrapolated_scatter_floor); the paths bring the worst
// targeted order's to kNoiseShare of the target.
void plan_scattering_count(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, Decision& d,
                           const ScatterPaths& walk) {
  const SpecMaterial& m = spec.material(q.material);
  const auto start = std::chrono::steady_clock::now();
  const QuarteredPilot pilot = run_quartered_pilot(
      walk, scatter_request(m, d, o.pilot_rays, derived_seed(plan_seed(spec, o), kScatterPilot, d.quantity), o.run));
  if (pilot.whole.partial || pilot.quarter.partial) throw Cancelled("plan: scattering pilot");
  d.pilot_seconds = seconds_since(start);
  d.pilot_units = o.pilot_rays;
  d.targeted_orders = targeted_order_bins(pilot.whole, q.target);
  d.pilot_error = extrapolated_scatter_floor(pilot.quarter, pilot.whole, d.targeted_orders);
  d.units = units_for_standard_error(o.pilot_rays, d.pilot_error, kNoiseShare * q.target);
  d.unit = "paths";
  std::string orders;
  for (int k : d.targeted_orders)
    orders += fmt::format("{}{} {:.2e}", orders.empty() ? "" : ", ", scatter_order_name(k), scatter_order_floor(pilot.whole, k));
  d.count_reason = fmt::format("pilot of {} paths: per-order TV noise floors ({}; orders that may carry at least {} of the "
                               "albedo), the worst extrapolated to the 1/sqrt(n) law from the pilot's first quarter: "
                               "{:.2e}; resolving TV {} needs every floor <= {} x {} ({} rows per hemisphere)",
                               o.pilot_rays, orders, q.target, d.pilot_error, q.target, kNoiseShare, q.target, kScatterRows);
  d.predicted_seconds = predicted_seconds(d.units, d.pilot_units, d.pilot_seconds);
  d.runnable = true;
}

// The analytic order-1 lobe: deterministic, no count. Its pilot is the cubature itself (its time and error
// estimate are what the plan states; the run computes it again, as cheaply).
void plan_analytic_scattering(const SpecMaterial& m, const SpecQuantity& q, const PlanOptions& o, Decision& d) {
  const auto start = std::chrono::steady_clock::now();
  const ScatterExpectation lobe = analytic_scatter_lobe(m, d, o.run);
  d.pilot_seconds = seconds_since(start);
  d.pilot_error = analytic_lobe_error(lobe, d.view);
  d.count_reason = fmt::format("deterministic: the cubature of the order-1 lobe ({} rows per hemisphere), no rays; "
                               "its error estimate is {:.2e} of the albedo, against the target TV {}",
                               kScatterRows, d.pilot_error, q.target);
  d.predicted_seconds = d.pilot_seconds;
  d.runnable = true;
}

// The order cap and the count of a walk's per-order lobes, `walk` the Smith walk or the paths on a surface.
void plan_walk_scattering(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, Decision& d,
                          const ScatterPaths& walk) {
  const SpecMaterial& m = spec.material(q.material);
  ScatterOptions view;
  view.wi = direction_from_degrees(d.view.theta_deg, d.view.phi_deg);
  view.material = m.facet;
  view.paths = std::max(o.cap_pilot_paths, paths_to_bound_bias(kBiasShare * q.target));
  view.seed = derived_seed(plan_seed(spec, o), kCapPilot, d.quantity);
  view.rows = 1;
  view.run = o.run;
  std::tie(d.order_cap, d.cap_reason) =
      walk_order_cap(view_cap_pilot(walk, view), q.target, fmt::format("theta {} ({} paths)", d.view.theta_deg, view.paths));
  plan_scattering_count(spec, q, o, d, walk);
}

void plan_scattering_view(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, Decision& d) {
  const SpecMaterial& m = spec.material(q.material);
  if (d.model.model == Model::analytic) return plan_analytic_scattering(m, q, o, d);
  plan_walk_scattering(spec, q, o, d, smith_walk_paths(scatter_surface(m, d), walk_kernel_of(q)));
}

// The per-order lobes on a tile: its scene built once (kept: the run's rounds on this tile use it).
void plan_heightfield_scattering(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o,
                                 const microgeom::Heightfield& field, SurfaceCache& cache, Decision& d) {
  const auto scene_start = std::chrono::steady_clock::now();
  const HeightfieldScene& scene = cache.scene_for(field);
  const double scene_seconds = seconds_since(scene_start);
  plan_walk_scattering(spec, q, o, d, surface_paths(scene));
  d.predicted_seconds += scene_seconds;  // the run builds the tile's Embree scene once per measurement
}

}  // namespace

static void plan_scattering_quantity(const ExperimentSpec& spec, std::size_t index, const PlanOptions& o, SurfaceCache& cache,
                                     std::vector<Decision>& out) {
  plan_views(spec, index, o, cache, {plan_scattering_view, plan_heightfield_scattering}, out);
}

static std::unique_ptr<Measurement> make_scattering_measurement(const ExperimentSpec& spec, const Decision& decision) {
  if (decision.model.model == Model::analytic) return std::make_unique<AnalyticScattering>(spec, decision);
  if (decision.model.model == Model::heightfield) return std::make_unique<HeightfieldScattering>(spec, decision);
  return std::make_unique<WalkScattering>(spec, decision);
}

// ---- its model --------------------------------------------------------------------------------------------------

static ModelChoice scattering_model(const SpecQuantity& q, const SpecMaterial&) {
  return q.surface.kind != SurfaceChoice::Kind::automatic ? explicit_surface_choice(q) : smith_orders_choice(q, "");
}

// ---- its spec keys ---------------------------------------------------------------------------------------------

namespace {
// Light from inside a dielectric (theta in (90, 180]) is scattered too.
void read_scattering_spec(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m, const std::filesystem::path&) {
  q.target = read_target(t, "target_tv", 1, "a TV distance is below 1");
  q.directions = read_directions(t, m.facet.transmits());
  q.orders = read_orders(t);
  read_walk_kernel(t, q, m);
}
}  // namespace

const KindSpec scattering_spec{"orders target_tv theta theta_range phi walk_kernel", read_scattering_spec};

// ---- its report section (report_html.h) -----------------------------------------------------------------------

namespace html {
namespace {

// Lobes in the hemispheres binning of `rows` rows per hemisphere, as a figure of the page.
std::string lobes_figure(const std::string& label, const std::string& subtitle, int rows,
                         const std::vector<ScatterFigureRow>& figure_rows) {
  return "<figure>" + scatter_figure_svg(label, subtitle, DirectionBinning::hemispheres(rows), figure_rows) + "</figure>\n";
}

std::string scatter_figure(const ScatterHistogram& h, const std::string& label, int rows) {
  std::vector<ScatterFigureRow> figure_rows;
  const double n = double(std::max<std::uint64_t>(h.paths(), 1));
  for (int k = 0; k < kScatterOrderBins; ++k) {
    const Histogram& lobe = h.histogram(0, k);
    std::vector<double> values;
    for (std::size_t b = 0; b < lobe.size(); ++b) values.push_back(lobe.weight(b) / n);
    figure_rows.push_back({scatter_order_name(k), {{"Smith walk", values}}, {}});
  }
  const std::string subtitle = fmt::format("{} paths; weight per launched path per bin", h.paths());
  return lobes_figure(label, subtitle, rows, figure_rows);
}

std::string expectation_figure(const ScatterExpectation& lobe, const std::string& label, int rows) {
  const std::vector<ScatterFigureRow> figure_rows{{"order 1", {{"analytic", lobe.order1.at(0)}}, {}}};
  const std::string subtitle = "the single-scattering expectation by cubature; weight per launched path per bin";
  return lobes_figure(label, subtitle, rows, figure_rows);
}

std::string scattering_values(const json& values, const ReportScatters& scatters, std::size_t index,
                              const std::string& label) {
  const json& s = member(values, "scattering");
  std::string out = fmt::format("<p>{} paths; albedo {}, left on the surface at the cap {}.</p>\n",
                                text_of(member(s, "paths")), estimate_text(member(s, "albedo")),
                                estimate_text(member(s, "unfinished")));
  std::string body;
  for (const json& o : member(s, "orders"))
    body += row({esc(text_of(member(o, "order"))), estimate_text(member(o, "albedo")), estimate_text(member(o, "reflected")),
                 estimate_text(member(o, "transmitted")), report_number(member(o, "noise_floor_tv")),
                 member(o, "targeted").get<bool>() ? "yes" : "no (below the target's share)"});
  out += table({"order", "albedo", "reflected", "transmitted", "lobe TV noise floor", "targeted"}, body);
  const auto h = scatters.find(index);
  if (h != scatters.end() && h->second.kind == ScatterFileKind::histogram)
    out += scatter_figure(h->second.histogram, label, member(s, "rows_per_hemisphere").get<int>());
  return out + fmt::format("<p>Walk sums: <a href=\"scattering-{0}.exr\">scattering-{0}.exr</a>.</p>\n", index);
}

std::string analytic_scattering_values(const json& values, const ReportScatters& scatters, std::size_t index,
                                       const std::string& label) {
  const json& s = member(values, "analytic_scattering");
  std::string out = fmt::format("<p>Order 1 by cubature (no rays): albedo {}, reflected {}, transmitted {}; error "
                                "estimate {} ({} of the albedo).</p>\n",
                                report_number(member(member(s, "albedo"), "value")),
                                report_number(member(member(s, "reflected"), "value")),
                                report_number(member(member(s, "transmitted"), "value")),
                                report_number(member(s, "error_estimate")), report_number(member(s, "relative_error")));
  const auto h = scatters.find(index);
  if (h != scatters.end() && h->second.kind == ScatterFileKind::expectation)
    out += expectation_figure(h->second.expectation, label, member(s, "rows_per_hemisphere").get<int>());
  return out + fmt::format("<p>Lobe: <a href=\"scattering-{0}.exr\">scattering-{0}.exr</a>.</p>\n", index);
}

}  // namespace
}  // namespace html

static std::string scattering_report(const nlohmann::json& values, std::size_t index, const ReportHistograms&,
                                     const ReportScatters& scatters, const std::string& label) {
  if (values.contains("scattering")) return html::scattering_values(values, scatters, index, label);
  if (values.contains("analytic_scattering")) return html::analytic_scattering_values(values, scatters, index, label);
  return "";
}

// ---- its entry in the registry (measurement_registry.cpp) -------------------------------------------------

extern const MeasurementKind scattering_kind{"scattering", &scattering_spec, true, scattering_model,
                                             plan_scattering_quantity, make_scattering_measurement, scattering_report,
                                             nullptr, nullptr};

}  // namespace microsim::experiment
