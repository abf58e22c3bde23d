// measure: an energy-compensation table as one measurement (albedo.h).
#include "measure/albedo.h"

#include "core/ndf_kind.h"
#include "core/parse.h"
#include "core/wall_clock.h"

#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace microsim {

AlbedoTable measure_albedo_table(const AlbedoTableRequest& request, const AlbedoRowCallback& on_row) {
  return albedo_table(request, on_row);
}

// ---- a table read back ---------------------------------------------------------------------------------------

namespace {

const nlohmann::json& table_member(const nlohmann::json& j, const std::string& key) {
  if (!j.is_object() || !j.contains(key)) throw std::invalid_argument(fmt::format("albedo table JSON: no '{}'", key));
  return j.at(key);
}

std::vector<double> numbers_of(const nlohmann::json& j, const std::string& what) {
  if (!j.is_array()) throw std::invalid_argument(fmt::format("albedo table JSON: '{}' is not an array", what));
  std::vector<double> v;
  for (const nlohmann::json& x : j) {
    if (!x.is_number() && !x.is_null())
      throw std::invalid_argument(fmt::format("albedo table JSON: '{}' holds a non-number", what));
    v.push_back(x.is_null() ? std::numeric_limits<double>::quiet_NaN() : x.get<double>());
  }
  return v;
}

std::vector<Estimate> estimates_of(const nlohmann::json& values, const nlohmann::json& errors, const std::string& what) {
  const std::vector<double> v = numbers_of(values, what), e = numbers_of(errors, what + " error");
  if (v.size() != e.size()) throw std::invalid_argument(fmt::format("albedo table JSON: '{}' sizes differ", what));
  std::vector<Estimate> out;
  for (std::size_t i = 0; i < v.size(); ++i) out.push_back({v[i], e[i]});
  return out;
}

AlbedoQuantity quantity_from_json(const std::string& name, const nlohmann::json& q) {
  AlbedoQuantity out{name, {}, estimates_of(table_member(q, "average"), table_member(q, "average_error"), name)};
  const nlohmann::json &values = table_member(q, "value"), &errors = table_member(q, "error");
  if (!values.is_array() || !errors.is_array() || values.size() != errors.size())
    throw std::invalid_argument(fmt::format("albedo table JSON: '{}' rows differ", name));
  for (std::size_t a = 0; a < values.size(); ++a)
    for (const Estimate& e : estimates_of(values[a], errors[a], name)) out.cells.push_back(e);
  return out;
}

}  // namespace

AlbedoTable albedo_table_from_json(const nlohmann::json& j, const AlbedoTableRequest& request) {
  AlbedoTable t;
  t.request = request;
  t.alphas = numbers_of(table_member(j, "alphas"), "alphas");
  t.mus = numbers_of(table_member(j, "mus"), "mus");
  t.mu_weights = numbers_of(table_member(j, "mu_weights"), "mu_weights");
  t.row_seconds = numbers_of(table_member(j, "row_seconds"), "row_seconds");
  t.seconds = table_member(j, "seconds").get<double>();
  t.partial = table_member(j, "partial").get<bool>();
  for (const nlohmann::json& name : table_member(j, "quantity_names")) {
    const std::string n = name.get<std::string>();
    t.quantities.push_back(quantity_from_json(n, table_member(table_member(j, "quantities"), n)));
    if (t.quantities.back().cells.size() != t.alphas.size() * t.mus.size())
      throw std::invalid_argument(fmt::format("albedo table JSON: '{}' has {} cells, not alphas x mus", n,
                                              t.quantities.back().cells.size()));
  }
  return t;
}

// ---- a sampled table by its cells ---------------------------------------------------------------------------

std::uint64_t albedo_cell_count(const AlbedoTableRequest& request) {
  return request.alphas.size() * std::uint64_t(request.mus);
}

AlbedoTable albedo_table_of_cells(const AlbedoTableRequest& request, const std::optional<AlbedoCells>& cells,
                                  double seconds) {
  if (cells) return albedo_table_from_cells(request, *cells, seconds);
  AlbedoTable cancelled;  // no row: a round cut short is run again whole
  cancelled.request = request;
  cancelled.partial = true;
  return cancelled;
}

