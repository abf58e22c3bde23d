#include "validate/stability_part.h"

#include <fmt/core.h>

#include <map>
#include <utility>

namespace microsim {

namespace {

constexpr const char* kProducer = "stability";
const PartReader kReader(kProducer);

using Count = std::uint64_t StabilityMetrics::*;
using Real = double StabilityMetrics::*;
using Text = std::string StabilityMetrics::*;

const std::pair<const char*, Count> kCounts[] = {
    {"evaluations", &StabilityMetrics::evaluations},
    {"empty_double", &StabilityMetrics::empty_double},
    {"empty_float", &StabilityMetrics::empty_float},
    {"empty_mismatch", &StabilityMetrics::empty_mismatch},
    {"non_finite_double", &StabilityMetrics::non_finite_double},
    {"non_finite_float", &StabilityMetrics::non_finite_float},
    {"negative", &StabilityMetrics::negative},
    {"claimed_unverifiable", &StabilityMetrics::claimed_unverifiable},
    {"claimed_unverifiable_interior", &StabilityMetrics::claimed_unverifiable_interior},
    {"zero_flips", &StabilityMetrics::zero_flips},
    {"zero_flips_interior", &StabilityMetrics::zero_flips_interior}};
const std::pair<const char*, Real> kReals[] = {
    {"norm_error_double", &StabilityMetrics::norm_error_double},
    {"norm_error_float", &StabilityMetrics::norm_error_float},
    {"angle_float_double", &StabilityMetrics::angle_float_double},
    {"rel_float_double", &StabilityMetrics::rel_float_double},
    {"cond_float_double", &StabilityMetrics::cond_float_double},
    {"rel_claimed", &StabilityMetrics::rel_claimed},
    {"cond_claimed", &StabilityMetrics::cond_claimed}};
const std::pair<const char*, Text> kConfigs[] = {
    {"worst_angle_config", &StabilityMetrics::worst_angle_config},
    {"worst_rel_config", &StabilityMetrics::worst_rel_config},
    {"worst_cond_config", &StabilityMetrics::worst_cond_config},
    {"worst_claimed_config", &StabilityMetrics::worst_claimed_config}};

nlohmann::json exact_reals(const std::vector<double>& values) {
  nlohmann::json a = nlohmann::json::array();
  for (const double v : values) a.push_back(exact_real_json(v));
  return a;
}

std::vector<double> exact_reals_from(const nlohmann::json& j, const char* key, const std::string& where) {
  const nlohmann::json& a = kReader.member(j, key, where);
  if (!a.is_array()) kReader.malformed(where + "/" + key, "is not an array");
  std::vector<double> values;
  for (std::size_t i = 0; i < a.size(); ++i) values.push_back(kReader.exact_real(a[i], fmt::format("{}/{}/{}", where, key, i)));
  return values;
}

nlohmann::json grid_json(const StabilityGrid& g) {
  std::vector<double> alphas;
  for (const auto& [ax, ay] : g.alphas) alphas.insert(alphas.end(), {ax, ay});
  return {{"alphas", exact_reals(alphas)},           {"thetas_deg", exact_reals(g.thetas_deg)},
          {"phis_deg", exact_reals(g.phis_deg)},     {"u_values", exact_reals(g.u_values)},
          {"random_u_per_view", g.random_u_per_view}};
}

StabilityGrid grid_from_json(const nlohmann::json& j, std::uint64_t seed) {
  const std::string w = "provenance/parameters/grid";
  StabilityGrid g;
  const std::vector<double> alphas = exact_reals_from(j, "alphas", w);
  if (alphas.size() % 2 != 0) kReader.malformed(w + "/alphas", "is not a list of pairs");
  for (std::size_t i = 0; i < alphas.size(); i += 2) g.alphas.emplace_back(alphas[i], alphas[i + 1]);
  g.thetas_deg = exact_reals_from(j, "thetas_deg", w);
  g.phis_deg = exact_reals_from(j, "phis_deg", w);
  g.u_values = exact_reals_from(j, "u_values", w);
  g.random_u_per_view = int(kReader.count(j, "random_u_per_view", w));
  g.seed = seed;
  return g;
}

// The subjects of the sweep `microsim stability` runs, in the table's order.
nlohmann::json subjects_json(const std::vector<StabilityMetrics>& rows) {
  nlohmann::json names = nlohmann::json::array();
  for (std::size_t k = 0; k < rows.size(); k += kStabilityRegimeCount) names.push_back(rows[k].subject);
  return names;
}

nlohmann::json part_row_json(const StabilityMetrics& r) {
  nlohmann::json j = {{"subject", r.subject}, {"regime", stability_regime_name(r.regime)}};
  for (const auto& [key, count] : kCounts) j[key] = r.*count;
  for (const auto& [key, real] : kReals) j[key] = exact_real_json(r.*real);
  for (const auto& [key, text] : kConfigs) j[key] = r.*text;
  return j;
}

// The index of a row's (subject, regime) in the table's rows.
using RowIndex = std::map<std::pair<std::string, std::string>, std::size_t>;
RowIndex row_index(const std::vector<StabilityMetrics>& rows) {
  RowIndex index;
  for (std::size_t k = 0; k < rows.size(); ++k) index[{rows[k].subject, stability_regime_name(rows[k].regime)}] = k;
  return index;
}

StabilityMetrics row_from_json(const nlohmann::json& j, const std::vector<StabilityMetrics>& skeleton,
                               const RowIndex& index, const std::string& where) {
  const auto it = index.find({kReader.text(j, "subject", where), kReader.text(j, "regime", where)});
  if (it == index.end()) kReader.malformed(where, "is no (subject, regime) of this build's sweep");
  StabilityMetrics r = skeleton[it->second];
  for (const auto& [key, count] : kCounts) r.*count = kReader.count(j, key, where);
  for (const auto& [key, real] : kReals) r.*real = kReader.exact_real(j, key, where);
  for (const auto& [key, text] : kConfigs) r.*text = kReader.text(j, key, where);
  return r;
}

}  // namespace

nlohmann::json stability_part_json(const StabilityTable& table) {
  const std::vector<StabilityMetrics> skeleton = stability_rows(sampler_registry(), true);
  const nlohmann::json parameters = {{"grid", grid_json(table.grid)}, {"subjects", subjects_json(skeleton)}};
  const Provenance p{kProducer, parameters.dump(), table.grid.seed, table.total_blocks, table.blocks};
  nlohmann::json rows = nlohmann::json::array();
  for (const StabilityMetrics& r : table.rows) rows.push_back(part_row_json(r));
  return {{"provenance", provenance_json(p, parameters)}, {"rows", rows}};
}

bool is_stability_part(const nlohmann::json& report) { return producer_of(report) == kProducer; }

StabilityTable read_stability_part(const nlohmann::json& report) {
  nlohmann::json parameters;
  const Provenance p = kReader.provenance(report, parameters);
  const std::vector<StabilityMetrics> skeleton = stability_rows(sampler_registry(), true);
  if (kReader.member(parameters, "subjects", "provenance/parameters") != subjects_json(skeleton))
    kReader.malformed("provenance/parameters/subjects", "are not the samplers and functions of this build");
  StabilityTable t;
  t.grid = grid_from_json(kReader.member(parameters, "grid", "provenance/parameters"), p.seed);
  if (p.total_blocks != stability_blocks(t.grid))
    kReader.malformed("provenance/total_blocks", fmt::format("is not the grid's {} blocks", stability_blocks(t.grid)));
  t.total_blocks = p.total_blocks;
  t.blocks = p.blocks;
  const RowIndex index = row_index(skeleton);
  const nlohmann::json& rows = kReader.member(report, "rows", "");
  if (!rows.is_array()) kReader.malformed("rows", "is not an array");
  for (std::size_t i = 0; i < rows.size(); ++i)
    t.rows.push_back(row_from_json(rows[i], skeleton, index, fmt::format("rows/{}", i)));
  return t;
}

StabilityTable merge_stability_parts(const std::vector<StabilityTable>& parts) {
  std::vector<Provenance> provenances;
  std::vector<nlohmann::json> parameters;
  for (const StabilityTable& t : parts) {
    const nlohmann::json part = stability_part_json(t)["provenance"];
    parameters.push_back(part["parameters"]);
    provenances.push_back({kProducer, parameters.back().dump(), t.grid.seed, t.total_blocks, t.blocks});
  }
  const std::vector<std::size_t> order = check_parts_of_one_run(provenances, parameters);
  std::vector<StabilityMetrics> rows = stability_rows(sampler_registry(), true);
  const RowIndex index = row_index(rows);
  for (const std::size_t i : order)
    for (const StabilityMetrics& r : parts[i].rows) merge_metrics(rows[index.at({r.subject, stability_regime_name(r.regime)})], r);
  StabilityTable merged;
  merged.grid = parts.front().grid;
  merged.total_blocks = parts.front().total_blocks;
  merged.blocks = {0, merged.total_blocks};
  for (StabilityMetrics& r : rows)
    if (r.evaluations > 0) merged.rows.push_back(std::move(r));
  return merged;
}

}  // namespace microsim
