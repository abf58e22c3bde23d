// experiment: the albedo kind (measurement.h): a table E(alpha, mu). Sampled (the Smith walk, or paths on the
// plan's tiles): rounds of tables, each from its own seed, pooled cell by cell (pool_rounds); the worst
// relative SE of the quantities the target applies to (measures.h, albedo_target_applies) decides. A round's
// blocks are the table's cells (row-major, each cell its own walk from its own seed): ranks and shards compute
// shards of the cells, joined in order (albedo_table_from_cells). A round cut short is run again whole on
// resumption (its completed rows are not kept). Analytic: the quadrature at the planned tolerance, again 100
// times tighter while an error estimate exceeds the target (deterministic: resumed, run again).
#include "experiment/measurement.h"
#include "experiment/measures.h"
#include "experiment/surface_albedo.h"

#include "scatter/albedo_table_io.h"

#include <fmt/core.h>

namespace microsim::experiment {
namespace {

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

class AlbedoMeasurement : public Measurement {
public:
  using Measurement::Measurement;
  std::string error_measure() const override {
    return fmt::format("the worst relative {} of {} over the cells and E_avg",
                       decision_.model.model == Model::analytic ? "quadrature error estimate" : "standard error",
                       albedo_target_text(quantity_));
  }
};

// The walk's table, or on the decision's tiles (albedo_cells_of), in rounds until its target is met.
class SampledAlbedo final : public AlbedoMeasurement {
public:
  using AlbedoMeasurement::AlbedoMeasurement;
  bool split() const override { return true; }
  RoundTask first_round(std::size_t index, std::uint64_t seed) const override {
    return {index, first_units(decision_, 1), round_seed(seed, index, 0), BlockRange{0, albedo_round_cells(spec_, decision_)}};
  }
  std::string part(const RoundTask& task, const BlockRange& mine, const RunControl& run,
                   SurfaceCache& surfaces) const override {
    return albedo_part(mine, albedo_cells_of(decision_, surfaces)(
                                 sampled_albedo_request(spec_, decision_, task.units, task.seed, run), mine));
  }
  void run(const RoundContext& c, MeasurementResult& m) const override {
    const RunControl& run = c.options.run;
    const AlbedoCellsOf cells = albedo_cells_of(decision_, c.surfaces);
    std::vector<AlbedoTable> tables;  // resumed: the completed rounds' tables
    std::vector<std::uint64_t> units;
    for (std::size_t r = 0; r < m.round_tables.size(); ++r) {
      const AlbedoTableRequest request = sampled_albedo_request(spec_, decision_, m.rounds[r].units, m.rounds[r].seed, run);
      tables.push_back(albedo_table_from_json(m.round_tables[r], request));
      units.push_back(m.rounds[r].units);
    }
    m.partial = false;
    std::uint64_t n = tables.empty() ? first_units(decision_, c.options.cost_factor)
                                     : next_round_units(m.units, m.achieved, m.target);
    for (int r = int(tables.size()); r < c.options.max_rounds && n > 0; ++r) {
      const std::uint64_t s = c.round_seed(r);
      AlbedoTable t = split_albedo_round(c.split(), c.index, sampled_albedo_request(spec_, decision_, n, s, run), cells);
      if (t.partial) {  // a round cut short is run again whole on resumption
        m.partial = true;
        break;
      }
      m.round_tables.push_back(albedo_table_json(t));
      tables.push_back(std::move(t));
      units.push_back(n);
      const AlbedoTable pooled = pool_tables(tables, units);
      m.achieved = worst_relative_error(pooled, quantity_);
      m.rounds.push_back({n, n, 0, false, s, 0, tables.back().seconds, m.achieved});
      m.units += n;
      m.rays += n * pooled.alphas.size() * pooled.mus.size();
      record_albedo(m, pooled);
      n = next_round_units(m.units, m.achieved, m.target);
    }
    m.met = !tables.empty() && m.achieved <= m.target;
  }
};

class AnalyticAlbedo final : public AlbedoMeasurement {
public:
  using AlbedoMeasurement::AlbedoMeasurement;
  void run(const RoundContext& c, MeasurementResult& m) const override {
    double tolerance = decision_.tolerance;
    m.rounds.clear();  // resumed: deterministic and cheap, run again
    m.partial = false;
    for (int r = 0; r < c.options.max_rounds && !m.met && tolerance >= 1e-13; ++r, tolerance /= 100) {
      const AlbedoTable t = albedo_table(albedo_request(spec_, quantity_, Model::analytic, 1, 0, tolerance, 1, c.options.run));
      if (t.partial) {
        m.partial = true;
        break;
      }
      m.achieved = worst_relative_error(t, quantity_);
      m.rounds.push_back({0, 0, 0, false, 0, tolerance, t.seconds, m.achieved});
      m.met = m.achieved <= m.target;
      record_albedo(m, t);
    }
  }
};

}  // namespace

std::unique_ptr<Measurement> make_albedo_measurement(const ExperimentSpec& spec, const Decision& decision) {
  if (decision.model.model == Model::analytic) return std::make_unique<AnalyticAlbedo>(spec, decision);
  return std::make_unique<SampledAlbedo>(spec, decision);
}

}  // namespace microsim::experiment
