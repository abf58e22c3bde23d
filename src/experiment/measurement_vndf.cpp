// experiment: the VNDF kind (measurement.h): rounds of rays, each from its own seed, their exact counts summed;
// the TV the sum resolves (resolved_tv: its noise floor over kNoiseShare) decides against target_tv. On the
// ellipsoid oracle (Heitz 2018: a convex GGX ellipsoid's visible normals are D_v) or on an explicit tile
// (built once through the SurfaceCache). A cancelled round keeps its completed blocks (a shorter run of its
// seed), and a resumed run traces on from its first missing block: the counts of the uninterrupted run.
#include "experiment/plan_kinds.h"
#include "experiment/heightfield_measures.h"
#include "experiment/measurement.h"
#include "experiment/report_html.h"
#include "experiment/measures.h"

#include "core/errors.h"
#include "core/parse.h"
#include "core/wall_clock.h"
#include "stats/part_json.h"

#include <fmt/core.h>
#include <fmt/ranges.h>

#include <chrono>

namespace microsim::experiment {
// ---- its parts and split rounds (parts.h, split_rounds.h) ----------------------------------------------------

namespace {

using nlohmann::json;

// A VNDF round's part: its histogram's part form (measure/vndf.h vndf_part_json: counts, unbinned rays, a
// tile's tracer diagnostics, exact).
std::string vndf_part(const RoundTask& task, const TracedHistogram& histogram) {
  return round_part(task, vndf_provenance(histogram).blocks, histogram.partial, vndf_part_json(histogram));
}

// The parts (from `first` on; the root's own is rank 0's) added to `own` in rank order (add_vndf_part): the
// one-process round's counts, and its trace and attributes (blocks, unbinned, rate; a tile's diagnostics),
// timed `seconds`.
template <class Vndf>
void add_vndf_parts(Vndf& own, const std::vector<std::string>& parts, const RoundTask& task, int first, double seconds) {
  TracedHistogram& h = own.histogram;
  TraceResult& t = own.trace;
  check_start(t.blocks, t.partial, task.blocks, first, int(parts.size()));
  const auto add = [&](const json& s, const BlockRange& blocks, int) {
    add_vndf_part(h, t.unbinned, read_vndf_part(s));
    t.blocks.end = blocks.end;
  };
  if (!t.partial && !add_parts(parts, task, first, add)) t.partial = true;
  t.counts = h.counts;
  t.rays = h.rays;
  t.hits = h.hits;
  t.seconds = seconds;
  h.partial = t.partial;
  h.attributes["blocks"] = fmt::format("{},{}", t.blocks.begin, t.blocks.end);
  h.attributes["unbinned"] = fmt::format("{}", fmt::join(t.unbinned, ","));
  h.attributes["rays_per_second"] = fmt::format("{:.17g}", t.rays_per_second());
}

EllipsoidVndf combine_vndf_parts(EllipsoidVndf own, const std::vector<std::string>& parts, const RoundTask& task,
                                 int first, double seconds) {
  add_vndf_parts(own, parts, task, first, seconds);
  EllipsoidVndf combined = analyse_ellipsoid_vndf(std::move(own.histogram), own.trace.unbinned);
  combined.trace = std::move(own.trace);
  combined.expected_hit_fraction = own.expected_hit_fraction;
  return combined;
}

HeightfieldVndf combine_vndf_parts(HeightfieldVndf own, const std::vector<std::string>& parts,
                                   const RoundTask& task, int first, double seconds) {
  add_vndf_parts(own, parts, task, first, seconds);
  own.diagnostics = heightfield_diagnostics(own.histogram);
  return own;
}

// A VNDF round, the ellipsoid's or a tile's (`trace` of a request's blocks), split.
template <class Vndf, class Trace>
Vndf split_traced_round(const RoundSplit& split, std::size_t measurement, const VndfRequest& request, const Trace& trace) {
  const auto start = std::chrono::steady_clock::now();
  const RoundTask task{measurement, request.rays, request.seed, round_blocks(request.blocks, request.rays, kRaysPerBlock)};
  return split_round<Vndf>(
      split, task, [&](const std::optional<BlockRange>& blocks) { return trace(with_blocks(request, blocks)); },
      [&](const Vndf& own, const BlockRange&) { return vndf_part(task, own.histogram); },
      [&](Vndf own, const std::vector<std::string>& parts, int first) {
        return combine_vndf_parts(std::move(own), parts, task, first, seconds_since(start));
      });
}

// An ellipsoid's VNDF round, split: the round's counts, not analysed (the caller analyses its sum).
EllipsoidVndf split_vndf_round(const RoundSplit& split, std::size_t measurement, const EllipsoidTarget& target,
                               const VndfRequest& request) {
  return split_traced_round<EllipsoidVndf>(split, measurement, request,
                                           [&](const VndfRequest& r) { return measure_ellipsoid_vndf(target, r); });
}

}  // namespace

HeightfieldVndf split_heightfield_vndf_round(const RoundSplit& split, std::size_t measurement, const SceneOf& scene,
                                             const microgeom::Heightfield& field, const std::string& label,
                                             const VndfRequest& request) {
  return split_traced_round<HeightfieldVndf>(
      split, measurement, request, [&](const VndfRequest& r) { return trace_heightfield_vndf(scene(), field, label, r); });
}

namespace {

class VndfMeasurement : public Measurement {
public:
  using Measurement::Measurement;
  std::string error_measure() const override {
    return fmt::format("the TV the histogram resolves: its TV noise floor (expected TV of an exact sampler, largest "
                       "binning) over {}", kNoiseShare);
  }
  bool split() const override { return true; }
  RoundTask first_round(std::size_t index, std::uint64_t seed) const override {
    // Capped as the rounds cap them.
    return first_round_task(index, seed, std::min(first_units(decision_, 1), kMaxRays), kRaysPerBlock);
  }
  void read_back(const std::filesystem::path& exr, MeasurementResult& m) const override {
    if (m.values.contains("analysis")) m.histogram = read_histogram_exr(exr);  // the summed counts
  }

protected:
  // One round (or the rest of one): `trace` of its request, its counts added to the sum, the sum analysed
  // (`analyse(round, fresh)` sets achieved, values and the histogram) and the round recorded.
  template <class Trace, class Analyse>
  bool round(const RoundContext& c, const RoundStart& start, MeasurementResult& m, const Trace& trace,
             const Analyse& analyse) const {
    VndfRequest req = vndf_request(spec_, decision_, start.units, start.seed, c.options.run);
    if (const auto blocks = start.blocks(kRaysPerBlock)) req.blocks = *blocks;
    const auto clock = std::chrono::steady_clock::now();
    const auto r = trace(req);
    m.partial = r.trace.partial;  // cancelled: its completed blocks are a shorter run of that seed, kept
    if (r.histogram.rays == 0) return false;
    const bool fresh = m.histogram.binnings.empty();
    if (fresh) {  // the first gives the binnings and attributes
      m.histogram = r.histogram;
      m.unbinned = r.trace.unbinned;
    } else {
      add_vndf_part(m.histogram, m.unbinned, r.histogram);  // a tile's diagnostics too: the analysis reads them
    }
    analyse(r, fresh);
    m.units += r.histogram.rays;
    m.rays += r.histogram.rays;
    m.rounds.push_back({start.done + r.histogram.rays, start.units, r.trace.blocks.end, r.trace.partial, start.seed, 0,
                        seconds_since(clock), m.achieved});
    return true;
  }
};

// On the ellipsoid oracle.
class EllipsoidVndfMeasurement final : public VndfMeasurement {
public:
  using VndfMeasurement::VndfMeasurement;
  std::string part(const RoundTask& task, const BlockRange& mine, const RunControl& run, SurfaceCache&) const override {
    VndfRequest request = vndf_request(spec_, decision_, task.units, task.seed, run);
    request.blocks = mine;
    return vndf_part(task, measure_ellipsoid_vndf(target(decision_), request).histogram);
  }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    const auto trace = [&](const VndfRequest& req) { return split_vndf_round(c.split(), c.index, target(decision_), req); };
    run_histogram_rounds(c, m, kMaxRays, [&](const RoundStart& start) {
      return round(c, start, m, trace, [&](const EllipsoidVndf& r, bool fresh) { analyse(r, fresh, m); });
    });
  }

private:
  static EllipsoidTarget target(const Decision& d) { return EllipsoidTarget(d.alpha.first, d.alpha.second, -1); }
  // The sum analysed; a whole first round's own analysis is the sum's (the reference's cubature not paid twice).
  static void analyse(const EllipsoidVndf& r, bool fresh, MeasurementResult& m) {
    const EllipsoidVndf analysed = fresh && !r.trace.partial ? r : analyse_ellipsoid_vndf(m.histogram, m.unbinned);
    m.achieved = resolved_tv(vndf_noise_floor(analysed));
    m.values = {{"analysis", to_json(analysed.analysis)},
                {"rays", analysed.histogram.rays},
                {"hits", analysed.histogram.hits},
                {"expected_hit_fraction", r.expected_hit_fraction},
                {"total_variation", vndf_total_variation(analysed)},
                {"noise_floor_tv", vndf_noise_floor(analysed)},
                {"unbinned", m.unbinned}};
    m.histogram = analysed.histogram;
  }
};

// On an explicit tile: every rank traces the same tile (its SurfaceCache's).
class HeightfieldVndfMeasurement final : public VndfMeasurement {
public:
  using VndfMeasurement::VndfMeasurement;
  std::string part(const RoundTask& task, const BlockRange& mine, const RunControl& run,
                   SurfaceCache& surfaces) const override {
    return tile_vndf_part(spec_, decision_, task, mine, run, surfaces);
  }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    const microgeom::Heightfield* field = decision_surface_or_null(decision_, c.surfaces, c.options.run);
    m.partial = field == nullptr;  // its build cancelled
    if (field == nullptr) return;
    // The scene is built when the root's own part begins: after the round was sent, while the ranks build theirs.
    const SceneOf scene = [&c, field]() -> const HeightfieldScene& { return c.surfaces.scene_for(*field); };
    const auto trace = [&](const VndfRequest& req) {
      return split_heightfield_vndf_round(c.split(), c.index, scene, *field, surface_label(decision_.surface), req);
    };
    run_histogram_rounds(c, m, kMaxRays, [&](const RoundStart& start) {
      return round(c, start, m, trace, [&](const HeightfieldVndf&, bool) {
        const HeightfieldVndf analysed = analyse_heightfield_vndf(m.histogram, m.unbinned, *field);  // the sum so far
        m.achieved = resolved_tv(heightfield_noise_floor(analysed));
        m.values = heightfield_vndf_values(analysed, m.unbinned, decision_.surface);
        m.histogram = analysed.histogram;
      });
    });
  }
};


