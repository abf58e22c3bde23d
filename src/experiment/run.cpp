// experiment: run_experiment: the sequential rounds of each runnable decision (run.h).
#include "experiment/run.h"

#include "experiment/measures.h"
#include "core/parse.h"
#include "scatter/albedo_table_io.h"

#include <fmt/core.h>

#include <chrono>
#include <cmath>
#include <stdexcept>

namespace microsim::experiment {
namespace {

enum RunSeedPurpose : std::uint64_t { kRoundSeed = 16 };

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::uint64_t round_seed(std::uint64_t seed, std::size_t decision, int round) {
  return derived_seed(seed, kRoundSeed, std::uint64_t(decision) * 1024 + std::uint64_t(round));
}

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

void run_walk_albedo(const ExperimentSpec& spec, std::uint64_t seed, std::size_t index, const RunOptions& o,
                     MeasurementResult& m) {
  const Decision& d = m.decision;
  const SpecQuantity& q = spec.quantities[d.quantity];
  std::vector<AlbedoTable> tables;
  std::vector<std::uint64_t> units;
  std::uint64_t n = d.units;
  for (int r = 0; r < kMaxRounds && n > 0; ++r) {
    const std::uint64_t s = round_seed(seed, index, r);
    AlbedoTable t = albedo_table(albedo_request(spec, q, Model::smith_walk, n, d.order_cap, 0, s, o.run));
    if (t.partial) {
      m.partial = true;
      break;
    }
    tables.push_back(std::move(t));
    units.push_back(n);
    const AlbedoTable pooled = pool_tables(tables, units);
    m.achieved = worst_relative_error(pooled, q);
    m.rounds.push_back({n, s, 0, tables.back().seconds, m.achieved});
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
  for (int r = 0; r < kMaxRounds && !m.met && tolerance >= 1e-13; ++r, tolerance /= 100) {
    const AlbedoTable t = albedo_table(albedo_request(spec, q, Model::analytic, 1, 0, tolerance, 1, o.run));
    if (t.partial) {
      m.partial = true;
      break;
    }
    m.achieved = worst_relative_error(t, q);
    m.rounds.push_back({0, 0, tolerance, t.seconds, m.achieved});
    m.met = m.achieved <= m.target;
    record_albedo(m, t);
  }
}

// ---- vndf --------------------------------------------------------------------------------------------------

// Adds a round's exact counts to the sum (the first round gives the binnings and attributes).
void add_round(TracedHistogram& sum, std::vector<std::uint64_t>& unbinned, const EllipsoidVndf& round) {
  if (sum.binnings.empty()) {
    sum = round.histogram;
    unbinned = round.trace.unbinned;
    return;
  }
  for (std::size_t k = 0; k < sum.counts.size(); ++k)
    for (std::size_t i = 0; i < sum.counts[k].size(); ++i) sum.counts[k][i] += round.histogram.counts[k][i];
  for (std::size_t k = 0; k < unbinned.size(); ++k) unbinned[k] += round.trace.unbinned[k];
  sum.rays += round.histogram.rays;
  sum.hits += round.histogram.hits;
}

void record_vndf(MeasurementResult& m, const EllipsoidVndf& analysed, double hit_fraction) {
  m.values = {{"analysis", to_json(analysed.analysis)},
              {"rays", analysed.histogram.rays},
              {"hits", analysed.histogram.hits},
              {"expected_hit_fraction", hit_fraction},
              {"total_variation", vndf_total_variation(analysed)},
              {"noise_floor_tv", vndf_noise_floor(analysed)}};
}

void run_vndf(const ExperimentSpec& spec, std::uint64_t seed, std::size_t index, const RunOptions& o, MeasurementResult& m) {
  const Decision& d = m.decision;
  const EllipsoidTarget target(d.alpha.first, d.alpha.second, -1);
  TracedHistogram sum;
  std::vector<std::uint64_t> unbinned;
  std::uint64_t n = d.units;
  for (int r = 0; r < kMaxRounds && n > 0; ++r) {
    VndfRequest req;
    req.theta_deg = d.view.theta_deg;
    req.phi_deg = d.view.phi_deg;
    req.rays = std::min<std::uint64_t>(n, kMaxRays);
    req.seed = round_seed(seed, index, r);
    req.rows = spec.quantities[d.quantity].rows;
    req.run = o.run;
    const auto start = std::chrono::steady_clock::now();
    const EllipsoidVndf round = measure_ellipsoid_vndf(target, req);
    m.partial = round.trace.partial;  // cancelled: its completed blocks are a shorter run of that seed, kept
    if (round.histogram.rays == 0) break;
    add_round(sum, unbinned, round);
    // One round: its own analysis is the sum's (the reference's cubature is not paid twice).
    const EllipsoidVndf analysed = m.rounds.empty() ? round : analyse_ellipsoid_vndf(sum, unbinned);
    m.achieved = vndf_noise_floor(analysed);
    m.units += round.histogram.rays;
    m.rays += round.histogram.rays;
    m.rounds.push_back({round.histogram.rays, req.seed, 0, seconds_since(start), m.achieved});
    record_vndf(m, analysed, round.expected_hit_fraction);
    n = m.partial ? 0 : next_round_units(m.units, m.achieved, m.target);
  }
  m.met = !m.rounds.empty() && m.achieved <= m.target;
}

MeasurementResult run_decision(const ExperimentSpec& spec, const Decision& d, std::size_t index, std::uint64_t seed,
                               const RunOptions& o) {
  MeasurementResult m;
  m.decision = d;
  const SpecQuantity& q = spec.quantities[d.quantity];
  const bool vndf = q.kind == QuantityKind::vndf;
  m.target = vndf ? kNoiseShare * q.target : q.target;
  m.error_measure = vndf ? "the histogram's TV noise floor (expected TV of an exact sampler), largest binning"
                         : fmt::format("the worst relative {} of {} over the cells and E_avg",
                                       d.model.model == Model::analytic ? "quadrature error estimate" : "standard error",
                                       albedo_target_text(q));
  if (!d.runnable) return m;
  m.ran = true;
  const auto start = std::chrono::steady_clock::now();
  if (vndf) run_vndf(spec, seed, index, o, m);
  else if (d.model.model == Model::smith_walk) run_walk_albedo(spec, seed, index, o, m);
  else run_analytic_albedo(spec, o, m);
  m.seconds = seconds_since(start);
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

ExperimentResults run_experiment(const ExperimentSpec& spec, const ExperimentPlan& plan, const RunOptions& options) {
  ExperimentResults results;
  const std::uint64_t seed = options.seed != 0 ? options.seed : spec.seed;
  const auto start = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < plan.decisions.size(); ++i) {
    if (options.run.cancelled()) {
      results.partial = true;
      break;
    }
    results.measurements.push_back(run_decision(spec, plan.decisions[i], i, seed, options));
    results.partial = results.partial || results.measurements.back().partial;
    if (options.on_measurement) options.on_measurement(results.measurements.back());
  }
  results.seconds = seconds_since(start);
  return results;
}

}  // namespace microsim::experiment
