// experiment: the albedo kind (measurement.h): a table E(alpha, mu), measured by measure/albedo.h (the table,
// its cells by block range, their parts, the pilots' measures); this file is its spec keys, plan, rounds and
// report section. Sampled (the Smith walk, or paths on the plan's tiles): rounds of tables, each from its own
// seed, pooled cell by cell (pool_rounds); the worst relative SE of the quantities the target applies to
// decides. A round's blocks are the table's cells: ranks and shards compute ranges of them, whose parts
// (albedo_part_json, as `microsim albedo --shard` writes) are joined in block order. A round cut short is run
// again whole on resumption (its completed rows are not kept). Analytic: the quadrature at the planned
// tolerance, again 100 times tighter while an error estimate exceeds the target (deterministic: resumed, run
// again).
#include "experiment/plan_kinds.h"
#include "experiment/measurement.h"
#include "stats/curve_figure.h"
#include "experiment/report_html.h"
#include "experiment/measures.h"
#include "experiment/surface_albedo.h"
#include "measure/albedo.h"

#include "core/wall_clock.h"
#include "scatter/albedo_table_io.h"

#include <fmt/core.h>

#include <chrono>
#include <cmath>
#include <limits>

namespace microsim::experiment {
// ---- its parts and split rounds (parts.h, split_rounds.h) ----------------------------------------------------

namespace {

using nlohmann::json;

// A rank's cells as the part `microsim albedo --shard` writes (measure/albedo.h albedo_part_json; its time 0:
// the round's is the root's), in the round's part.
std::string albedo_part(const RoundTask& task, const AlbedoTableRequest& request, const BlockRange& cells,
                        const std::optional<AlbedoCells>& estimates) {
  if (!estimates) return cancelled_part(task, cells);
  return round_part(task, cells, false, albedo_part_json(request, cells, *estimates, 0));
}

// The parts from `first` on, in rank order, after `cells` (rank 0's, or none), read as `microsim merge` reads
// them (read_albedo_part): the whole table, or a partial one (no row) when a part was cancelled.
AlbedoTable combine_albedo_parts(const AlbedoTableRequest& request, AlbedoCells cells,
                                 const std::vector<std::string>& parts, const RoundTask& task, int first,
                                 double seconds) {
  const bool complete = add_parts(parts, task, first, [&](const json& s, const BlockRange& blocks, int) {
    const AlbedoPart part = read_albedo_part(s);
    if (part.provenance.blocks != blocks) throw std::invalid_argument("its cells are not the part's blocks");
    cells.insert(cells.end(), part.cells.begin(), part.cells.end());
  });
  return albedo_table_of_cells(request, complete ? std::optional(std::move(cells)) : std::nullopt, seconds);
}

// The table of a sampled request (a walk's, or on tiles) from `cells`, its cells split: albedo_table's, bit for
// bit; partial (no row) when a part was cancelled.
AlbedoTable split_albedo_round(const RoundSplit& split, std::size_t measurement, const AlbedoTableRequest& request,
                               const AlbedoCellsOf& cells) {
  const auto start = std::chrono::steady_clock::now();
  const BlockRange round{0, albedo_cell_count(request)};
  const RoundTask task{measurement, request.paths, request.seed, round};
  const bool stored = stored_parts(split.stored, task) != nullptr;  // its start: no cell (no tile acquired)
  using Cells = std::optional<AlbedoCells>;
  return split_round<Cells, AlbedoTable>(
      split, task,
      [&](const std::optional<BlockRange>& mine) -> Cells {
        return stored ? Cells(AlbedoCells{}) : cells(request, mine ? *mine : round);
      },
      [&](const Cells& own, const BlockRange& mine) { return albedo_part(task, request, mine, own); },
      [&](Cells own, const std::vector<std::string>& parts, int first) {
        if (!own) return albedo_table_of_cells(request, std::nullopt, 0);
        return combine_albedo_parts(request, std::move(*own), parts, task, first, seconds_since(start));
      });
}

// The cells of an albedo decision's requests: the walk's, or those on the tiles of its surface plan, from
// `surfaces` (which must outlive the function).
AlbedoCellsOf albedo_cells_of(const Decision& decision, SurfaceCache& surfaces) {
  if (decision.model.model != Model::heightfield) return walk_albedo_cells;
  return [plan = decision.surface, &surfaces](const AlbedoTableRequest& request, const BlockRange& cells) {
    return surface_albedo_cells_of(request, cells, plan, surfaces);
  };
}

// The cells of a sampled albedo table's round: alphas x mus (its blocks, for the split and the shards).
std::uint64_t albedo_round_cells(const ExperimentSpec& spec, const Decision& decision) {
  const SpecQuantity& q = spec.quantities[decision.quantity];
  return spec.material(q.material).alphas.size() * std::uint64_t(q.mus);
}

// The albedos a target applies to: orders single, the single-scattering albedos (E1, E1_R, E1_T); all orders,
// every albedo the table holds, not the unfinished or lost weight (measure/albedo.h worst_relative_albedo_error).
std::string_view albedo_target_prefix(const SpecQuantity& quantity) { return quantity.orders == Orders::single ? "E1" : "E"; }
std::string albedo_target_text(const SpecQuantity& quantity) { return std::string(albedo_target_prefix(quantity)) + "*"; }
double worst_relative_error(const AlbedoTable& table, const SpecQuantity& quantity) {
  return worst_relative_albedo_error(table, albedo_target_prefix(quantity));
}

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
    const AlbedoTableRequest request = sampled_albedo_request(spec_, decision_, task.units, task.seed, run);
    return albedo_part(task, request, mine, albedo_cells_of(decision_, surfaces)(request, mine));
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
      const AlbedoTable t =
          measure_albedo_table(albedo_request(spec_, quantity_, Model::analytic, 1, 0, tolerance, 1, c.options.run));
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


// ---- its plan ----------------------------------------------------------------------------------------------

// The order-cap pilot on the roughest row of an albedo table, every mu (measure/albedo.h
// albedo_unfinished_share). `cells`: the walk's, or on tiles.
CapPilot table_cap_pilot(AlbedoTableRequest row, const AlbedoCellsOf& cells) {
  return [row, cells](int cap) {
    AlbedoTableRequest r = row;
    r.max_order = cap;
    const AlbedoTable t = measure_albedo_cells_table(r, cells);
    if (t.partial) throw Cancelled("plan: order-cap pilot");
    const AlbedoUnfinishedShare worst = albedo_unfinished_share(t);
    return CapProbe{cap, worst.share, worst.share_se};
  };
}

void plan_analytic_albedo(const ExperimentSpec& spec, const SpecQuantity& q, const PlanOptions& o, Decision& d) {
  // The quadrature's error estimate per cell, absolute: 1e-3 of the relative target keeps it below the target
  // for every E >= 1e-3 (a GGX mirror's E1 is above 0.05 on the table's range).
  d.tolerance = std::clamp(1e-3 * q.target, 1e-13, 1e-2);
  d.count_reason = fmt::format("deterministic: quadrature to {:.0e} absolute per cell (1e-3 x target); rerun "
                               "tighter if an error estimate exceeds the target", d.tolerance);
  AlbedoTableRequest pilot = albedo_request(spec, q, Model::analytic, 1, 0, d.tolerance, 1, o.run);
  const std::size_t rows = pilot.alphas.size();
  pilot.alphas = {pilot.alphas.front()};
  const AlbedoTable t = measure_albedo_table(pilot);
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
  const AlbedoTable t = measure_albedo_cells_table(
      sampled_albedo_request(spec, d, o.pilot_paths, derived_seed(seed, kTablePilot, d.quantity), o.run), cells);
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

}  // namespace

static void plan_albedo_quantity(const ExperimentSpec& spec, std::size_t index, const PlanOptions& o, SurfaceCache& cache,
                                 std::vector<Decision>& out) {
  out.push_back(plan_albedo(spec, index, o, cache));
}

static std::unique_ptr<Measurement> make_albedo_measurement(const ExperimentSpec& spec, const Decision& decision) {
  if (decision.model.model == Model::analytic) return std::make_unique<AnalyticAlbedo>(spec, decision);
  return std::make_unique<SampledAlbedo>(spec, decision);
}

// ---- its model --------------------------------------------------------------------------------------------------

static ModelChoice albedo_model(const SpecQuantity& q, const SpecMaterial& m) {
  if (q.surface.kind != SurfaceChoice::Kind::automatic) return explicit_surface_choice(q);
  return smith_orders_choice(q, m.facet.kind() == MaterialKind::conductor
                                    ? "; a conductor's table is the mirror's (Kulla & Conty 2017: E(mu) for F = 1, the "
                                      "Fresnel enters through F_avg)"
                                    : "");
}

// ---- its spec keys ---------------------------------------------------------------------------------------------

namespace {

void check_albedo_material(const SpecTable& t, const SpecMaterial& m, bool inside) {
  for (std::size_t i = 0; i < m.alphas.size(); ++i) {
    const auto [ax, ay] = m.alphas[i];
    if (ax != ay) t.fail("material", fmt::format("material {}: an albedo table is isotropic (alpha pair {}, {})", quote_excerpt(m.name), ax, ay));
    if (ax < kMinAlbedoAlpha || ax > kMaxAlbedoAlpha)
      t.fail("material", fmt::format("material {}: alpha {} outside an albedo table's [{}, {}]", quote_excerpt(m.name), ax,
                                     kMinAlbedoAlpha, kMaxAlbedoAlpha));
    if (i > 0 && !(ax > m.alphas[i - 1].first))
      t.fail("material", fmt::format("material {}: an albedo table's alphas must increase ({} after {})", quote_excerpt(m.name), ax,
                                     m.alphas[i - 1].first));
  }
  if (inside && !m.facet.transmits()) t.fail("inside", fmt::format("light from inside needs a dielectric ({} is opaque)", quote_excerpt(m.name)));
}

void read_albedo_spec(const SpecTable& t, SpecQuantity& q, const SpecMaterial& m, const std::filesystem::path&) {
  q.target = read_target(t, "target_relative_error", 0.5, "a relative error below 0.5");
  q.orders = read_orders(t);
  q.mus = int(t.integer("mus", 16, kMinAlbedoMus, kMaxAlbedoMus));
  q.inside = t.boolean("inside", false);
  check_albedo_material(t, m, q.inside);
  read_walk_kernel(t, q, m);
}

}  // namespace

const KindSpec albedo_spec{"orders target_relative_error mus inside walk_kernel", read_albedo_spec};

// ---- its report section (report_html.h) -----------------------------------------------------------------------

namespace html {
namespace {

// The rows of one albedo quantity: E(mu) +- error per alpha, then E_avg +- error.
std::string albedo_quantity_table(const json& values, const json& q) {
  std::vector<std::string> header{"alpha"};
  for (const json& mu : member(values, "mus")) header.push_back("mu " + report_number(mu));
  header.push_back("E_avg");
  std::string body;
  const json& alphas = member(values, "alphas");
  for (std::size_t a = 0; a < alphas.size(); ++a) {
    std::vector<std::string> cells{report_number(alphas[a])};
    for (std::size_t k = 0; k < member(q, "value")[a].size(); ++k)
      cells.push_back(report_number(q["value"][a][k]) + " &plusmn; " + report_number(member(q, "error")[a][k]));
    cells.push_back("<b>" + report_number(member(q, "average")[a]) + "</b> &plusmn; " +
                    report_number(member(q, "average_error")[a]));
    body += row(cells);
  }
  return table(header, body);
}

std::string albedo_quantity_figure(const json& values, const std::string& name, const json& q) {
  std::vector<Curve> curves;
  const json& alphas = member(values, "alphas");
  for (std::size_t a = 0; a < alphas.size(); ++a)
    curves.push_back({"alpha " + report_number(alphas[a]), member(values, "mus").get<std::vector<double>>(),
                      member(q, "value")[a].get<std::vector<double>>(), member(q, "error")[a].get<std::vector<double>>()});
  if (curves.empty()) return "";
  const std::string subtitle = fmt::format("{} ({}), error bars: {}", text_of(member(values, "model")),
                                           text_of(member(values, "material")), text_of(member(values, "error")));
  return "<figure>" + curve_figure_svg(name + "(mu) per alpha", subtitle, {"mu = cos theta_i", name}, curves) +
         "</figure>\n";
}

std::string albedo_values(const json& values) {
  std::string out = fmt::format("<p>{} {}, {} side; error: {}.</p>\n", esc(text_of(member(values, "model"))),
                                esc(text_of(member(values, "material"))), esc(text_of(member(values, "side"))),
                                esc(text_of(member(values, "error"))));
  for (const json& name : member(values, "quantity_names")) {
    const std::string n = name.get<std::string>();
    const json& q = member(member(values, "quantities"), n.c_str());
    out += fmt::format("<h4>{}</h4>\n", esc(n)) + albedo_quantity_table(values, q);
    if (n != "unfinished" && n != "lost") out += albedo_quantity_figure(values, n, q);
  }
  return out;
}

}  // namespace
}  // namespace html

static std::string albedo_report(const nlohmann::json& values, std::size_t index, const ReportHistograms&, const ReportScatters&,
                                 const std::string&) {
  if (!values.contains("quantity_names")) return "";
  return html::albedo_values(values) + fmt::format("<p>Table: <a href=\"albedo-{0}.csv\">albedo-{0}.csv</a>.</p>\n", index);
}

// ---- its entry in the registry (measurement_registry.cpp) -------------------------------------------------

extern const MeasurementKind albedo_kind{"albedo", &albedo_spec, false, albedo_model, plan_albedo_quantity,
                                         make_albedo_measurement, albedo_report, nullptr, nullptr};

}  // namespace microsim::experiment