// ---- its plan ----------------------------------------------------------------------------------------------

// A VNDF's rays from its pilot (on the ellipsoid, or `on` a tile): the TV noise floor ~ 1/sqrt(n) brought to
// kNoiseShare of the target. The tracing scales with the rays; what the pilot spent besides tracing (the
// scene, the reference's cubature, the empirical Smith tables) is paid once.
void count_vndf_rays(const SpecQuantity& q, const PlanOptions& o, double pilot_floor, double trace_seconds,
                     std::string_view on, Decision& d) {
  d.pilot_units = o.pilot_rays;
  d.pilot_error = pilot_floor;
  d.units = units_for_standard_error(o.pilot_rays, d.pilot_error, kNoiseShare * q.target);
  d.unit = "rays";
  d.count_reason = fmt::format("pilot of {} rays{}: TV noise floor {:.2e} ~ 1/sqrt(n); resolving TV {} needs a floor "
                               "<= {} x {} (rows {})", o.pilot_rays, on, d.pilot_error, q.target, kNoiseShare, q.target, q.rows);
  const double overhead = std::max(0.0, d.pilot_seconds - trace_seconds);
  d.predicted_seconds = overhead + predicted_seconds(d.units, d.pilot_units, trace_seconds);
}

void plan_vndf_view(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, Decision& d) {
  const EllipsoidTarget target(d.alpha.first, d.alpha.second, -1);
  VndfRequest r;
  r.theta_deg = d.view.theta_deg;
  r.phi_deg = d.view.phi_deg;
  r.rays = o.pilot_rays;
  r.seed = derived_seed(plan_seed(spec, o), kVndfPilot, d.quantity);
  r.rows = q.rows;
  r.run = o.run;
  const auto start = std::chrono::steady_clock::now();
  const EllipsoidVndf m = measure_ellipsoid_vndf(target, r);
  if (m.trace.partial) throw Cancelled("plan: vndf pilot");
  d.pilot_seconds = seconds_since(start);
  count_vndf_rays(q, o, vndf_noise_floor(m), m.trace.seconds, "", d);
  d.runnable = true;
}

