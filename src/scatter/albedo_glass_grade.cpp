#include "scatter/albedo_glass_grade.h"

#include "core/parse.h"
#include "core/strict_parse.h"
#include "scatter/albedo_grade.h"
#include "scatter/albedo_layout.h"
#include "scatter/albedo_layout_io.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace microsim {

namespace {

std::size_t glass_node_count(const GlassLayout& l) {
  return std::size_t(l.roughness_nodes) * std::size_t(l.mu_nodes) * std::size_t(l.index_nodes);
}

void check_glass_grade_input(const GlassLayout& layout, const std::vector<double>& values, double tolerance) {
  const std::size_t n = glass_node_count(layout);
  if (values.size() != n)
    throw std::invalid_argument(fmt::format("grade: {} values for the {} layout ({} x {} x {} = {})", values.size(),
                                            layout.name, layout.roughness_nodes, layout.mu_nodes, layout.index_nodes, n));
  for (std::size_t k = 0; k < n; ++k)
    if (!std::isfinite(values[k])) throw std::invalid_argument(fmt::format("grade: value {} is not finite", k));
  if (!(tolerance > 0) || !std::isfinite(tolerance))
    throw std::invalid_argument(fmt::format("grade: tolerance {} must be positive", tolerance));
}

GlassCellGrade grade_glass_cell(const GlassLayoutTable& t, std::size_t k, double value, double tolerance,
                                std::uint64_t samples, double z) {
  GlassCellGrade c;
  const std::size_t nx = t.alphas.size(), ny = t.mus.size();
  c.x = k % nx;
  c.y = (k / nx) % ny;
  c.z = k / (nx * ny);
  static_cast<NodeGrade&>(c) = grade_node(value, t.cells[k].total(), layout_quantisation(LayoutEncoding::six_decimals, value),
                                          t.in_range[c.x], tolerance, samples, z);
  c.alpha = t.alphas[c.x];
  c.mu = t.mus[c.y];
  c.ior = t.layout.inverse ? 1 / t.iors[c.z] : t.iors[c.z];
  return c;
}

}  // namespace

double glass_grade_reference_tolerance(double tolerance) {
  const double step = layout_quantisation(LayoutEncoding::six_decimals, 0.5);
  return std::clamp(std::min(tolerance / 100, step / 10), 1e-13, 1e-6);
}

GlassGrade grade_glass_against(const GlassLayoutTable& t, const std::vector<double>& values, double tolerance,
                               std::uint64_t samples) {
  check_glass_grade_input(t.layout, values, tolerance);
  if (t.cells.size() != values.size())
    throw std::invalid_argument("grade: the reference does not have the layout's nodes");
  GlassGrade g;
  g.layout = t.layout;
  g.tolerance = tolerance;
  g.reference_tolerance = t.tolerance;
  g.table_samples = samples;
  g.noise_z = grade_noise_z(values.size(), samples);
  for (std::size_t k = 0; k < values.size(); ++k)
    g.cells.push_back(grade_glass_cell(t, k, values[k], tolerance, samples, g.noise_z));
  static_cast<GradeTotals&>(g) = grade_totals(g.cells, samples > 0);
  return g;
}

std::optional<GlassGrade> grade_glass_table(const GlassLayout& layout, const std::vector<double>& values,
                                            double tolerance, std::uint64_t samples, const RunControl& run) {
  check_glass_grade_input(layout, values, tolerance);
  const std::optional<GlassLayoutTable> t =
      glass_layout_table(layout, glass_grade_reference_tolerance(tolerance), run, false);
  if (!t) return std::nullopt;
  return grade_glass_against(*t, values, tolerance, samples);
}

namespace {

nlohmann::json glass_cell_json(const GlassCellGrade& c) {
  return {{"x", c.x}, {"y", c.y}, {"z", c.z}, {"alpha", c.alpha}, {"mu", c.mu}, {"ior", c.ior}, {"value", c.value},
          {"reference", c.reference.value}, {"reference_error", c.reference.standard_error},
          {"difference", c.difference}, {"quantisation", c.quantisation}, {"noise", c.noise},
          {"within_quantisation", c.within_quantisation}, {"within_noise", c.within_noise},
          {"within_tolerance", c.within_tolerance}, {"graded", c.graded}};
}

}  // namespace