AlbedoTable measure_albedo_cells_table(const AlbedoTableRequest& request, const AlbedoCellsOf& cells_of) {
  const auto start = std::chrono::steady_clock::now();
  const std::optional<AlbedoCells> cells = cells_of(request, BlockRange{0, albedo_cell_count(request)});
  return albedo_table_of_cells(request, cells, seconds_since(start));
}

// ---- the part of a shard ---------------------------------------------------------------------------------------

namespace {

const PartReader kAlbedoReader(kAlbedoPartProducer);

// Per cell, its estimates as [value, error], each exact_real_json.
nlohmann::json albedo_cells_json(const AlbedoCells& cells) {
  nlohmann::json out = nlohmann::json::array();
  for (const std::vector<Estimate>& cell : cells) {
    nlohmann::json values = nlohmann::json::array();
    for (const Estimate& e : cell) values.push_back({exact_real_json(e.value), exact_real_json(e.standard_error)});
    out.push_back(values);
  }
  return out;
}

// Appends `count` cells of that form (member `where`), each of `quantities` estimates, to `cells`.
void append_albedo_cells(AlbedoCells& cells, const nlohmann::json& sums, std::size_t count, std::size_t quantities,
                         const PartReader& reader, const std::string& where) {
  if (!sums.is_array() || sums.size() != count) reader.malformed(where, "is not one estimate list per cell");
  for (std::size_t c = 0; c < count; ++c) {
    const std::string at = fmt::format("{}/{}", where, c);
    if (!sums[c].is_array() || sums[c].size() != quantities) reader.malformed(at, "is not one estimate per quantity");
    std::vector<Estimate>& cell = cells.emplace_back();
    for (const nlohmann::json& e : sums[c]) {
      if (!e.is_array() || e.size() != 2) reader.malformed(at, "is not [value, error]");
      cell.push_back({reader.exact_real(e[0], at), reader.exact_real(e[1], at)});
    }
  }
}

// What defines the run besides its seed and blocks: every member of the request a cell depends on (counts
// unsigned, as a part read back from its text holds them).
nlohmann::json albedo_parameters(const AlbedoTableRequest& r) {
  nlohmann::json p{{"model", to_string(r.model)}, {"ndf", to_string(r.ndf)}, {"material", r.material.describe()},
                   {"inside", r.inside}, {"alphas", r.alphas}, {"mus", std::uint64_t(r.mus)}, {"paths", r.paths},
                   {"max_order", std::uint64_t(r.max_order)}};
  if (r.model == AlbedoModel::surface) p["resolution"] = std::uint64_t(r.resolution);
  // Only a lanes table names its kernel: the parts of scalar tables keep the form they had before the choice.
  if (r.walk_kernel != WalkKernel::scalar) p["walk_kernel"] = to_string(r.walk_kernel);
  // Its SIMD target too: parts walked on machines of other targets differ in their last bits and do not merge.
  if (r.walk_kernel == WalkKernel::lanes) p["walk_target"] = smith_walk_lanes_target();
  return p;
}

// The request of a part's parameters (and seed); HistogramMergeError for a malformed one.
AlbedoTableRequest request_of(const nlohmann::json& p, std::uint64_t seed) {
  const std::string where = "provenance/parameters";
  AlbedoTableRequest r;
  try {
    r.model = parse_albedo_model("model", kAlbedoReader.text(p, "model", where));
    r.ndf = parse_ndf_kind("ndf", kAlbedoReader.text(p, "ndf", where));
    r.material = parse_material("material", kAlbedoReader.text(p, "material", where));
    r.inside = kAlbedoReader.flag(p, "inside", where);
    r.alphas = kAlbedoReader.member(p, "alphas", where).get<std::vector<double>>();
    r.mus = int(kAlbedoReader.count(p, "mus", where));
    r.paths = kAlbedoReader.count(p, "paths", where);
    r.max_order = int(kAlbedoReader.count(p, "max_order", where));
    if (r.model == AlbedoModel::surface) r.resolution = int(kAlbedoReader.count(p, "resolution", where));
    if (p.contains("walk_kernel"))
      r.walk_kernel = parse_walk_kernel("walk_kernel", kAlbedoReader.text(p, "walk_kernel", where));
    r.seed = seed;
    AlbedoTableRequest checked = r;  // a surface's build parameters are its caller's (surface_albedo_cells)
    if (checked.model == AlbedoModel::surface) checked.model = AlbedoModel::smith_walk;
    check_albedo_request(checked);
  } catch (const HistogramMergeError&) {
    throw;
  } catch (const std::exception& e) {  // ParseError, a json type error, the request's check
    kAlbedoReader.malformed(where, e.what());
  }
  if (r.model == AlbedoModel::analytic) kAlbedoReader.malformed(where + "/model", "is not a sampled model");
  return r;
}

}  // namespace

