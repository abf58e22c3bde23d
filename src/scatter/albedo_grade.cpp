#include "scatter/albedo_grade.h"

#include <boost/math/distributions/normal.hpp>
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace microsim {

namespace {

void check_grade_input(const AlbedoLayout& layout, const std::vector<double>& values, double tolerance) {
  const std::size_t n = std::size_t(layout.roughness.nodes) * std::size_t(layout.mu.nodes);
  if (values.size() != n)
    throw std::invalid_argument(
        fmt::format("grade: {} values for the {} layout ({} x {} = {})", values.size(), layout.name,
                    layout_columns(layout), layout_rows(layout), n));
  for (std::size_t k = 0; k < n; ++k)
    if (!std::isfinite(values[k])) throw std::invalid_argument(fmt::format("grade: value {} is not finite", k));
  if (!(tolerance > 0) || !std::isfinite(tolerance))
    throw std::invalid_argument(fmt::format("grade: tolerance {} must be positive", tolerance));
}

CellGrade grade_cell(const LayoutTable& t, const std::vector<Estimate>& reference, std::size_t ri, std::size_t mj,
                     double value, double tolerance, std::uint64_t samples, double z) {
  CellGrade c;
  static_cast<NodeGrade&>(c) = grade_node(value, reference[ri * t.mus.size() + mj],
                                          layout_quantisation(t.layout.encoding, value), t.in_range[ri], tolerance,
                                          samples, z);
  c.ri = ri;
  c.mj = mj;
  c.alpha = t.alphas[ri];
  c.mu = t.mus[mj];
  return c;
}

// A way to misread a table: the reference node (ri', mj') the value stored at (ri, mj) was made for, if any.
using Node = std::optional<std::pair<std::size_t, std::size_t>>;
struct Misreading {
  const char* words;
  Node (*node)(std::size_t ri, std::size_t mj, std::size_t nr, std::size_t nm);
};
constexpr Misreading kMisreadings[] = {
    {"its roughness rows one node up (row i filled at roughness node i + 1, as Filament's generator fills its LUT)",
     [](std::size_t ri, std::size_t mj, std::size_t nr, std::size_t) { return ri + 1 < nr ? Node{{ri + 1, mj}} : Node{}; }},
    {"its roughness rows one node down (row i filled at roughness node i - 1)",
     [](std::size_t ri, std::size_t mj, std::size_t, std::size_t) { return ri > 0 ? Node{{ri - 1, mj}} : Node{}; }},
    {"its mu columns one node up (column j filled at mu node j + 1)",
     [](std::size_t ri, std::size_t mj, std::size_t, std::size_t nm) { return mj + 1 < nm ? Node{{ri, mj + 1}} : Node{}; }},
    {"its mu columns one node down (column j filled at mu node j - 1)",
     [](std::size_t ri, std::size_t mj, std::size_t, std::size_t) { return mj > 0 ? Node{{ri, mj - 1}} : Node{}; }},
    {"transposed (roughness and mu swapped)",
     [](std::size_t ri, std::size_t mj, std::size_t nr, std::size_t nm) { return nr == nm ? Node{{mj, ri}} : Node{}; }},
};
// A misreading counts when it fits the graded nodes it covers with at most half the straight RMS difference.
constexpr double kMisreadingGain = 0.5;

// The RMS difference of the table read as `m` says against the reference (graded nodes; NaN when none is covered).
double misread_rms(const LayoutTable& t, const std::vector<Estimate>& reference, const std::vector<double>& nodes,
                   const Misreading& m) {
  const std::size_t nr = t.alphas.size(), nm = t.mus.size();
  double sum = 0;
  std::size_t n = 0;
  for (std::size_t ri = 0; ri < nr; ++ri)
    for (std::size_t mj = 0; mj < nm; ++mj)
      if (const Node to = m.node(ri, mj, nr, nm); to && t.in_range[ri] && t.in_range[to->first]) {
        const double d = nodes[ri * nm + mj] - reference[to->first * nm + to->second].value;
        sum += d * d;
        ++n;
      }
  return n == 0 ? std::nan("") : std::sqrt(sum / double(n));
}

std::vector<std::string> misreading_hints(const LayoutTable& t, const std::vector<Estimate>& reference,
                                          const std::vector<double>& nodes, const AlbedoGrade& g) {
  std::vector<std::string> hints;
  if (g.passed()) return hints;
  for (const Misreading& m : kMisreadings)
    if (const double rms = misread_rms(t, reference, nodes, m); rms <= kMisreadingGain * g.rms)
      hints.push_back(fmt::format("the table fits the reference read with {}: RMS difference {:.3g} against {:.3g} as "
                                  "the layout reads it", m.words, rms, g.rms));
  return hints;
}

}  // namespace

NodeGrade grade_node(double value, const Estimate& reference, double quantisation, bool graded, double tolerance,
                     std::uint64_t samples, double z) {
  NodeGrade c;
  c.value = value;
  c.reference = reference;
  c.graded = graded;
  c.difference = value - reference.value;
  c.quantisation = quantisation;
  const double slack = quantisation + reference.standard_error;
  c.within_quantisation = std::abs(c.difference) <= slack;
  if (samples > 0) {
    const double e = std::clamp(reference.value, 0.0, 1.0);
    c.noise = z * std::sqrt(e * (1 - e) / double(samples));
    c.within_noise = std::abs(c.difference) <= c.noise + slack;
  }
  // A node is judged beyond what its encoding can hold: a table rounded to half floats cannot be nearer than that.
  c.within_tolerance = !graded || std::abs(c.difference) <= tolerance + slack;
  return c;
}

double grade_noise_z(std::size_t nodes, std::uint64_t samples) {
  if (samples == 0 || nodes == 0) return 0;
  const double per_node = 1 - std::pow(1 - kGradeNoiseLevel, 1.0 / double(nodes));
  return boost::math::quantile(boost::math::complement(boost::math::normal(), per_node / 2));
}

double grade_reference_tolerance(const AlbedoLayout& layout, double tolerance) {
  const double step = layout_quantisation(layout.encoding, 0.5);
  return std::clamp(std::min(tolerance / 100, step / 10), 1e-13, 1e-6);
}

AlbedoGrade grade_against(const LayoutTable& t, const std::vector<double>& values, double tolerance,
                          std::uint64_t samples, bool grazing) {
  check_grade_input(t.layout, values, tolerance);
  if (grazing && (!t.layout.has_grazing() || t.grazing.size() != t.cells.size()))
    throw std::invalid_argument(fmt::format("grade: the {} layout's reference has no grazing channel", t.layout.name));
  const std::vector<Estimate>& reference = grazing ? t.grazing : t.cells;
  AlbedoGrade g;
  g.layout = t.layout;
  g.quantity = grazing ? t.layout.grazing_quantity : t.layout.quantity;
  g.ndf = t.ndf;
  g.tolerance = tolerance;
  g.reference_tolerance = t.tolerance;
  g.table_samples = samples;
  const std::size_t nm = t.mus.size();
  g.noise_z = grade_noise_z(values.size(), samples);
  std::vector<double> nodes(t.cells.size());
  for (std::size_t ri = 0; ri < t.alphas.size(); ++ri)
    for (std::size_t mj = 0; mj < nm; ++mj) {
      nodes[ri * nm + mj] = values[layout_storage_index(t.layout, ri, mj)];
      g.cells.push_back(grade_cell(t, reference, ri, mj, nodes[ri * nm + mj], tolerance, samples, g.noise_z));
    }
  static_cast<GradeTotals&>(g) = grade_totals(g.cells, samples > 0);
  g.table_interpolation = interpolation_error(t, nodes, grazing ? t.grazing_centres : t.centres);
  g.reference_interpolation = grazing ? t.grazing_interpolation : t.interpolation;
  g.hints = misreading_hints(t, reference, nodes, g);
  return g;
}

std::optional<AlbedoGrade> grade_albedo_table(const AlbedoLayout& layout, const std::vector<double>& values,
                                              double tolerance, std::uint64_t samples, const RunControl& run,
                                              NdfKind ndf) {
  check_grade_input(layout, values, tolerance);
  const std::optional<LayoutTable> t =
      layout_table(layout, grade_reference_tolerance(layout, tolerance), run, false, ndf);
  if (!t) return std::nullopt;
  return grade_against(*t, values, tolerance, samples);
}

std::optional<std::vector<AlbedoGrade>> grade_albedo_channels(const AlbedoLayout& layout,
                                                              const std::vector<double>& values,
                                                              const std::vector<double>& grazing, double tolerance,
                                                              std::uint64_t samples, const RunControl& run,
                                                              NdfKind ndf) {
  check_grade_input(layout, values, tolerance);
  if (!grazing.empty()) {
    if (!layout.has_grazing())
      throw std::invalid_argument(fmt::format("grade: the {} layout has no grazing channel", layout.name));
    check_grade_input(layout, grazing, tolerance);
  }
  const std::optional<LayoutTable> t =
      layout_table(layout, grade_reference_tolerance(layout, tolerance), run, false, ndf);
  if (!t) return std::nullopt;
  std::vector<AlbedoGrade> grades{grade_against(*t, values, tolerance, samples)};
  if (!grazing.empty()) grades.push_back(grade_against(*t, grazing, tolerance, samples, true));
  return grades;
}

namespace {

nlohmann::json interpolation_json(const InterpolationError& e) {
  return {{"max_abs", e.max_abs}, {"rms", e.rms}, {"worst_alpha", e.worst_alpha}, {"worst_mu", e.worst_mu},
          {"worst_roughness_index", e.worst_ri}, {"worst_mu_index", e.worst_mj}};
}

nlohmann::json cell_json(const CellGrade& c) {
  return {{"roughness_index", c.ri}, {"mu_index", c.mj}, {"alpha", c.alpha}, {"mu", c.mu},
          {"value", c.value}, {"reference", c.reference.value}, {"reference_error", c.reference.standard_error},
          {"difference", c.difference}, {"quantisation", c.quantisation}, {"noise", c.noise},
          {"within_quantisation", c.within_quantisation}, {"within_noise", c.within_noise},
          {"within_tolerance", c.within_tolerance}, {"graded", c.graded}};
}

}  // namespace

nlohmann::json albedo_grade_json(const AlbedoGrade& g) {
  nlohmann::json cells = nlohmann::json::array();
  for (const CellGrade& c : g.cells) cells.push_back(cell_json(c));
  return {{"kind", "albedo table grade"},
          {"layout", g.layout.name},
          {"quantity", g.quantity},
          {"ndf", to_string(g.ndf)},
          {"source", g.layout.source},
          {"encoding", to_string(g.layout.encoding)},
          {"tolerance", g.tolerance},
          {"reference_tolerance", g.reference_tolerance},
          {"table_samples", g.table_samples},
          {"noise_z", g.noise_z},
          {"noise_level", kGradeNoiseLevel},
          {"passed", g.passed()},
          {"max_abs", g.max_abs},
          {"rms", g.rms},
          {"worst", cell_json(g.cells[g.worst])},
          {"failed", g.failed},
          {"not_graded", g.not_graded},
          {"beyond_quantisation", g.beyond_quantisation},
          {"beyond_noise", g.beyond_noise},
          {"table_interpolation", interpolation_json(g.table_interpolation)},
          {"reference_interpolation", interpolation_json(g.reference_interpolation)},
          {"hints", g.hints},
          {"cells", cells}};
}

}  // namespace microsim