// The VNDF traced on the tile: a pilot of pilot_rays rays gives the noise floor (~ 1/sqrt(n)) and the rate.
void plan_heightfield_vndf(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o,
                           const microgeom::Heightfield& field, SurfaceCache& cache, Decision& d) {
  const auto start = std::chrono::steady_clock::now();
  HeightfieldVndf traced = trace_heightfield_vndf(
      cache.scene_for(field), field, surface_label(d.surface),  // the scene kept: the run's rounds may use it
      vndf_request(spec, d, o.pilot_rays, derived_seed(plan_seed(spec, o), kVndfPilot, d.quantity), o.run));
  if (traced.trace.partial) throw Cancelled("plan: vndf pilot");
  const HeightfieldVndf m = analyse_heightfield_vndf(std::move(traced.histogram), traced.trace.unbinned, field);
  d.pilot_seconds = seconds_since(start);
  count_vndf_rays(q, o, heightfield_noise_floor(m), traced.trace.seconds, " on the tile", d);
}

}  // namespace

static void plan_vndf_quantity(const ExperimentSpec& spec, std::size_t index, const PlanOptions& o, SurfaceCache& cache,
                               std::vector<Decision>& out) {
  plan_views(spec, index, o, cache, {plan_vndf_view, plan_heightfield_vndf, nullptr, false}, out);
}

