// experiment: run_experiment: the sequential rounds of each runnable decision (run.h).
#include "experiment/run.h"
#include "experiment/surface_albedo.h"
#include "core/wall_clock.h"

#include "experiment/heightfield_measures.h"
#include "experiment/masking_runs.h"
#include "experiment/masking_surface.h"
#include "experiment/measures.h"
#include "experiment/split_rounds.h"
#include "core/parse.h"
#include "scatter/albedo_table_io.h"
#include "scatter/surface_scatter.h"
#include "validate/compare.h"
#include "validate/validate.h"
#include "validate/sample_io.h"
#include "stats/scatter_compare.h"

#include <fmt/core.h>

#include <chrono>
#include <algorithm>
#include <limits>
#include <cmath>
#include <stdexcept>

namespace microsim::experiment {
namespace {

enum RunSeedPurpose : std::uint64_t { kRoundSeed = 16 };

std::uint64_t round_seed(std::uint64_t seed, std::size_t decision, int round) {
  return derived_seed(seed, kRoundSeed, std::uint64_t(decision) * 1024 + std::uint64_t(round));
}

// The reference rays of a validation against a tile: round 1's seed (its samples draw from round 0's).
std::uint64_t validation_rays_seed(std::uint64_t seed, std::size_t decision) { return round_seed(seed, decision, 1); }

// ---- albedo ----------------------------------------------------------------------------------------------

// The rounds' tables as one table of their summed paths per cell (pool_rounds per cell and per E_avg).
AlbedoTable pool_tables(const std::vector<AlbedoTable>& tables, const std::vector<std::uint64_t>& units) {
  AlbedoTable pooled = tables.back();
  pooled.seconds = 0;
  pooled.request.paths = 0;
  for (std::size_t r = 0; r < tables.size(); ++r) {
    pooled.seconds += tables[r].seconds;
    pooled.request.paths += units[r];
  }
  for (std::size_t k = 0; k < pooled.quantities.size(); ++k) {
    const auto pool_member = [&](auto member, std::size_t i) {
      std::vector<Estimate> rounds;
      for (const AlbedoTable& t : tables) rounds.push_back((t.quantities[k].*member)[i]);
      return pool_rounds(rounds, units);
    };
    for (std::size_t i = 0; i < pooled.quantities[k].cells.size(); ++i)
      pooled.quantities[k].cells[i] = pool_member(&AlbedoQuantity::cells, i);
    for (std::size_t i = 0; i < pooled.quantities[k].average.size(); ++i)
      pooled.quantities[k].average[i] = pool_member(&AlbedoQuantity::average, i);
  }
  return pooled;
}

void record_albedo(MeasurementResult& m, const AlbedoTable& table) {
  m.values = albedo_table_json(table);
  m.csv = albedo_table_csv(table);
}

std::uint64_t first_units(const Decision& d, const RunOptions& o) {
  return std::max<std::uint64_t>(1, std::uint64_t(std::ceil(double(d.units) * o.cost_factor)));
}

// A sampled table (the walk's, or on the decision's tiles from `surfaces`) in rounds until its target is met.
void run_sampled_albedo(const ExperimentSpec& spec, std::uint64_t seed, std::size_t index, const RunOptions& o,
                        SurfaceCache& surfaces, MeasurementResult& m) {
  const Decision& d = m.decision;
  const SpecQuantity& q = spec.quantities[d.quantity];
  const AlbedoCellsOf cells = albedo_cells_of(d, surfaces);
  std::vector<AlbedoTable> tables;  // resumed: the completed rounds' tables
  std::vector<std::uint64_t> units;
  for (std::size_t r = 0; r < m.round_tables.size(); ++r) {
    tables.push_back(albedo_table_from_json(m.round_tables[r],
                                            sampled_albedo_request(spec, d, m.rounds[r].units, m.rounds[r].seed, o.run)));
    units.push_back(m.rounds[r].units);
  }
  m.partial = false;
  std::uint64_t n = tables.empty() ? first_units(d, o) : next_round_units(m.units, m.achieved, m.target);
  for (int r = int(tables.size()); r < o.max_rounds && n > 0; ++r) {
    const std::uint64_t s = round_seed(seed, index, r);
    AlbedoTable t = split_albedo_round({o.ranks, o.stored}, index, sampled_albedo_request(spec, d, n, s, o.run), cells);
    if (t.partial) {  // a round cut short is run again whole on resumption
      m.partial = true;
      break;
    }
    m.round_tables.push_back(albedo_table_json(t));
    tables.push_back(std::move(t));
    units.push_back(n);
    const AlbedoTable pooled = pool_tables(tables, units);
    m.achieved = worst_relative_error(pooled, q);
    m.rounds.push_back({n, n, 0, false, s, 0, tables.back().seconds, m.achieved});
    m.units += n;
    m.rays += n * pooled.alphas.size() * pooled.mus.size();
    record_albedo(m, pooled);
    n = next_round_units(m.units, m.achieved, m.target);
  }
  m.met = !tables.empty() && m.achieved <= m.target;
}

void run_analytic_albedo(const ExperimentSpec& spec, const RunOptions& o, MeasurementResult& m) {
  const Decision& d = m.decision;
  const SpecQuantity& q = spec.quantities[d.quantity];
  double tolerance = d.tolerance;
  m.rounds.clear();  // resumed: deterministic and cheap, run again
  m.partial = false;
  for (int r = 0; r < o.max_rounds && !m.met && tolerance >= 1e-13; ++r, tolerance /= 100) {
    const AlbedoTable t = albedo_table(albedo_request(spec, q, Model::analytic, 1, 0, tolerance, 1, o.run));
    if (t.partial) {
      m.partial = true;
      break;
    }
    m.achieved = worst_relative_error(t, q);
    m.rounds.push_back({0, 0, 0, false, 0, tolerance, t.seconds, m.achieved});
    m.met = m.achieved <= m.target;
    record_albedo(m, t);
  }
}

// ---- vndf --------------------------------------------------------------------------------------------------

// Adds a round's exact counts to the sum (the first round gives the binnings and attributes).
void add_counts(TracedHistogram& sum, std::vector<std::uint64_t>& unbinned, const TracedHistogram& round,
                const std::vector<std::uint64_t>& round_unbinned) {
  if (sum.binnings.empty()) {
    sum = round;
    unbinned = round_unbinned;
    return;
  }
  for (std::size_t k = 0; k < sum.counts.size(); ++k)
    for (std::size_t i = 0; i < sum.counts[k].size(); ++i) sum.counts[k][i] += round.counts[k][i];
  for (std::size_t k = 0; k < unbinned.size(); ++k) unbinned[k] += round_unbinned[k];
  sum.rays += round.rays;
  sum.hits += round.hits;
}

void add_round(TracedHistogram& sum, std::vector<std::uint64_t>& unbinned, const EllipsoidVndf& round) {
  add_counts(sum, unbinned, round.histogram, round.trace.unbinned);
}

void record_vndf(MeasurementResult& m, const EllipsoidVndf& analysed, double hit_fraction) {
  m.values = {{"analysis", to_json(analysed.analysis)},
              {"rays", analysed.histogram.rays},
              {"hits", analysed.histogram.hits},
              {"expected_hit_fraction", hit_fraction},
              {"total_variation", vndf_total_variation(analysed)},
              {"noise_floor_tv", vndf_noise_floor(analysed)},
              {"unbinned", m.unbinned}};
  m.histogram = analysed.histogram;
}

// The round to run next (a traced VNDF or a walk): a partial round of a resumed run from its first missing
// block (its record removed: the finished round replaces it), else a new round of at most `max_units` rays.
struct RoundStart {
  std::uint64_t rays = 0, first_block = 0, seed = 0, done = 0;  // done: rays of the round already counted
};

RoundStart next_round(MeasurementResult& m, std::uint64_t seed, std::size_t index, const RunOptions& o,
                      std::uint64_t max_units) {
  if (!m.rounds.empty() && m.rounds.back().partial) {
    const RoundRecord r = m.rounds.back();
    m.rounds.pop_back();
    return {r.planned, r.blocks_done, r.seed, r.units};
  }
  const std::uint64_t n = m.rounds.empty() ? first_units(m.decision, o) : next_round_units(m.units, m.achieved, m.target);
  return {std::min(n, max_units), 0, round_seed(seed, index, int(m.rounds.size())), 0};
}

// One round (or the rest of one): traced, added to the sum, the sum analysed and recorded. False when
// nothing was traced (cancelled before its first block).
bool vndf_round(const ExperimentSpec& spec, const EllipsoidTarget& target, const RoundStart& start, std::size_t index,
                const RunOptions& o, MeasurementResult& m) {
  VndfRequest req = vndf_request(spec, m.decision, start.rays, start.seed, o.run);
  if (start.first_block > 0) req.blocks = BlockRange{start.first_block, (start.rays + kRaysPerBlock - 1) / kRaysPerBlock};
  const auto clock = std::chrono::steady_clock::now();
  const EllipsoidVndf round = split_vndf_round({o.ranks, o.stored}, index, target, req);
  m.partial = round.trace.partial;  // cancelled: its completed blocks are a shorter run of that seed, kept
  if (round.histogram.rays == 0) return false;
  const bool fresh = m.histogram.binnings.empty();
  add_round(m.histogram, m.unbinned, round);
  // A whole first round: its own analysis is the sum's (the reference's cubature is not paid twice).
  const EllipsoidVndf analysed = fresh && !round.trace.partial ? round : analyse_ellipsoid_vndf(m.histogram, m.unbinned);
  m.achieved = resolved_tv(vndf_noise_floor(analysed));
  m.units += round.histogram.rays;
  m.rays += round.histogram.rays;
  m.rounds.push_back({start.done + round.histogram.rays, start.rays, round.trace.blocks.end, round.trace.partial,
                      req.seed, 0, seconds_since(clock), m.achieved});
  record_vndf(m, analysed, round.expected_hit_fraction);
  return true;
}

// The sequential rounds of a histogram (a VNDF, a walk's lobes): rounds of at most `max_units` until the
// target is met, kMaxRounds are run or a round is cut short (a partial round of a resumed run first).
void run_rounds(MeasurementResult& m, std::uint64_t seed, std::size_t index, const RunOptions& o, std::uint64_t max_units,
                const std::function<bool(const RoundStart&)>& round) {
  m.partial = false;
  while (int(m.rounds.size()) < o.max_rounds || (!m.rounds.empty() && m.rounds.back().partial)) {
    const RoundStart start = next_round(m, seed, index, o, max_units);
    if (start.rays == 0 || !round(start) || m.partial) break;
  }
  m.met = !m.rounds.empty() && !m.rounds.back().partial && m.achieved <= m.target;
}

void run_vndf(const ExperimentSpec& spec, std::uint64_t seed, std::size_t index, const RunOptions& o, MeasurementResult& m) {
  const EllipsoidTarget target(m.decision.alpha.first, m.decision.alpha.second, -1);
  run_rounds(m, seed, index, o, kMaxRays,
             [&](const RoundStart& start) { return vndf_round(spec, target, start, index, o, m); });
}

// ---- scattering (the Smith walk) ---------------------------------------------------------------------------

// Adds a round's (or a part of a round's) exact sums to the sum; the first gives the binning and channels.
void add_scatter_round(ScatterHistogram& sum, const ScatterHistogram& round) {
  if (sum.binning_id().empty()) {
    sum = round;
    return;
  }
  for (int c = 0; c < round.channels(); ++c) {
    for (int k = 0; k < kScatterOrderBins; ++k) {
      const Histogram& h = round.histogram(c, k);
      for (std::size_t b = 0; b < h.size(); ++b) sum.add_sums(c, k, b, h.exact_weight(b), h.exact_weight_squared(b));
      sum.add_unbinned_sums(c, k, h.exact_unbinned_weight(), h.exact_unbinned_weight_squared());
    }
    sum.add_unfinished_sums(c, round.exact_unfinished(c, false), round.exact_unfinished(c, true));
    sum.add_lost_sums(c, round.exact_lost(c, false), round.exact_lost(c, true));
  }
  sum.add_launched(round.paths());
}

nlohmann::json estimate_json(const Estimate& e) { return {{"value", e.value}, {"standard_error", e.standard_error}}; }

void record_scatter(MeasurementResult& m) {
  const ScatterHistogram& h = m.scatter;
  nlohmann::json orders = nlohmann::json::array();
  const std::vector<int>& targeted = m.decision.targeted_orders;
  for (int k = 0; k < kScatterOrderBins; ++k)
    orders.push_back({{"order", scatter_order_name(k)},
                      {"albedo", estimate_json(h.albedo(0, k))},
                      {"reflected", estimate_json(h.albedo(0, k, ScatterSide::reflected))},
                      {"transmitted", estimate_json(h.albedo(0, k, ScatterSide::transmitted))},
                      {"noise_floor_tv", scatter_order_floor(h, k)},
                      {"targeted", std::find(targeted.begin(), targeted.end(), k) != targeted.end()}});
  m.values = {{"scattering", {{"paths", h.paths()},
                              {"channel", h.channel_name(0)},
                              {"albedo", estimate_json(h.albedo(0, -1))},
                              {"unfinished", estimate_json(h.unfinished(0))},
                              {"orders", orders},
                              {"noise_floor_tv", scatter_noise_floor(h, targeted)},
                              {"rows_per_hemisphere", kScatterRows}}}};
}

bool scatter_round(const ExperimentSpec& spec, const RoundStart& start, const RunOptions& o, const ScatterPaths& walk,
                   MeasurementResult& m) {
  const Decision& d = m.decision;
  const SpecMaterial& material = spec.material(spec.quantities[d.quantity].material);
  ScatterOptions options = scatter_request(material, d, start.rays, start.seed, o.run);
  if (start.first_block > 0) options.blocks = BlockRange{start.first_block, (start.rays + kPathsPerBlock - 1) / kPathsPerBlock};
  const auto clock = std::chrono::steady_clock::now();
  const ScatterHistogram round = walk(options);
  m.partial = round.partial;
  if (round.paths() == 0) return false;
  add_scatter_round(m.scatter, round);
  m.achieved = resolved_tv(scatter_noise_floor(m.scatter, d.targeted_orders));
  m.units += round.paths();
  m.rays += round.paths();
  m.rounds.push_back({start.done + round.paths(), start.rays, round.provenance.blocks.end, round.partial, start.seed, 0,
                      seconds_since(clock), m.achieved});
  record_scatter(m);
  return true;
}

void run_scattering(const ExperimentSpec& spec, std::uint64_t seed, std::size_t index, const RunOptions& o,
                    MeasurementResult& m) {
  const SmithMicrosurface surface = scatter_surface(spec.material(spec.quantities[m.decision.quantity].material), m.decision);
  const ScatterPaths walk = [&](const ScatterOptions& options) {
    return split_scatter_round({o.ranks, o.stored}, index,
                               [&surface](const ScatterOptions& part) { return smith_walk_scatter(surface, part); }, options);
  };
  run_rounds(m, seed, index, o, std::numeric_limits<std::uint64_t>::max(),
             [&](const RoundStart& start) { return scatter_round(spec, start, o, walk, m); });
}

// ---- an explicit heightfield (vndf, scattering) --------------------------------------------------------------

// One round (or the rest of one) of rays traced on the tile, added to the sum, the sum analysed and recorded.
bool heightfield_vndf_round(const ExperimentSpec& spec, const SceneOf& scene, const microgeom::Heightfield& field,
                            const RoundStart& start, std::size_t index, const RunOptions& o, MeasurementResult& m) {
  VndfRequest req = vndf_request(spec, m.decision, start.rays, start.seed, o.run);
  if (start.first_block > 0) req.blocks = BlockRange{start.first_block, (start.rays + kRaysPerBlock - 1) / kRaysPerBlock};
  const auto clock = std::chrono::steady_clock::now();
  const HeightfieldVndf round =
      split_heightfield_vndf_round({o.ranks, o.stored}, index, scene, field, surface_label(m.decision.surface), req);
  m.partial = round.trace.partial;
  if (round.histogram.rays == 0) return false;
  const bool fresh = m.histogram.binnings.empty();
  if (!fresh) add_heightfield_diagnostics(m.histogram, round.histogram);  // the analysis reads them there
  add_counts(m.histogram, m.unbinned, round.histogram, round.trace.unbinned);
  const HeightfieldVndf analysed = analyse_heightfield_vndf(m.histogram, m.unbinned, field);  // the sum so far
  m.achieved = resolved_tv(heightfield_noise_floor(analysed));
  m.units += round.histogram.rays;
  m.rays += round.histogram.rays;
  m.rounds.push_back({start.done + round.histogram.rays, start.rays, round.trace.blocks.end, round.trace.partial,
                      req.seed, 0, seconds_since(clock), m.achieved});
  m.values = heightfield_vndf_values(analysed, m.unbinned, m.decision.surface);
  m.histogram = analysed.histogram;
  return true;
}

void record_validation(const ValidationReport& r, const SpecQuantity& q, std::uint64_t planned, double seconds,
                       MeasurementResult& m);  // the validations' section, below

// A validation against the tile's traced visible normals (plan.cpp plan_heightfield_validation): the planned
// rays traced in one round of seed 1 (split over the ranks, or a merge's stored parts: validation_rays_round),
// then the zoo sampler's samples (drawn as validate_sampler draws them, from the round seed 0) or the dump's
// against them on this process (validate/compare.h). Cancelled: nothing is kept, as an analytic validation.
void run_heightfield_validation(const ExperimentSpec& spec, std::uint64_t seed, std::size_t index, const RunOptions& o,
                                const SceneOf& scene, const microgeom::Heightfield& field, MeasurementResult& m) {
  const Decision& d = m.decision;
  const SpecQuantity& q = spec.quantities[d.quantity];
  const std::uint64_t n = first_units(d, o);
  m.rounds.clear();
  m.partial = false;
  const auto clock = std::chrono::steady_clock::now();
  const HeightfieldVndf traced = split_heightfield_vndf_round(
      {o.ranks, o.stored}, index, scene, field, surface_label(d.surface),
      vndf_request(spec, d, n, validation_rays_seed(seed, index), o.run));
  const GGX<double> ggx(d.alpha.first, d.alpha.second);
  const Vec3<double> wi = direction_from_degrees(d.view.theta_deg, d.view.phi_deg);
  const ValidationOptions v = validation_request(q, n, round_seed(seed, index, 0), o.run);
  try {
    if (traced.trace.partial) throw Cancelled("the validation's rays");
    ValidationReport r;
    if (q.dump.empty()) {
      r = compare_sampler_to_trace(*find_sampler(q.sampler), ggx, wi, v, traced.histogram);
    } else {
      DirectionSampleReader reader = open_dump(q);
      r = compare_sample_file_to_trace(reader, q.dump, ggx, wi, v, traced.histogram);
    }
    record_validation(r, q, n, seconds_since(clock), m);
    m.values["validation"]["reference"] = fmt::format("{} rays traced on {}", traced.histogram.hits, surface_label(d.surface));
  } catch (const Cancelled&) {
    m.partial = true;
  } catch (const SampleFileError& e) {
    throw dump_error(q, e);
  } catch (const InsufficientData& e) {
    if (q.dump.empty()) throw;
    throw dump_error(q, e);
  }
}

// The tile (built once through the cache, or read back), then the rounds on it: rays for a VNDF, paths for
// the per-order lobes, split over the ranks (every rank traces the same tile: split_rounds.h).
void run_heightfield(const ExperimentSpec& spec, std::uint64_t seed, std::size_t index, const RunOptions& o,
                     SurfaceCache& cache, MeasurementResult& m) {
  m.partial = false;
  const microgeom::Heightfield* field = nullptr;
  try {
    field = &decision_surface(m.decision, cache, o.run);
  } catch (const Cancelled&) {
    m.partial = true;
    return;
  }
  // The scene, kept by the cache between rounds (and for the next decision on the tile), is built when the
  // root's own part begins: after the round was sent, while the other ranks build theirs.
  const SceneOf scene = [&cache, field]() -> const HeightfieldScene& { return cache.scene_for(*field); };
  if (spec.quantities[m.decision.quantity].kind == QuantityKind::validation)
    return run_heightfield_validation(spec, seed, index, o, scene, *field, m);
  if (spec.quantities[m.decision.quantity].kind == QuantityKind::vndf)
    return run_rounds(m, seed, index, o, kMaxRays,
                      [&](const RoundStart& start) { return heightfield_vndf_round(spec, scene, *field, start, index, o, m); });
  const ScatterPaths walk = [&](const ScatterOptions& options) {
    return split_scatter_round({o.ranks, o.stored}, index,
                               [&scene](const ScatterOptions& part) { return scatter_on_surface(scene(), part); }, options);
  };
  run_rounds(m, seed, index, o, std::numeric_limits<std::uint64_t>::max(),
             [&](const RoundStart& start) { return scatter_round(spec, start, o, walk, m); });
}

// ---- scattering (the analytic order-1 lobe) ----------------------------------------------------------------

void record_analytic_scatter(MeasurementResult& m) {
  const ScatterExpectation& lobe = m.expectation;
  const Direction& view = m.decision.view;
  const auto exact = [](double value) { return nlohmann::json{{"value", value}, {"standard_error", 0.0}}; };
  m.values = {{"analytic_scattering", {{"channel", lobe.channel_names.at(0)},
                                       {"albedo", exact(expectation_albedo(lobe, view))},
                                       {"reflected", exact(expectation_albedo(lobe, view, ScatterSide::reflected))},
                                       {"transmitted", exact(expectation_albedo(lobe, view, ScatterSide::transmitted))},
                                       {"error_estimate", lobe.error_estimate.at(0)},
                                       {"relative_error", m.achieved},
                                       {"rows_per_hemisphere", kScatterRows}}}};
}

// The cubature once (deterministic; resumed: run again, as the analytic albedo).
void run_analytic_scattering(const ExperimentSpec& spec, const RunOptions& o, MeasurementResult& m) {
  const Decision& d = m.decision;
  m.rounds.clear();
  m.partial = false;
  const auto clock = std::chrono::steady_clock::now();
  try {
    m.expectation = analytic_scatter_lobe(spec.material(spec.quantities[d.quantity].material), d, o.run);
  } catch (const Cancelled&) {
    m.partial = true;
    return;
  }
  m.achieved = analytic_lobe_error(m.expectation, d.view);
  m.rounds.push_back({0, 0, 0, false, 0, 0, seconds_since(clock), m.achieved});
  m.met = m.achieved <= m.target;
  record_analytic_scatter(m);
}

// ---- validation --------------------------------------------------------------------------------------------

// The validator's binned counts as a histogram (counts, and the claimed pdf's bin probabilities): what the
// report draws and validation-K.exr keeps.
TracedHistogram validation_histogram(const ValidationReport& r, const Decision& d) {
  TracedHistogram h;
  for (const BinnedComparison& c : r.histograms) {
    h.binnings.push_back(c.binning);
    std::vector<std::uint64_t> counts;
    std::vector<double> probability;
    for (std::size_t i = 0; i < c.observed.size(); ++i) {
      counts.push_back(std::uint64_t(std::llround(c.observed[i])));
      probability.push_back(r.samples > 0 ? c.expected[i] / double(r.samples) : 0.0);
    }
    h.counts.push_back(std::move(counts));
    h.probability.push_back(std::move(probability));
  }
  h.rays = h.hits = r.samples;
  h.attributes = {{"surface", "sampler " + r.sampler},
                  {"alpha", fmt::format("{},{}", d.alpha.first, d.alpha.second)},
                  {"theta", fmt::format("{}", d.view.theta_deg)},
                  {"phi", fmt::format("{}", d.view.phi_deg)},
                  {"seed", std::to_string(r.seed)}};
  return h;
}

// The TV deviation `samples` rows of a dump detect against its analytic reference (their count is the file's,
// not planned: plan.h detectable_tv).
double dump_detected_tv(const SpecQuantity& q, std::uint64_t samples) {
  const ValidationTests tests = validation_tests(q.rows, q.significance);
  return detectable_tv(std::max<std::uint64_t>(samples, 1), tests.dof, tests.level, q.power);
}

bool is_analytic_dump(const SpecQuantity& q, const Decision& d) {
  return !q.dump.empty() && d.model.model == Model::analytic_validator;
}

// The validation's result: the deviation its samples detect (N ~ 1 / tv^2, plan.h: the planned count detects
// the target; a dump's rows what they detect), the report and counts.
void record_validation(const ValidationReport& r, const SpecQuantity& q, std::uint64_t planned, double seconds,
                       MeasurementResult& m) {
  const Decision& d = m.decision;
  m.achieved = is_analytic_dump(q, d)
                   ? dump_detected_tv(q, r.samples)
                   : q.target * std::sqrt(double(d.units) / double(std::max<std::uint64_t>(r.samples, 1)));
  m.units = m.rays = r.samples;
  m.rounds.push_back({r.samples, planned, 0, false, r.seed, 0, seconds, m.achieved});
  m.values = {{"validation", to_json(r)}};
  m.histogram = validation_histogram(r, d);
  m.met = m.achieved <= m.target * (1 + 1e-12);
}

// A dump: every sample of the file against the density it claims, its weights against its material's BSDF in
// its convention (validate_dump_as_given, streamed; light from inside a dielectric mirrored). A file that
// cannot be read, or holds too few samples, is bad input (std::invalid_argument naming the file).
void run_dump_validation(const SpecQuantity& q, const SpecMaterial& material, const RunOptions& o, MeasurementResult& m) {
  const Decision& d = m.decision;
  const GGX<double> ggx(d.alpha.first, d.alpha.second);
  const Vec3<double> view = direction_from_degrees(d.view.theta_deg, d.view.phi_deg);
  ValidationOptions v = validation_request(q, 0, 0, o.run);
  const DumpClaims claims = dump_claims(q, material);
  if (SampleColumns::parse(q.dump_columns).channels() > 0) v.bsdf = claims.bsdf;  // the weight test
  v.convention = q.convention;
  if (q.dump_dropped > 0) v.dropped_below_horizon = q.dump_dropped;
  m.rounds.clear();
  m.partial = false;
  const auto clock = std::chrono::steady_clock::now();
  try {
    DirectionSampleReader reader = open_dump(q);
    ValidationReport r = validate_dump_as_given(reader, claims, ggx, view, v, q.dump_frame == "z-up");
    r.sampler = q.dump;
    record_validation(r, q, d.units, seconds_since(clock), m);
  } catch (const Cancelled&) {
    m.partial = true;
  } catch (const SampleFileError& e) {
    throw dump_error(q, e);
  } catch (const InsufficientData& e) {
    throw dump_error(q, e);
  }
}

// One validation at the planned sample count (the chi-square power rule: no pilot, no rounds). Cancelled:
// nothing is kept (the validator has no partial result), the measurement runs again on resumption.
void run_validation(const ExperimentSpec& spec, std::uint64_t seed, std::size_t index, const RunOptions& o,
                    MeasurementResult& m) {
  const Decision& d = m.decision;
  const SpecQuantity& q = spec.quantities[d.quantity];
  if (!q.dump.empty()) return run_dump_validation(q, spec.material(q.material), o, m);
  const SamplerInfo* sampler = find_sampler(q.sampler);
  if (sampler == nullptr) throw std::invalid_argument(fmt::format("{}.sampler: unknown sampler '{}'", q.key, q.sampler));
  const ValidationOptions v = validation_request(q, first_units(d, o), round_seed(seed, index, 0), o.run);
  m.rounds.clear();
  m.partial = false;
  const auto clock = std::chrono::steady_clock::now();
  ValidationReport r;
  try {
    r = split_validation({o.ranks, o.stored}, index, *sampler, GGX<double>(d.alpha.first, d.alpha.second),
                         direction_from_degrees(d.view.theta_deg, d.view.phi_deg), v);
  } catch (const Cancelled&) {
    m.partial = true;
    return;
  }
  record_validation(r, q, r.samples, seconds_since(clock), m);
}

std::string error_measure(const SpecQuantity& q, const Decision& d) {
  if (q.kind == QuantityKind::masking && d.model.model == Model::analytic) return "none: Smith's closed forms are exact";
  if (q.kind == QuantityKind::masking)
    return fmt::format("the largest standard error of the measured {}{}", to_string(q.masking),
                       q.masking.conditional ? " (every bin of <v, m> and of height)" : "");
  if (q.kind == QuantityKind::scattering && d.model.model == Model::analytic)
    return "the cubature's summed error estimate over the order-1 albedo (to first order a bound on the lobe's TV error)";
  if (q.kind == QuantityKind::scattering)
    return fmt::format("the TV the lobes resolve: the largest per-order TV noise floor of the orders carrying at least "
                       "the target's share of the albedo, over {}", kNoiseShare);
  if (q.kind == QuantityKind::validation && is_analytic_dump(q, d))
    return fmt::format("the smallest TV deviation detected with power {} at level {} by the dump's rows{}", q.power,
                       q.significance, q.target > 0 ? "" : " (no detect_tv asked: the target is what they detect)");
  if (q.kind == QuantityKind::validation)
    return fmt::format("the smallest TV deviation detected with power {} at level {} by the samples run", q.power,
                       q.significance);
  if (q.kind == QuantityKind::vndf)
    return fmt::format("the TV the histogram resolves: its TV noise floor (expected TV of an exact sampler, largest "
                       "binning) over {}", kNoiseShare);
  return fmt::format("the worst relative {} of {} over the cells and E_avg",
                     d.model.model == Model::analytic ? "quadrature error estimate" : "standard error",
                     albedo_target_text(q));
}

// A measurement afresh, or continued from `previous` (an interrupted run's); a finished one is kept.
MeasurementResult run_decision(const ExperimentSpec& spec, const Decision& d, std::size_t index, std::uint64_t seed,
                               const RunOptions& o, SurfaceCache& surfaces, const MeasurementResult* previous) {
  if (previous != nullptr && (!previous->partial || !d.runnable)) return *previous;
  MeasurementResult m = previous != nullptr ? *previous : MeasurementResult{};
  m.decision = d;
  const SpecQuantity& q = spec.quantities[d.quantity];
  const bool vndf = q.kind == QuantityKind::vndf;
  const bool analytic = d.model.model == Model::analytic;
  // As the spec asks it: every achieved error is in its unit (a histogram's: resolved_tv). A dump without
  // detect_tv: what the plan's count of its rows detects.
  m.target = q.target > 0 || !is_analytic_dump(q, d) ? q.target : dump_detected_tv(q, d.units);
  m.error_measure = error_measure(q, d);
  if (!d.runnable) return m;
  m.ran = true;
  const auto start = std::chrono::steady_clock::now();
  if (q.kind == QuantityKind::masking)
    run_masking(spec, index, masking_surface_seed(seed, d.realisation), round_seed(seed, index, 0), first_units(d, o), o,
                surfaces, m);
  else if (q.kind == QuantityKind::albedo && !analytic) run_sampled_albedo(spec, seed, index, o, surfaces, m);
  else if (d.model.model == Model::heightfield) run_heightfield(spec, seed, index, o, surfaces, m);
  else if (vndf) run_vndf(spec, seed, index, o, m);
  else if (q.kind == QuantityKind::validation) run_validation(spec, seed, index, o, m);
  else if (q.kind == QuantityKind::scattering && analytic) run_analytic_scattering(spec, o, m);
  else if (q.kind == QuantityKind::scattering) run_scattering(spec, seed, index, o, m);
  else run_analytic_albedo(spec, o, m);
  m.seconds += seconds_since(start);
  return m;
}

}  // namespace

Estimate pool_rounds(const std::vector<Estimate>& rounds, const std::vector<std::uint64_t>& units) {
  if (rounds.size() != units.size() || rounds.empty()) throw std::invalid_argument("pool_rounds: sizes differ or none");
  double total = 0, weighted = 0, variance = 0;
  for (std::size_t r = 0; r < rounds.size(); ++r) {
    const double n = double(units[r]);
    total += n;
    weighted += n * rounds[r].value;
    variance += n * n * rounds[r].standard_error * rounds[r].standard_error;
  }
  if (!(total > 0)) throw std::invalid_argument("pool_rounds: no units");
  return {weighted / total, std::sqrt(variance) / total};
}

std::vector<RoundTask> first_split_rounds(const ExperimentSpec& spec, const ExperimentPlan& plan, std::uint64_t seed) {
  std::vector<RoundTask> tasks;
  const RunOptions planned;  // the first round at the planned cost
  for (std::size_t i = 0; i < plan.decisions.size(); ++i) {
    const Decision& d = plan.decisions[i];
    if (!d.runnable || !is_shared_by_ranks(spec, d)) continue;
    const QuantityKind kind = spec.quantities[d.quantity].kind;
    const bool vndf = kind == QuantityKind::vndf;  // capped as next_round caps them
    const bool tile_rays = kind == QuantityKind::validation && d.model.model == Model::heightfield;  // its one round
    std::uint64_t units = std::min(first_units(d, planned), vndf ? kMaxRays : std::numeric_limits<std::uint64_t>::max());
    const std::uint64_t block = vndf || tile_rays                    ? kRaysPerBlock
                                : kind == QuantityKind::validation ? kSampleBlock
                                : kind == QuantityKind::masking    ? kSamplesPerBlock
                                                                   : kPathsPerBlock;
    const BlockRange blocks = kind == QuantityKind::albedo ? BlockRange{0, albedo_round_cells(spec, d)}  // its cells
                                                           : BlockRange{0, units / block + (units % block != 0)};
    if (kind == QuantityKind::masking) units = kMaskingRunSamples;  // its rounds are block ranges of one run
    tasks.push_back({i, units, tile_rays ? validation_rays_seed(seed, i) : round_seed(seed, i, 0), blocks,
                     kind == QuantityKind::masking ? masking_surface_seed(seed, d.realisation) : 0});
  }
  return tasks;
}

ExperimentResults run_experiment(const ExperimentSpec& spec, const ExperimentPlan& plan, const RunOptions& options) {
  ExperimentResults results;
  SurfaceCache memory;  // without the caller's cache: surfaces for this run only
  SurfaceCache& surfaces = options.surfaces != nullptr ? *options.surfaces : memory;
  const std::uint64_t seed = options.seed != 0 ? options.seed : spec.seed;
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < plan.decisions.size(); ++i) {
    if (options.run.cancelled() || results.partial) {  // partial: a rank's part was cancelled (split rounds)
      results.partial = true;
      break;
    }
    const MeasurementResult* previous =
        options.resume != nullptr && i < options.resume->measurements.size() ? &options.resume->measurements[i] : nullptr;
    results.measurements.push_back(run_decision(spec, plan.decisions[i], i, seed, options, surfaces, previous));
    results.partial = results.partial || results.measurements.back().partial;
    if (options.on_measurement) options.on_measurement(results.measurements.back());
  }
  results.seconds = seconds_since(start) + (options.resume != nullptr ? options.resume->seconds : 0);
  return results;
}

}  // namespace microsim::experiment
