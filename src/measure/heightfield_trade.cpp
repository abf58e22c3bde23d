// measure: the heightfield trade table and the surface size rule (heightfield_trade.h).
#include "measure/heightfield_trade.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace microsim {

extern const char* const kHeightfieldTradeJson;  // generated from docs/data/heightfield-trade.json (CMake)

namespace {

template <class T> T trade_member(const nlohmann::json& j, const char* key, const std::string& where) {
  if (!j.is_object() || !j.contains(key))
    throw std::invalid_argument(fmt::format("heightfield trade table: {} has no '{}'", where, key));
  try {
    return j.at(key).get<T>();
  } catch (const nlohmann::json::exception&) {
    throw std::invalid_argument(fmt::format("heightfield trade table: {}.{} has the wrong type", where, key));
  }
}

TradeRow trade_row_from_json(const nlohmann::json& j, const std::string& where) {
  TradeRow r{trade_member<std::string>(j, "ndf_match", where), trade_member<int>(j, "resolution", where),
             trade_member<double>(j, "corr_cells", where), trade_member<double>(j, "bias_tv", where),
             trade_member<double>(j, "iid_noise_tv", where), trade_member<double>(j, "build_cpu_seconds", where)};
  if (r.ndf_match != "radial" && r.ndf_match != "joint")
    throw std::invalid_argument(fmt::format("heightfield trade table: {}.ndf_match '{}' is neither radial nor joint", where, r.ndf_match));
  if (r.resolution < 2 || !(r.corr_cells > 0) || !(r.bias_tv >= 0) || !(r.build_cpu_seconds >= 0))
    throw std::invalid_argument(fmt::format("heightfield trade table: {}: a size, bias or time out of range", where));
  return r;
}

double anisotropy_factor(double anisotropy) { return std::sqrt(std::max(1.0, anisotropy)); }

bool power_of_two(int n) { return n > 0 && (n & (n - 1)) == 0; }

std::string row_text(const TradeRow& r) {
  return fmt::format("{} {}^2, l {} cells ({} l per tile): NDF TV {} in the table's bins, {} for independent "
                     "triangles", r.ndf_match, r.resolution, r.corr_cells, r.tiles(), r.bias_tv, r.iid_noise_tv);
}

std::string anisotropy_text(double anisotropy) {
  return anisotropy > 1 ? fmt::format(" x sqrt({:.3g}) for the anisotropy (the tile holds that many times fewer "
                                      "independent patches; an extrapolation: the table is isotropic)", anisotropy)
                        : "";
}

// Why only wide tiles were considered ("" when every width was).
std::string wide_text(const TradeTable& table, const SizeRequest& request) {
  if (request.scattering && table.scattering_min_tiles > 0)
    return fmt::format("; per-order scattering: at least {} l per tile", table.scattering_min_tiles);
  if (request.theta_deg > table.grazing_theta_deg)
    return fmt::format("; theta {} > {}: at least {} l per tile", request.theta_deg, table.grazing_theta_deg,
                       table.grazing_min_tiles);
  return "";
}

// The rows a request may use: buildable sizes, wide enough for its view, cheapest build first.
std::vector<TradeRow> candidate_rows(const TradeTable& table, const SizeRequest& request) {
  std::vector<TradeRow> rows;
  const bool grazing = request.theta_deg > table.grazing_theta_deg;
  const double min_tiles = std::max(grazing ? table.grazing_min_tiles : 0, request.scattering ? table.scattering_min_tiles : 0);
  for (const TradeRow& r : table.rows)
    if (power_of_two(r.resolution) && r.resolution >= std::max(request.min_resolution, kMinSurfaceResolution) &&
        r.resolution <= kMaxSurfaceResolution && r.tiles() >= min_tiles)
      rows.push_back(r);
  std::stable_sort(rows.begin(), rows.end(),
                   [](const TradeRow& a, const TradeRow& b) { return a.build_cpu_seconds < b.build_cpu_seconds; });
  return rows;
}

}  // namespace

