// experiment: plan_experiment: the pilots behind the decisions (plan.h).
#include "experiment/heightfield_measures.h"
#include "core/wall_clock.h"
#include "experiment/masking_runs.h"
#include "experiment/measures.h"
#include "experiment/plan.h"
#include "experiment/split_rounds.h"
#include "experiment/surface_albedo.h"
#include "experiment/surface_cache.h"

#include "validate/compare.h"
#include "validate/sample_io.h"
#include "validate/validation_part.h"
#include "scatter/smith_walk.h"
#include "scatter/surface_scatter.h"
#include "stats/binning.h"
#include "stats/scatter_compare.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <chrono>
#include <filesystem>
#include <functional>
#include <string_view>
#include <vector>

namespace microsim::experiment {
namespace {

enum SeedPurpose : std::uint64_t { kCapPilot = 1, kTablePilot = 2, kVndfPilot = 3, kScatterPilot = 4, kValidationPilot = 5 };

std::uint64_t plan_seed(const ExperimentSpec& spec, const PlanOptions& options) {
  return options.seed != 0 ? options.seed : spec.seed;
}

std::string alpha_text(const std::pair<double, double>& a) {
  return a.first == a.second ? fmt::format("{}", a.first) : fmt::format("{},{}", a.first, a.second);
}

// ---- the walk's order cap -----------------------------------------------------------------------------------

// A pilot of the walk at one cap: the weight left on the surface relative to the albedo, at the cell or view
// where that is largest.
using CapPilot = std::function<CapProbe(int cap)>;

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

// The roughest row of an albedo table (paths stay longest on the roughest surface), every mu: the cell whose
// unfinished weight (plus two standard errors) is the largest share of its E. `cells`: the walk's, or on tiles.
CapPilot table_cap_pilot(AlbedoTableRequest row, const AlbedoCellsOf& cells) {
  return [row, cells](int cap) {
    AlbedoTableRequest r = row;
    r.max_order = cap;
    const AlbedoTable t = split_albedo_round({}, 0, r, cells);
    if (t.partial) throw Cancelled("plan: order-cap pilot");
    CapProbe worst{cap, 0, 0};
    for (std::size_t m = 0; m < t.mus.size(); ++m) {
      Estimate u = t.cell("unfinished", 0, m);
      // None left among n paths: the 95% upper bound is 3 / n (the rule of three), i.e. "2 standard errors".
      if (u.value == 0) u.standard_error = 1.5 / double(r.paths);
      const double e = std::max(t.cell("E", 0, m).value, 1e-300);
      if ((u.value + 2 * u.standard_error) / e > worst.unfinished + 2 * worst.unfinished_se)
        worst = {cap, u.value / e, u.standard_error / e};
    }
    return worst;
  };
}

// Paths per cell or view with which "none left" bounds the bias below `threshold` with room: the rule of
// three (3 / n) at half the threshold.
std::uint64_t paths_to_bound_bias(double threshold) { return std::uint64_t(std::ceil(6.0 / threshold)); }

// Caps 4, 8, 16, ... probed until one leaves less than kBiasShare of the (relative) target on the surface;
// the cap and its reason.
std::pair<int, std::string> walk_order_cap(const CapPilot& pilot, double relative_target, const std::string& where) {
  std::vector<CapProbe> probes;
  const double threshold = kBiasShare * relative_target;
  for (int cap = 4; cap <= kMaxOrderCap; cap *= 2) {
    probes.push_back(pilot(cap));
    if (const auto chosen = order_cap_for(probes, threshold))
      return {*chosen, fmt::format("{}: {} orders leave {:.2e} +- {:.1e} of E on the surface (worst), below {} x "
                                   "target = {:.2e}{}",
                                   where, *chosen, probes.back().unfinished, probes.back().unfinished_se, kBiasShare,
                                   threshold, probes.size() > 1 ? fmt::format("; {} orders left {:.2e}", probes[probes.size() - 2].cap, probes[probes.size() - 2].unfinished) : "")};
  }
  return {kMaxOrderCap, fmt::format("{}: no cap up to {} leaves less than {} x target on the surface: the largest "
                                    "cap, its bias reported", where, kMaxOrderCap, kBiasShare)};
}

// ---- albedo -------------------------------------------------------------------------------------------------

void plan_analytic_albedo(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, Decision& d) {
  // The quadrature's error estimate per cell, absolute: 1e-3 of the relative target keeps it below the target
  // for every E >= 1e-3 (a GGX mirror's E1 is above 0.05 on the table's range).
  d.tolerance = std::clamp(1e-3 * q.target, 1e-13, 1e-2);
  d.count_reason = fmt::format("deterministic: quadrature to {:.0e} absolute per cell (1e-3 x target); rerun "
                               "tighter if an error estimate exceeds the target", d.tolerance);
  AlbedoTableRequest pilot = albedo_request(spec, q, Model::analytic, 1, 0, d.tolerance, 1, o.run);
  const std::size_t rows = pilot.alphas.size();
  pilot.alphas = {pilot.alphas.front()};
  const AlbedoTable t = albedo_table(pilot);
  if (t.partial) throw Cancelled("plan: albedo pilot");
  d.pilot_units = 1;
  d.pilot_seconds = t.seconds;
  d.pilot_error = worst_relative_error(t, q);
  d.predicted_seconds = t.seconds * double(rows);
  d.unit = "";
}

// A sampled table (the walk's, or on the decision's tiles: `cells`): its order cap from the roughest row (1
// for single scattering, which only an explicit surface samples), then a pilot table for the paths per cell.
void plan_sampled_albedo(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, const AlbedoCellsOf& cells,
                         Decision& d) {
  const std::uint64_t seed = plan_seed(spec, o);
  const std::uint64_t cap_paths =
      std::max(o.cap_pilot_paths / std::uint64_t(q.mus), paths_to_bound_bias(kBiasShare * q.target));
  if (q.orders == Orders::single) {
    d.order_cap = 1;
    d.cap_reason = "single scattering: the first bounce only";
  } else {
    AlbedoTableRequest row = sampled_albedo_request(spec, d, cap_paths, derived_seed(seed, kCapPilot, d.quantity), o.run);
    row.alphas = {row.alphas.back()};  // increasing: the roughest
    std::tie(d.order_cap, d.cap_reason) = walk_order_cap(
        table_cap_pilot(row, cells), q.target, fmt::format("alpha {}, {} mus, {} paths per cell", row.alphas.front(), q.mus, row.paths));
  }
  const AlbedoTable t = split_albedo_round(
      {}, 0, sampled_albedo_request(spec, d, o.pilot_paths, derived_seed(seed, kTablePilot, d.quantity), o.run), cells);
  if (t.partial) throw Cancelled("plan: albedo pilot");
  d.pilot_units = o.pilot_paths;
  d.pilot_seconds = t.seconds;
  d.pilot_error = worst_relative_error(t, q);
  d.units = units_for_standard_error(o.pilot_paths, d.pilot_error, q.target);
  d.unit = "paths per cell";
  d.count_reason = fmt::format("pilot of {} paths per cell: worst relative SE of {} {:.2e}; n = {} x ({:.2e} / {:.0e})^2",
                               o.pilot_paths, albedo_target_text(q), d.pilot_error, o.pilot_paths, d.pilot_error,
                               q.target);
  d.predicted_seconds = predicted_seconds(d.units, d.pilot_units, d.pilot_seconds);
  d.runnable = true;
}

// The tile a decision planned, into d.surface; false (with why it is not runnable) when none fits.
bool take_surface(const SurfaceDecision& s, Decision& d) {
  d.surface = s.plan;
  if (s.runnable) return true;
  d.count_reason = "no tile: " + s.why;
  d.not_runnable = s.why;
  return false;
}

// An albedo table on explicit surfaces (surface_albedo.h): its tiles (the same size at every alpha) built
// into `cache`, then as a walk's, the paths on the tiles.
void plan_surface_albedo(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, SurfaceCache& cache,
                         Decision& d) {
  if (!take_surface(plan_albedo_surfaces(spec, q, plan_seed(spec, o), o.run), d)) return;
  const auto start = std::chrono::steady_clock::now();
  const std::size_t built = cache.builds();
  double scene_seconds = 0;  // every tile's Embree scene: built again in each round (the cache keeps one at a time)
  for (const auto& alpha : spec.material(q.material).alphas) {
    const microgeom::Heightfield& field = cache.surface_for(surface_key(d.surface, {alpha.first, alpha.first}), o.run);
    const auto scene_start = std::chrono::steady_clock::now();
    cache.scene_for(field);
    scene_seconds += seconds_since(scene_start);
  }
  d.surface.reason += fmt::format("; {} tiles ({} built during the plan, kept for the run; {:.3g} s with their scenes)",
                                  spec.material(q.material).alphas.size(), cache.builds() - built, seconds_since(start));
  plan_sampled_albedo(spec, q, o, albedo_cells_of(d, cache), d);
  d.count_reason += " (the error on these tiles: the spread between realisations is not in it)";
  // The pilot's time holds the scenes too: they are paid per round, the tracing per path.
  d.predicted_seconds = scene_seconds + predicted_seconds(d.units, d.pilot_units, std::max(0.0, d.pilot_seconds - scene_seconds));
}

Decision plan_albedo(const ExperimentSpec& spec, std::size_t index, const PlanOptions& o, SurfaceCache& cache) {
  const SpecQuantity& q = spec.quantities[index];
  const SpecMaterial& m = spec.material(q.material);
  Decision d;
  d.quantity = index;
  d.label = fmt::format("{} albedo {} ({} alphas x {} mus{})", q.key, m.name, m.alphas.size(), q.mus,
                        q.inside ? ", inside" : "");
  d.model = choose_model(q, m);
  if (d.model.model == Model::analytic) {
    plan_analytic_albedo(spec, q, o, d);
    d.runnable = true;
  } else if (d.model.model == Model::smith_walk) {
    plan_sampled_albedo(spec, q, o, walk_albedo_cells, d);
  } else {
    plan_surface_albedo(spec, q, o, cache, d);
  }
  return d;
}

// ---- per view: vndf, scattering, validation ---------------------------------------------------------------

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

// A scattering pilot (`walk`: the Smith walk, or paths on a tile) run as its first quarter of blocks and the
// rest, merged: the whole pilot bit for bit, and its quarter for extrapolated_scatter_floor. Under 2 blocks,
// `quarter` is the whole pilot.
struct QuarteredPilot {
  ScatterHistogram quarter, whole;
};
QuarteredPilot run_quartered_pilot(const ScatterPaths& walk, const ScatterOptions& request) {
  const std::uint64_t blocks = (request.paths + kPathsPerBlock - 1) / kPathsPerBlock;
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
  const SmithMicrosurface surface = scatter_surface(m, d);
  plan_walk_scattering(spec, q, o, d, [surface](const ScatterOptions& r) { return smith_walk_scatter(surface, r); });
}

// A dump's rows, read from the file (every row checked: a file that cannot be read as samples is bad input
// naming the spec's key, before anything runs). A second pass over the file, the run's being the first to test.
std::uint64_t dump_rows(const SpecQuantity& q, const RunControl& run) {
  try {
    DirectionSampleReader reader = open_dump(q);
    std::vector<Vec3<double>> block(kSampleFileBlock);
    std::vector<double> pdfs(reader.columns().has_pdf() ? block.size() : 0);
    std::vector<double> weights(block.size() * std::size_t(reader.columns().channels()));
    while (reader.read(block, pdfs, weights) > 0)
      if (run.cancelled()) throw Cancelled("plan: reading a dump");
    return reader.rows_read();
  } catch (const SampleFileError& e) {
    throw dump_error(q, e);
  }
}

// The time of a drawn validation: its reference's cubature (paid once), then the samples at the rate of a
// pilot of kChunkBlocks blocks of them (as many as the validator runs at once: every thread busy).
void time_validation(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, Decision& d) {
  const SamplerInfo& sampler = *find_sampler(q.sampler);  // the spec names a zoo sampler (spec.cpp)
  const auto start = std::chrono::steady_clock::now();
  const auto reference = claimed_reference(sampler, GGX<double>(d.alpha.first, d.alpha.second),
                                           direction_from_degrees(d.view.theta_deg, d.view.phi_deg), q.rows);
  const auto drawn = std::chrono::steady_clock::now();
  const std::uint64_t pilot = std::min<std::uint64_t>(d.units, kChunkBlocks * kSampleBlock);
  tally_drawn_samples(sampler, *reference,
                      validation_request(q, pilot, derived_seed(plan_seed(spec, o), kValidationPilot, d.quantity), o.run));
  const double reference_seconds = std::chrono::duration<double>(drawn - start).count();
  const double tally_seconds = seconds_since(drawn);
  d.pilot_units = pilot;
  d.pilot_seconds = reference_seconds + tally_seconds;
  d.predicted_seconds = reference_seconds + predicted_seconds(d.units, pilot, tally_seconds);
}

// A dump against its analytic reference: every row is tested, so the count is the file's rows and the TV they
// detect follows from it; detect_tv, when the spec gives one, is a target those rows meet or not.
void plan_dump_validation(const SpecQuantity& q, const PlanOptions& o, Decision& d) {
  const ValidationTests tests = validation_tests(q.rows, q.significance);
  d.units = dump_rows(q, o.run);
  d.unit = "samples";
  const double detected = detectable_tv(d.units, tests.dof, tests.level, q.power);
  d.count_reason = fmt::format("the dump's {} rows (read from {}), all tested: they detect any deviation of TV {:.3g} "
                               "with power {} at level {:.3g} per binning (Sidak of {}), df {} (noncentrality >= 4 N "
                               "TV^2)", d.units, std::filesystem::path(q.dump).filename().string(), detected, q.power,
                               tests.level, q.significance, tests.dof);
  if (q.target > 0) {
    const std::uint64_t needed = validation_samples(q.target, tests.dof, tests.level, q.power);
    d.count_reason += fmt::format("; detect_tv {} needs {} rows: {}", q.target, needed,
                                  d.units >= needed ? "the dump has them" : "the dump has fewer (target not met)");
  } else {
    d.count_reason += "; no detect_tv asked: the rows fix the TV detected";
  }
  d.runnable = true;
}

void plan_validation_view(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, Decision& d) {
  if (!q.dump.empty()) return plan_dump_validation(q, o, d);
  const ValidationTests tests = validation_tests(q.rows, q.significance);
  d.units = validation_samples(q.target, tests.dof, tests.level, q.power);
  d.unit = "samples";
  d.count_reason = fmt::format("chi-square power: df {}, level {:.3g} per binning (Sidak of {}), power {} against any "
                               "deviation of TV {} (noncentrality >= 4 N TV^2)", tests.dof, tests.level, q.significance,
                               q.power, q.target);
  time_validation(spec, q, o, d);
  d.runnable = true;
}

// ---- an explicit heightfield (vndf, scattering) ---------------------------------------------------------------

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

// Why a validation cannot be made against a tile's traced visible normals ("" when it can): the reference is
// D_v of the tile, so the samples must claim D_v (a zoo sampler of visible normals; a dump with pdf vndf).
std::string surface_validation_refusal(const SpecQuantity& q) {
  if (!q.dump.empty() && q.dump_pdf != "vndf")
    return fmt::format("a dump of pdf {} against a surface: the traced reference is the tile's visible normals (pdf "
                       "vndf only)", q.dump_pdf);
  if (!q.dump.empty())
    return SampleColumns::parse(q.dump_columns).channels() == 0 ? "" : "a dump with weights against a surface: the "
                                                                       "traced reference is the tile's visible normals "
                                                                       "(their weights are tested analytically)";
  const SamplerInfo& sampler = *find_sampler(q.sampler);  // the spec names a zoo sampler (spec.cpp)
  if (sampler.domain == SampleDomain::microfacet_normal && sampler.claims == ClaimedPdf::visible_normals) return "";
  return fmt::format("sampler {} does not claim the visible normals: the traced reference is the tile's visible "
                     "normals", sampler.name);
}

// A validation against the tile's traced visible normals (validate/compare.h: the two-sample chi-square in
// each binning of the traced histogram, Sidak-combined). A two-sample test of n samples against n rays has the
// noncentrality of a one-sample test of n / 2: twice the analytic validator's samples, and as many rays (at
// least twice the two-sample minimum of a pilot's proportions). The tile's bias is at most kBiasShare of the
// deviation to detect (its size rule), so a correct sampler is rejected little more often than the level says.
void plan_heightfield_validation(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o,
                                 const microgeom::Heightfield& field, SurfaceCache& cache, Decision& d) {
  const ValidationTests tests = validation_tests(q.rows, q.significance);
  const auto start = std::chrono::steady_clock::now();
  const HeightfieldVndf pilot = trace_heightfield_vndf(
      cache.scene_for(field), field, surface_label(d.surface),
      vndf_request(spec, d, o.pilot_rays, derived_seed(plan_seed(spec, o), kVndfPilot, d.quantity), o.run));
  if (pilot.trace.partial) throw Cancelled("plan: validation pilot on the tile");
  const std::uint64_t minimum = 2 * trace_minimum_samples(pilot.histogram);
  d.units = std::max(2 * validation_samples(q.target, tests.dof, tests.level, q.power), minimum);
  d.unit = "samples";
  d.count_reason = fmt::format("two-sample chi-square against as many rays traced on the tile: power {} at level {:.3g} "
                               "per binning (Sidak of {}), df {}, against any deviation of TV {}: twice the one-sample "
                               "count (noncentrality >= 4 (n/2) TV^2), at least twice the two-sample minimum of the "
                               "pilot's proportions ({})",
                               q.power, tests.level, q.significance, tests.dof, q.target, minimum);
  if (!q.dump.empty())
    d.count_reason += fmt::format("; the dump's {} rows (read from {}) are all tested, against the planned rays",
                                  dump_rows(q, o.run), std::filesystem::path(q.dump).filename().string());
  d.pilot_units = o.pilot_rays;
  d.pilot_seconds = seconds_since(start);
  d.pilot_error = 0;
  // The tracing scales with the rays (the samples' draws are cheaper and not timed).
  d.predicted_seconds = predicted_seconds(d.units, d.pilot_units, pilot.trace.seconds);
}

// The tile of a heightfield decision (the trade table's size, or the user's), built (or read) through the
// cache, then its pilot: the VNDF's rays, or the order cap and paths of its per-order scattering.
void plan_heightfield_view(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, SurfaceCache& cache,
                           Decision& d) {
  if (q.kind == QuantityKind::validation) {
    d.not_runnable = surface_validation_refusal(q);
    if (!d.not_runnable.empty()) return;
  }
  if (!take_surface(plan_surface(q, d, plan_seed(spec, o), cache), d)) return;
  const auto start = std::chrono::steady_clock::now();
  const std::size_t built = cache.builds();
  const microgeom::Heightfield& field = decision_surface(d, cache, o.run);
  const double surface_seconds = seconds_since(start);
  if (q.kind == QuantityKind::vndf) {
    plan_heightfield_vndf(spec, q, o, field, cache, d);
  } else if (q.kind == QuantityKind::validation) {
    plan_heightfield_validation(spec, q, o, field, cache, d);
  } else {
    const auto scene_start = std::chrono::steady_clock::now();
    const HeightfieldScene& scene = cache.scene_for(field);  // kept: the run's rounds on this tile use it
    const double scene_seconds = seconds_since(scene_start);
    plan_walk_scattering(spec, q, o, d, [&scene](const ScatterOptions& r) { return scatter_on_surface(scene, r); });
    d.predicted_seconds += scene_seconds;  // the run builds the tile's Embree scene once per measurement
  }
  d.surface.reason += cache.builds() > built
                          ? fmt::format("; built in {:.3g} s during the plan (kept for the run)", surface_seconds)
                          : fmt::format("; not built: {} ({:.3g} s)", q.surface.kind == SurfaceChoice::Kind::heightmap
                                                                         ? "the user's file" : "shared or read back", surface_seconds);
  d.runnable = true;
}

void plan_views(const ExperimentSpec& spec, std::size_t index, const PlanOptions& o, SurfaceCache& cache,
                std::vector<Decision>& out) {
  const SpecQuantity& q = spec.quantities[index];
  const SpecMaterial& m = spec.material(q.material);
  for (const auto& alpha : m.alphas)
    for (const Direction& v : q.directions) {
      Decision d;
      d.quantity = index;
      d.alpha = alpha;
      d.view = v;
      d.label = fmt::format("{} {} {} alpha {} theta {} phi {}", q.key, to_string(q.kind), m.name, alpha_text(alpha),
                            v.theta_deg, v.phi_deg);
      d.model = choose_model(q, m);
      if (d.model.model == Model::heightfield) {
        plan_heightfield_view(spec, q, o, cache, d);
      } else if (q.kind == QuantityKind::vndf) {
        plan_vndf_view(spec, q, o, d);
      } else if (q.kind == QuantityKind::scattering) {
        plan_scattering_view(spec, q, o, d);
      } else {
        plan_validation_view(spec, q, o, d);
      }
      out.push_back(std::move(d));
    }
}

}  // namespace

ExperimentPlan plan_experiment(const ExperimentSpec& spec, const PlanOptions& options) {
  ExperimentPlan plan;
  SurfaceCache memory;  // without the caller's cache: surfaces for this plan only
  SurfaceCache& surfaces = options.surfaces != nullptr ? *options.surfaces : memory;
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < spec.quantities.size(); ++i) {
    if (options.run.cancelled()) throw Cancelled("plan");
    if (spec.quantities[i].kind == QuantityKind::albedo)
      plan.decisions.push_back(plan_albedo(spec, i, options, surfaces));
    else if (spec.quantities[i].kind == QuantityKind::masking)
      plan_masking(spec, i, options, surfaces, plan.decisions);
    else
      plan_views(spec, i, options, surfaces, plan.decisions);
  }
  plan.pilot_seconds = seconds_since(start);
  for (const Decision& d : plan.decisions) plan.predicted_seconds += d.predicted_seconds;
  return plan;
}

}  // namespace microsim::experiment