std::string tile_vndf_part(const ExperimentSpec& spec, const Decision& decision, const RoundTask& task,
                           const BlockRange& mine, const RunControl& run, SurfaceCache& surfaces) {
  const microgeom::Heightfield* field = decision_surface_or_null(decision, surfaces, run);
  if (field == nullptr) return cancelled_part(task, mine);  // its build cancelled: a part cancelled before its first block
  VndfRequest request = vndf_request(spec, decision, task.units, task.seed, run);
  request.blocks = mine;
  const HeightfieldVndf m = trace_heightfield_vndf(surfaces.scene_for(*field), *field, surface_label(decision.surface), request);
  return vndf_part(task, m.histogram);
}

static std::unique_ptr<Measurement> make_vndf_measurement(const ExperimentSpec& spec, const Decision& decision) {
  if (decision.model.model == Model::heightfield) return std::make_unique<HeightfieldVndfMeasurement>(spec, decision);
  return std::make_unique<EllipsoidVndfMeasurement>(spec, decision);
}

// ---- its model --------------------------------------------------------------------------------------------------

static ModelChoice vndf_model(const SpecQuantity& q, const SpecMaterial&) {
  if (q.surface.kind != SurfaceChoice::Kind::automatic) return explicit_surface_choice(q);
  return {Model::ellipsoid_oracle, "a measured VNDF histogram: the exact ellipsoid oracle (Heitz 2018: the visible "
                                   "normals of the convex GGX ellipsoid are D_v exactly; only Monte Carlo noise, no "
                                   "heightfield bias)"};
}

// ---- its spec keys ---------------------------------------------------------------------------------------------

namespace {
void read_vndf_spec(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m, const std::filesystem::path&) {
  q.target = read_target(t, "target_tv", 1, "a TV distance is below 1");
  q.directions = read_directions(t, false);
  read_validator_rows(t, q, m);
}
}  // namespace

const KindSpec vndf_spec{"target_tv theta theta_range phi rows", read_vndf_spec};

// ---- its report section (report_html.h) -----------------------------------------------------------------------

namespace html {
namespace {

std::string vndf_fit_table(const json& values) {
  std::string body;
  for (const json& fit : member(member(values, "analysis"), "binnings")) {
    std::vector<std::string> cells{esc(text_of(member(fit, "binning")))};
    for (const char* key : {"total_variation", "noise_floor_tv"}) cells.push_back(report_number(member(fit, key)));
    const json& chi2 = fit.contains("chi2") ? fit["chi2"] : json::object();
    for (const char* key : {"statistic", "dof", "p_value"})
      cells.push_back(chi2.contains(key) ? report_number(chi2[key]) : "-");
    body += row(cells);
  }
  return table({"binning", "TV vs analytic D_v", "noise floor TV", "chi-square", "dof", "p"}, body);
}

std::string vndf_values(const json& values, const ReportHistograms& histograms, std::size_t index,
                        const std::string& label) {
  std::string out = fmt::format("<p>{} rays, {} hits (expected hit fraction {}); measured TV against the analytic "
                                "D_v {}, noise floor {}.</p>\n",
                                text_of(member(values, "rays")), text_of(member(values, "hits")),
                                report_number(member(values, "expected_hit_fraction")),
                                report_number(member(values, "total_variation")),
                                report_number(member(values, "noise_floor_tv")));
  out += vndf_fit_table(values);
  if (values.contains("heightfield")) {
    const json& f = values["heightfield"];
    out += fmt::format("<p>On the tile ({}): TV to Smith with the tile's own NDF {} (its masking, without the NDF's "
                       "bias); back-facing first hits {}, convex-edge grazes passed over {}, leaked {}, unresolved {}.</p>\n",
                       esc(text_of(member(f, "surface"))), report_number(member(f, "tv_own_ndf")),
                       text_of(member(f, "backfacing")), text_of(member(f, "edge_grazes")), text_of(member(f, "leaked")),
                       text_of(member(f, "unresolved")));
  }
  const auto h = histograms.find(index);
  if (h != histograms.end()) out += histogram_figure(h->second, label, "analytic D_v");
  return out + fmt::format("<p>Histogram: <a href=\"vndf-{0}.exr\">vndf-{0}.exr</a>.</p>\n", index);
}

}  // namespace
}  // namespace html

static std::string vndf_report(const nlohmann::json& values, std::size_t index, const ReportHistograms& histograms, const ReportScatters&,
                               const std::string& label) {
  return values.contains("analysis") ? html::vndf_values(values, histograms, index, label) : "";
}

// ---- its entry in the registry (measurement_registry.cpp) -------------------------------------------------

extern const MeasurementKind vndf_kind{"vndf", &vndf_spec, true, vndf_model, plan_vndf_quantity,
                                       make_vndf_measurement, vndf_report, nullptr, nullptr};

}  // namespace microsim::experiment