TradeTable trade_table_from_json(const nlohmann::json& document) {
  TradeTable t;
  t.source = trade_member<std::string>(document, "source", "the document");
  const auto rows = trade_member<nlohmann::json>(document, "rows", "the document");
  if (!rows.is_array() || rows.empty()) throw std::invalid_argument("heightfield trade table: 'rows' is not a non-empty array");
  for (std::size_t i = 0; i < rows.size(); ++i) t.rows.push_back(trade_row_from_json(rows[i], fmt::format("rows[{}]", i)));
  if (document.contains("grazing")) {
    t.grazing_theta_deg = trade_member<double>(document["grazing"], "theta_above_deg", "grazing");
    t.grazing_min_tiles = trade_member<double>(document["grazing"], "min_tiles", "grazing");
  }
  if (document.contains("scattering"))
    t.scattering_min_tiles = trade_member<double>(document["scattering"], "min_tiles", "scattering");
  return t;
}

const TradeTable& builtin_trade_table() {
  static const TradeTable table = trade_table_from_json(nlohmann::json::parse(kHeightfieldTradeJson));
  return table;
}

SurfaceSize choose_surface_size(const TradeTable& table, const SizeRequest& request) {
  if (!(request.target_tv > 0)) throw std::invalid_argument("choose_surface_size: target_tv must be > 0");
  const double allowed = kBiasShare * request.target_tv;
  const double factor = anisotropy_factor(request.anisotropy);
  const std::vector<TradeRow> rows = candidate_rows(table, request);
  for (const TradeRow& r : rows)
    if (r.bias() * factor <= allowed)
      return {true, r.resolution, r.corr_cells, r.ndf_match, r.bias() * factor,
              fmt::format("the cheapest tile to build ({} CPU s measured{}) whose predicted bias {:.2e} (table row: {}{}) "
                          "is at most {} x target TV {} = {:.2e}; source: {}",
                          r.build_cpu_seconds, wide_text(table, request), r.bias() * factor, row_text(r),
                          anisotropy_text(request.anisotropy), kBiasShare, request.target_tv, allowed, table.source)};
  SurfaceSize none;
  const auto best = std::min_element(rows.begin(), rows.end(),
                                     [](const TradeRow& a, const TradeRow& b) { return a.bias() < b.bias(); });
  none.reason = best == rows.end()
                    ? fmt::format("no row of the trade table fits the view (theta {}) and the assembly's sizes ({} to {})",
                                  request.theta_deg, request.min_resolution, kMaxSurfaceResolution)
                    : fmt::format("no tile up to {}^2 meets the target: the smallest predicted bias is {:.2e} ({}{}), above "
                                  "{} x target TV {} = {:.2e}; a target TV >= {:.2e} is reachable",
                                  kMaxSurfaceResolution, best->bias() * factor, row_text(*best),
                                  anisotropy_text(request.anisotropy), kBiasShare, request.target_tv, allowed,
                                  best->bias() * factor / kBiasShare);
  return none;
}

std::optional<SurfaceSize> predicted_bias(const TradeTable& table, int resolution, double corr_cells,
                                          const std::string& ndf_match, double anisotropy) {
  const double tiles = resolution / corr_cells;
  const TradeRow* used = nullptr;
  for (const TradeRow& r : table.rows)
    if (r.ndf_match == ndf_match && r.tiles() <= tiles * (1 + 1e-9) && (used == nullptr || r.tiles() > used->tiles()))
      used = &r;
  if (used == nullptr) return std::nullopt;
  const double bias = used->bias() * anisotropy_factor(anisotropy);
  return SurfaceSize{true, resolution, corr_cells, ndf_match, bias,
                     fmt::format("the heightmap's own size ({}^2, l {} cells: {:.4g} l per tile, NDF matched {}): predicted "
                                 "bias {:.2e} from the table row with the most correlation lengths not above it ({}{}); "
                                 "source: {}",
                                 resolution, corr_cells, tiles, ndf_match, bias, row_text(*used),
                                 anisotropy_text(anisotropy), table.source)};
}

}  // namespace microsim
