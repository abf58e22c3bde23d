#include "albedo_layout_report.h"

#include "command.h"
#include "progress_bar.h"

#include "core/atomic_file.h"
#include "core/parse.h"
#include "microfacet/ggx.h"
#include "microgeom/exr_io.h"
#include "scatter/albedo_glass_grade.h"
#include "scatter/albedo_grade.h"
#include "scatter/albedo_layout_io.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <memory>

namespace microsim::app {

namespace {

void print_interpolation(const char* what, const InterpolationError& e) {
  fmt::print("{}: max |error| {:.3g} at alpha {:.4g}, mu {:.4g}; RMS {:.3g}\n", what, e.max_abs, e.worst_alpha,
             e.worst_mu, e.rms);
}

void print_layout_table(const LayoutTable& t) {
  fmt::print("albedo layout {} ({} mirror): {}\nsource: {}\nencoding: {}; reference tolerance {:g}; {:.1f} s\n",
             t.layout.name, to_string(t.ndf), t.layout.summary, t.layout.source, to_string(t.layout.encoding),
             t.tolerance, t.seconds);
  print_interpolation("interpolation error at cell centres (bilinear between nodes - reference)", t.interpolation);
  if (t.layout.has_grazing())
    print_interpolation(fmt::format("{} (the grazing channel): interpolation error at cell centres",
                                    t.layout.grazing_quantity).c_str(), t.grazing_interpolation);
  std::size_t outside = 0;
  for (const bool in : t.in_range) outside += !in;
  if (outside > 0)
    fmt::print("{} roughness node(s) of alpha below {:g}: the reference there is at alpha {:g} (microsim's {} clamps "
               "alpha), not graded, and the cells touching them are left out of the interpolation error\n", outside,
               kMinAlpha, kMinAlpha, t.ndf == NdfKind::ggx ? "GGX" : "Beckmann");
  if (t.average.empty()) return;
  fmt::print("{:<12} {:<12} {:>24}\n", "roughness", "alpha", "E_avg");
  for (std::size_t i = 0; i < t.alphas.size(); ++i)
    fmt::print("{:<12.6g} {:<12.6g} {:>14.9f} +- {:.1g}\n", t.roughness[i], t.alphas[i], t.average[i].value,
               t.average[i].standard_error);
}

LayoutValues read_grade_values(const std::string& path, const AlbedoLayout& layout) {
  try {
    return read_layout_channels(path, layout);
  } catch (const std::invalid_argument& e) {  // unreadable, or not a table of this layout
    throw UsageError(fmt::format("--grade {}: {}", quote_excerpt(path), e.what()));
  }
}

// The failing nodes listed on stdout, in storage order (the rest are in --json's cells), and the line saying so.
constexpr std::size_t kListedFailures = 40;
void print_more_failures(std::size_t failed) {
  if (failed > kListedFailures)
    fmt::print("... and {} more failing nodes (every node is in --json's cells)\n", failed - kListedFailures);
}

// A grade's noise check, when the table's sample count is stated, and its verdict, both kinds of layout alike.
void print_noise_line(std::uint64_t samples, double z, std::size_t beyond, std::size_t nodes) {
  if (samples > 0)
    fmt::print("beyond the noise of {} samples per node ({:.2f} sigma: family level {:g}; weights in [0, 1]): {} of {} "
               "nodes\n", samples, z, kGradeNoiseLevel, beyond, nodes);
}
void print_verdict_line(const GradeTotals& g, std::size_t nodes, double tolerance, const std::string& quantity) {
  fmt::print("{}: {} of {} nodes beyond the tolerance {:g} (beyond the encoding's rounding) ({})\n",
             g.passed() ? "PASS" : "FAIL", g.failed, nodes, tolerance, quantity);
}

void print_grade(const AlbedoGrade& g) {
  const CellGrade& w = g.cells[g.worst];
  fmt::print("grade: {} layout, {} ({} nodes) against the analytic reference of a {} mirror (quadrature tolerance "
             "{:g}: the smaller of the tolerance / 100 and a tenth of the encoding's rounding step)\n", g.layout.name,
             g.quantity, g.cells.size(), to_string(g.ndf), g.reference_tolerance);
  fmt::print("max |table - reference| {:.3g} at node (roughness {}, mu {}) = (alpha {:.6g}, mu {:.6g}): table {:.9g}, "
             "reference {:.9g}; RMS {:.3g}\n", g.max_abs, w.ri, w.mj, w.alpha, w.mu, w.value, w.reference.value, g.rms);
  if (g.not_graded > 0)
    fmt::print("not graded: {} nodes of alpha below {:g}, the reference's range (microsim's {} clamps alpha there)\n",
               g.not_graded, kMinAlpha, g.ndf == NdfKind::ggx ? "GGX" : "Beckmann");
  fmt::print("beyond the encoding's quantisation ({}): {} of {} nodes\n", to_string(g.layout.encoding),
             g.beyond_quantisation, g.cells.size());
  print_noise_line(g.table_samples, g.noise_z, g.beyond_noise, g.cells.size());
  print_interpolation("the table's bilinear interpolation at cell centres - reference", g.table_interpolation);
  print_interpolation("the layout's own (reference nodes) at cell centres", g.reference_interpolation);
  std::size_t listed = 0;
  for (const CellGrade& c : g.cells)
    if (!c.within_tolerance && listed++ < kListedFailures)
      fmt::print("FAIL node (roughness {}, mu {}) alpha {:.6g} mu {:.6g}: table {:.9g} reference {:.9g} difference {:.3g}\n",
                 c.ri, c.mj, c.alpha, c.mu, c.value, c.reference.value, c.difference);
  print_more_failures(listed);
  print_verdict_line(g, g.cells.size(), g.tolerance, g.quantity);
  for (const std::string& h : g.hints) fmt::print("hint: {}\n", h);
}

void print_glass_grade(const GlassGrade& g) {
  const GlassCellGrade& w = g.cells[g.worst];
  fmt::print("grade: {} layout ({}), {} nodes against the analytic reference (quadrature tolerance {:g}: the smaller "
             "of the tolerance / 100 and a tenth of the 6-decimal rounding step)\n", g.layout.name, g.layout.quantity,
             g.cells.size(), g.reference_tolerance);
  fmt::print("max |table - reference| {:.3g} at node (x {}, y {}, z {}) = (alpha {:.6g}, mu {:.6g}, ior {:.6g}): "
             "table {:.9g}, reference {:.9g}; RMS {:.3g}\n", g.max_abs, w.x, w.y, w.z, w.alpha, w.mu, w.ior, w.value,
             w.reference.value, g.rms);
  if (g.not_graded > 0)
    fmt::print("not graded: {} nodes of alpha below {:g}, the reference's range\n", g.not_graded, kMinAlpha);
  fmt::print("beyond Cycles' 6-decimal rounding: {} of {} nodes\n", g.beyond_quantisation, g.cells.size());
  print_noise_line(g.table_samples, g.noise_z, g.beyond_noise, g.cells.size());
  std::size_t listed = 0;
  for (const GlassCellGrade& c : g.cells)
    if (!c.within_tolerance && listed++ < kListedFailures)
      fmt::print("FAIL node (x {}, y {}, z {}) alpha {:.6g} mu {:.6g} ior {:.6g}: table {:.9g} reference {:.9g} "
                 "difference {:.3g}\n", c.x, c.y, c.z, c.alpha, c.mu, c.ior, c.value, c.reference.value, c.difference);
  print_more_failures(listed);
  print_verdict_line(g, g.cells.size(), g.tolerance, g.layout.quantity);
}

}  // namespace

int run_albedo_glass_grade(const GlassLayout& layout, const std::string& table, double tolerance,
                           std::uint64_t table_samples, int threads, const std::string& json) {
  std::vector<double> values;
  try {
    values = read_glass_values(table, layout);
  } catch (const std::invalid_argument& e) {  // unreadable, or not a table of this layout
    throw UsageError(fmt::format("--grade {}: {}", quote_excerpt(table), e.what()));
  }
  for (std::size_t k = 0; k < values.size(); ++k)
    if (!std::isfinite(values[k]))
      throw UsageError(fmt::format("--grade {}: value {} is not finite", quote_excerpt(table), k));
  const auto progress = std::make_shared<CliProgress>(true);
  install_interrupt_handler();
  const std::optional<GlassGrade> g =
      grade_glass_table(layout, values, tolerance, table_samples, cli_run_control(threads, progress));
  progress->finish();
  if (!g) return interrupted_nothing_written("albedo");
  if (!json.empty()) write_file_atomically(json, glass_grade_json(*g).dump(2) + "\n");
  print_glass_grade(*g);
  return g->passed() ? kExitOk : kExitRejected;
}

int run_albedo_layout(const AlbedoLayout& layout, NdfKind ndf, double tolerance, int threads, const LayoutOutputs& o) {
  const auto progress = std::make_shared<CliProgress>(true);
  install_interrupt_handler();
  fmt::print(stderr, "albedo: layout {} ({} x {} nodes and the cell centres)\n", layout.name, layout_columns(layout),
             layout_rows(layout));
  const std::optional<LayoutTable> t = layout_table(layout, tolerance, cli_run_control(threads, progress), true, ndf);
  progress->finish();
  if (!t) return interrupted_nothing_written("albedo");
  microgeom::write_exr(o.exr, layout_table_exr(*t));
  if (!o.csv.empty()) write_file_atomically(o.csv, layout_table_csv(*t));
  if (!o.encoded.empty()) write_file_atomically(o.encoded, layout_table_encoded(*t));
  if (!o.centres.empty()) write_file_atomically(o.centres, layout_centres_csv(*t));
  if (!o.json.empty()) write_file_atomically(o.json, layout_table_json(*t).dump(2) + "\n");
  print_layout_table(*t);
  return kExitOk;
}

int run_albedo_glass_layout(const GlassLayout& layout, double tolerance, int threads, const GlassOutputs& o) {
  const auto progress = std::make_shared<CliProgress>(true);
  install_interrupt_handler();
  fmt::print(stderr, "albedo: layout {} ({} x {} x {} nodes and E_avg)\n", layout.name, layout.roughness_nodes,
             layout.mu_nodes, layout.index_nodes);
  const std::optional<GlassLayoutTable> t = glass_layout_table(layout, tolerance, cli_run_control(threads, progress));
  progress->finish();
  if (!t) return interrupted_nothing_written("albedo");
  if (!o.csv.empty()) write_file_atomically(o.csv, glass_layout_csv(*t));
  if (!o.encoded.empty()) write_file_atomically(o.encoded, glass_layout_encoded(*t));
  if (!o.json.empty()) write_file_atomically(o.json, glass_layout_json(*t).dump(2) + "\n");
  fmt::print("albedo layout {}: {}\nsource: {}\nreference tolerance {:g}; {:.1f} s\n", layout.name, layout.summary,
             layout.source, t->tolerance, t->seconds);
  double worst = 0;
  for (const SingleScatteringAlbedo& c : t->cells) worst = std::max(worst, c.total().standard_error);
  fmt::print("largest error estimate of a node: {:.3g}\n", worst);
  const std::size_t nx = t->alphas.size();
  for (const std::size_t z : {std::size_t(0), t->iors.size() / 2, t->iors.size() - 1})
    fmt::print("E_avg at ior {:.6g}{}: {:.6f} (alpha {:g}) .. {:.6f} (alpha {:g})\n", t->iors[z],
               layout.inverse ? " (from inside)" : "", t->average[z * nx + 1].value, t->alphas[1],
               t->average[z * nx + nx - 1].value, t->alphas[nx - 1]);
  return kExitOk;
}

int run_albedo_grade(const AlbedoLayout& layout, NdfKind ndf, const std::string& table, double tolerance,
                     std::uint64_t table_samples, int threads, const std::string& json) {
  const LayoutValues v = read_grade_values(table, layout);
  for (const std::vector<double>* channel : {&v.values, &v.grazing})
    for (std::size_t k = 0; k < channel->size(); ++k)
      if (!std::isfinite((*channel)[k]))
        throw UsageError(fmt::format("--grade {}: value {} is not finite", quote_excerpt(table), k));
  const auto progress = std::make_shared<CliProgress>(true);
  install_interrupt_handler();
  const std::optional<std::vector<AlbedoGrade>> g =
      grade_albedo_channels(layout, v.values, v.grazing, tolerance, table_samples, cli_run_control(threads, progress),
                            ndf);
  progress->finish();
  if (!g) return interrupted_nothing_written("albedo");
  nlohmann::json out = albedo_grade_json(g->front());
  if (g->size() > 1) out["grazing"] = albedo_grade_json(g->back());
  if (!json.empty()) write_file_atomically(json, out.dump(2) + "\n");
  bool passed = true;
  for (const AlbedoGrade& grade : *g) {
    print_grade(grade);
    passed = passed && grade.passed();
  }
  if (layout.has_grazing() && v.grazing.empty())
    fmt::print("the table has no {} channel: {} graded alone\n", layout.grazing_quantity, layout.quantity);
  return passed ? kExitOk : kExitRejected;
}

}  // namespace microsim::app