nlohmann::json albedo_part_json(const AlbedoTableRequest& request, const BlockRange& blocks, const AlbedoCells& cells,
                                double seconds) {
  const Provenance provenance{kAlbedoPartProducer, "", request.seed, albedo_cell_count(request), blocks};
  return {{"provenance", provenance_json(provenance, albedo_parameters(request))},
          {"quantity_names", albedo_quantity_names(request.model, request.material)},
          {"cells", albedo_cells_json(cells)},
          {"seconds", seconds}};
}

std::optional<nlohmann::json> measure_albedo_part(const AlbedoTableRequest& request, const BlockRange& blocks) {
  const auto start = std::chrono::steady_clock::now();
  const std::optional<AlbedoCells> cells = walk_albedo_cells(request, blocks);
  if (!cells) return std::nullopt;
  return albedo_part_json(request, blocks, *cells, seconds_since(start));
}

AlbedoPart read_albedo_part(const nlohmann::json& part) {
  AlbedoPart p;
  p.provenance = kAlbedoReader.provenance(part, p.parameters);
  p.request = request_of(p.parameters, p.provenance.seed);
  if (p.provenance.total_blocks != albedo_cell_count(p.request))
    kAlbedoReader.malformed("provenance/total_blocks", "is not the table's alphas x mus");
  const std::size_t quantities = albedo_quantity_names(p.request.model, p.request.material).size();
  append_albedo_cells(p.cells, kAlbedoReader.member(part, "cells", ""), std::size_t(p.provenance.blocks.size()),
                      quantities, kAlbedoReader, "cells");
  p.seconds = kAlbedoReader.real(part, "seconds", "");
  return p;
}

AlbedoTable merge_albedo_parts(const std::vector<AlbedoPart>& parts) {
  AlbedoCells cells;
  double seconds = 0;
  for (const std::size_t i : check_parts_of_one_run(parts)) {
    cells.insert(cells.end(), parts[i].cells.begin(), parts[i].cells.end());
    seconds += parts[i].seconds;
  }
  return albedo_table_from_cells(parts.front().request, cells, seconds);
}

// ---- what a table achieved, and the pilots -------------------------------------------------------------------

namespace {

double relative_error(const Estimate& e) {
  if (e.standard_error == 0) return 0;
  return e.value != 0 ? e.standard_error / std::abs(e.value) : std::numeric_limits<double>::infinity();
}

}  // namespace

double worst_relative_albedo_error(const AlbedoTable& table, std::string_view prefix) {
  double worst = 0;
  for (const AlbedoQuantity& q : table.quantities) {
    if (!q.name.starts_with(prefix)) continue;
    for (const Estimate& e : q.cells) worst = std::max(worst, relative_error(e));
    for (const Estimate& e : q.average) worst = std::max(worst, relative_error(e));
  }
  return worst;
}

AlbedoUnfinishedShare albedo_unfinished_share(const AlbedoTable& t) {
  AlbedoUnfinishedShare worst;
  for (std::size_t m = 0; m < t.mus.size(); ++m) {
    Estimate u = t.cell("unfinished", 0, m);
    if (u.value == 0) u.standard_error = 1.5 / double(t.request.paths);  // 3 / n as two standard errors
    const double e = std::max(t.cell("E", 0, m).value, 1e-300);
    if ((u.value + 2 * u.standard_error) / e > worst.share + 2 * worst.share_se) worst = {u.value / e, u.standard_error / e};
  }
  return worst;
}

}  // namespace microsim