nlohmann::json glass_grade_json(const GlassGrade& g) {
  nlohmann::json cells = nlohmann::json::array();
  for (const GlassCellGrade& c : g.cells) cells.push_back(glass_cell_json(c));
  return {{"kind", "glass table grade"}, {"layout", g.layout.name}, {"quantity", g.layout.quantity},
          {"source", g.layout.source}, {"encoding", to_string(LayoutEncoding::six_decimals)},
          {"tolerance", g.tolerance}, {"reference_tolerance", g.reference_tolerance},
          {"table_samples", g.table_samples}, {"noise_z", g.noise_z}, {"noise_level", kGradeNoiseLevel},
          {"passed", g.passed()}, {"max_abs", g.max_abs}, {"rms", g.rms}, {"worst", glass_cell_json(g.cells[g.worst])},
          {"failed", g.failed}, {"not_graded", g.not_graded}, {"beyond_quantisation", g.beyond_quantisation},
          {"beyond_noise", g.beyond_noise}, {"cells", cells}};
}

namespace {

std::string_view trimmed(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

// The ','-separated fields of `line` (reader::split_commas), each trimmed of blanks.
std::vector<std::string_view> comma_fields(std::string_view line) {
  std::vector<std::string_view> f = reader::split_commas(line);
  for (std::string_view& field : f) field = trimmed(field);
  return f;
}

std::size_t glass_csv_column(const std::vector<std::string_view>& header, std::string_view name) {
  for (std::size_t i = 0; i < header.size(); ++i)
    if (header[i] == name) return i;
  throw std::invalid_argument(fmt::format("the CSV has no column '{}' (a glass table microsim wrote has x, y, z "
                                          "and E)", name));
}

}  // namespace

std::vector<double> glass_values_from_csv(std::string_view text, const GlassLayout& l) {
  std::istringstream in{std::string(text)};
  std::string line;
  std::vector<std::string_view> header;
  std::string header_line;
  std::size_t number_of_line = 0;
  while (header.empty() && std::getline(in, header_line)) {  // '#' comments may come before the header
    ++number_of_line;
    if (!trimmed(header_line).empty() && header_line.front() != '#') header = comma_fields(header_line);
  }
  if (header.empty()) throw std::invalid_argument("a CSV without a header");
  const std::size_t cx = glass_csv_column(header, "x"), cy = glass_csv_column(header, "y"),
                    cz = glass_csv_column(header, "z"), ce = glass_csv_column(header, "E");
  const auto nx = std::size_t(l.roughness_nodes), ny = std::size_t(l.mu_nodes), nz = std::size_t(l.index_nodes);
  std::vector<double> values(nx * ny * nz, std::nan(""));
  std::size_t seen = 0;
  while (std::getline(in, line)) {
    ++number_of_line;
    if (trimmed(line).empty() || line.front() == '#') continue;
    const std::vector<std::string_view> f = comma_fields(line);
    if (f.size() != header.size())
      throw std::invalid_argument(fmt::format("line {}: {} fields, the header has {}", number_of_line, f.size(), header.size()));
    const std::string what = fmt::format("line {}", number_of_line);
    const auto x = std::size_t(parse_uint(what + " x", f[cx], 0, nx - 1));
    const auto y = std::size_t(parse_uint(what + " y", f[cy], 0, ny - 1));
    const auto z = std::size_t(parse_uint(what + " z", f[cz], 0, nz - 1));
    const std::size_t k = (z * ny + y) * nx + x;
    if (!std::isnan(values[k])) throw std::invalid_argument(fmt::format("{}: node ({}, {}, {}) given twice", what, x, y, z));
    values[k] = parse_double(what + " E", f[ce]);
    ++seen;
  }
  if (seen != values.size())
    throw std::invalid_argument(fmt::format("{} nodes in the CSV; the {} layout has {}", seen, l.name, values.size()));
  return values;
}

std::vector<double> glass_values_from_text(std::string_view text, const GlassLayout& l) {
  return printed_values(text, glass_node_count(l), l.name);
}

std::vector<double> read_glass_values(const std::string& path, const GlassLayout& layout) {
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext != ".csv" && ext != ".txt") throw std::invalid_argument("a .csv or a .txt (Cycles' printed values) glass table");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::invalid_argument("cannot be read");
  std::ostringstream text;
  text << in.rdbuf();
  return ext == ".csv" ? glass_values_from_csv(text.str(), layout) : glass_values_from_text(text.str(), layout);
}

}  // namespace microsim
