#include "masking_report.h"

#include "command.h"

#include "core/atomic_file.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>

namespace microsim::app {

std::string pm(const Estimate& e, int digits) { return fmt::format("{:.{}f} ± {:.{}f}", e.value, digits, e.standard_error, digits); }

int interrupted_partial_written(const char* command, const std::vector<std::string>& outputs) {
  std::string written;
  for (const auto& o : outputs)
    if (!o.empty()) written += (written.empty() ? "" : ", ") + ("'" + o + "'");
  fmt::print(stderr, "{}: interrupted: partial results{}\n", command,
             written.empty() ? "" : ", written marked partial to " + written);
  return kExitInterrupted;
}

namespace {

double angle_deg(double cosine) { return std::acos(std::min(cosine, 1.0)) * 180 / kPi<double>; }

void print_g2_rows(const std::string& name, const G2Result& g) {
  fmt::print("| {} ({} samples) | {} | {:.4f} (sep. {:.4f}) | {:.4f} (sep. {:.4f}) |\n", name, g.samples, pm(g.value),
             g.smith_analytic, g.separable_analytic, g.smith_empirical, g.separable_empirical);
  fmt::print("| {} / Smith height-correlated | | {} | {} |\n", name, pm(g.ratio_analytic), pm(g.ratio_empirical));
}

void print_conditional_bins(const MaskingResult& r) {
  fmt::print("\nG1(v | m): bins of <v, m> holding equal shares of the front-facing projected area "
             "(first = most grazing, last = facing v). Smith: ratio 1.\n");
  fmt::print("| bin | angle(m, v) deg | share | samples | G1(v given m) | ratio to G1(v) |\n|---|---|---|---|---|---|\n");
  for (std::size_t b = 0; b < r.by_normal.size(); ++b) {
    const auto& c = r.by_normal[b];
    fmt::print("| {} | {:.1f} .. {:.1f} | {:.3f} | {} | {} | {} |\n", b, angle_deg(c.hi), angle_deg(c.lo), c.share,
               c.samples, pm(c.g1), pm(c.ratio));
  }
  const auto& g = r.near_grazing;
  fmt::print("| near-grazing ({:.1f}% of the area) | {:.2f} .. 90.0 | {:.3f} | {} | {} | {} |\n", 100.0 * g.share,
             angle_deg(g.hi), g.share, g.samples, pm(g.g1), pm(g.ratio));
  fmt::print("\nG1(v | h): equal-count bins of the vertex heights (first = lowest). "
             "Smith: C1(h)^Lambda(v) averaged over the bin.\n");
  fmt::print("| bin | height | share | G1(v given h) | Smith, analytic | Smith, own NDF |\n|---|---|---|---|---|---|\n");
  for (std::size_t b = 0; b < r.by_height.size(); ++b) {
    const auto& c = r.by_height[b];
    fmt::print("| {} | {:.4g} .. {:.4g} | {:.3f} | {} | {:.4f} | {:.4f} |\n", b, c.lo, c.hi, c.share, pm(c.g1),
               c.smith_analytic, c.smith_empirical);
  }
}

void print_masking(const MaskingResult& r, const AnalyticSmith& analytic) {
  fmt::print("samples {}  front-facing {}  shadow rays {}  {:.2f} s  {:.3f} Mrays/s{}\n", r.samples, r.front_facing,
             r.rays, r.seconds, r.rays_per_second() * 1e-6, r.partial ? "  PARTIAL (interrupted)" : "");
  fmt::print("leak test  E[w V] / cos(theta_v) = {}  ({:+.2f} SE from 1; leaked rays {}, unresolved {})\n",
             pm(r.leak_ratio), r.leak_ratio.standard_error > 0 ? (r.leak_ratio.value - 1) / r.leak_ratio.standard_error : 0.0, r.leaked,
             r.unresolved);
  fmt::print("\n| quantity | measured | Smith, {} | Smith, own NDF |\n|---|---|---|---|\n", analytic.describe());
  fmt::print("| Lambda(v) | | {:.5f} | {:.5f} |\n", r.lambda_analytic, r.lambda_empirical);
  fmt::print("| G1(v) | {} | {:.4f} | {:.4f} |\n", pm(r.g1), r.g1_smith_analytic, r.g1_smith_empirical);
  if (r.mirror) print_g2_rows("G2 mirror, l = reflect(v, m)", *r.mirror);
  if (r.pair) {
    print_g2_rows("G2(v, l), facets facing both", *r.pair);
    print_g2_rows(fmt::format("G2(v, l), m within {} deg of h", r.cone_deg), *r.pair_cone);
  }
  print_conditional_bins(r);
}

void print_vndf(const MaskingVndf& v) {
  fmt::print("\nVNDF: {} rays along -v, {} front-facing first hits, {:.3f} Mrays/s\n", v.trace.rays, v.trace.hits,
             v.trace.rays_per_second() * 1e-6);
  fmt::print("| bins | cells | TV to Smith (analytic) | TV to Smith (own NDF) | TV noise floor | p (analytic) | p (own NDF) |\n"
             "|---|---|---|---|---|---|---|\n");
  for (const auto& c : v.comparisons)
    fmt::print("| {} | {} | {:.5f} | {:.5f} | {:.5f} | {:.3g} | {:.3g} |\n", c.binning, c.bins, c.tv_analytic,
               c.tv_empirical, c.tv_noise, c.p_value_analytic, c.p_value_empirical);
}

}  // namespace

int report_surface_masking(const SurfaceMasking& m, const MaskingSurface& surface, const MaskingOutputs& outputs) {
  if (!outputs.json.empty()) {
    nlohmann::json j = surface_masking_json(m, surface);
    j["peak_rss_mib"] = peak_rss_mib();
    write_file_atomically(outputs.json, j.dump(2) + "\n");
  }
  const microgeom::Heightfield& field = surface.field;
  const Provenance& p = m.provenance;
  fmt::print("trace masking  {}  ({} x {}, tile {:.6g})  theta {}  phi {}  seed {}{}\n", surface.path, field.resolution(),
             field.resolution(), field.tile_size(), m.request.theta_deg, m.request.phi_deg, m.request.seed,
             p.complete() ? "" : fmt::format("  blocks {} of {}", p.blocks.to_string(), p.total_blocks));
  fmt::print("analytic reference: {} ({})\n", surface.analytic.describe(), surface.reference_source);
  print_masking(m.result, surface.analytic);
  if (m.vndf) print_vndf(*m.vndf);
  fmt::print("peak RSS {:.1f} MiB\n", peak_rss_mib());
  const bool failed = leak_failed(m.result);
  fmt::print("leak test ({} SE): {}\n", kLeakSigmas, failed ? "FAILED" : "passed");
  if (masking_is_partial(m)) return interrupted_partial_written("trace masking", {outputs.json});
  return failed ? kExitRejected : kExitOk;
}

}  // namespace microsim::app
