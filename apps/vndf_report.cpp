#include "vndf_report.h"

#include "surface_input.h"

#include "core/atomic_file.h"

#include <fmt/core.h>

#include <stdexcept>

namespace microsim::app {

namespace {

void write_outputs(const TracedHistogram& h, const nlohmann::json& j, const VndfOutputs& outputs) {
  if (outputs.part) write_file_atomically(outputs.out, vndf_part_json(h).dump() + "\n");
  else write_histogram_exr(outputs.out, h);
  if (!outputs.json.empty()) write_file_atomically(outputs.json, j.dump(2) + "\n");
}

void print_fits(const TraceAnalysis& analysis) {
  fmt::print("{:<8} {:>6} {:>12} {:>12} {:>12} {:>6} {:>10}\n", "bins", "cells", "TV", "TV floor", "chi2", "dof", "p");
  for (const TraceFit& f : analysis.fits) {
    fmt::print("{:<8} {:>6} {:>12.6f} {:>12.6f} {:>12.1f} {:>6} {:>10.4g}\n", f.binning, f.chi2.cells, f.total_variation,
               f.noise_floor_tv, f.chi2.statistic, f.chi2.dof, f.chi2.p_value);
  }
  fmt::print("distance to analytic D_v: Sidak-combined p = {:.4g} ({} at level {})\n", analysis.p_value,
             analysis.rejected ? "distinguishable" : "indistinguishable", analysis.significance);
}

void print_comparisons(const std::vector<VndfComparison>& comparisons) {
  fmt::print("| bins | cells | TV to Smith (analytic) | TV to Smith (own NDF) | TV noise floor | p (analytic) | p (own NDF) |\n"
             "|---|---|---|---|---|---|---|\n");
  for (const auto& c : comparisons)
    fmt::print("| {} | {} | {:.5f} | {:.5f} | {:.5f} | {:.3g} | {:.3g} |\n", c.binning, c.bins, c.tv_analytic,
               c.tv_empirical, c.tv_noise, c.p_value_analytic, c.p_value_empirical);
}

const char* partial_note(const TraceResult& r) { return r.partial ? "  PARTIAL (interrupted)" : ""; }

// The run's speed; a merged histogram has none (its parts were timed apart), said so rather than zeros.
std::string speed_text(const TraceResult& r, bool cpu) {
  if (r.seconds <= 0 && r.rays > 0) return "time not measured (merged parts)";
  return fmt::format("{:.2f} s  {:.3f} Mrays/s", r.seconds, r.rays_per_second() * 1e-6) +
         (cpu ? fmt::format("  {:.1f} CPU ns/ray", r.cpu_ns_per_ray()) : "");
}

}  // namespace

int report_ellipsoid_vndf(const EllipsoidVndf& m, const EllipsoidTarget& target, const VndfOutputs& outputs) {
  const TracedHistogram& h = m.histogram;
  const TraceResult& r = m.trace;
  const nlohmann::json j = ellipsoid_vndf_json(m, target, outputs.out);
  write_outputs(h, j, outputs);

  const GGX<double> ggx = histogram_ggx(h);
  const VndfRunRecord run = vndf_run_record(h);
  fmt::print("trace vndf  ellipsoid alpha ({}, {})  theta {}  phi {}  {}\n", ggx.alpha_x(), ggx.alpha_y(),
             run.theta_deg, run.phi_deg, target.describe());
  fmt::print("rays {}  hits {}  hit fraction {:.6f} (exact ellipsoid: {:.6f})  {}{}\n", r.rays, r.hits,
             r.rays ? double(r.hits) / double(r.rays) : 0.0, m.expected_hit_fraction, speed_text(r, true), partial_note(r));
  print_fits(m.analysis);
  fmt::print("wrote {}{}\n", outputs.out, outputs.json.empty() ? "" : " and " + outputs.json);
  return r.partial ? kExitInterrupted : kExitOk;
}

int report_heightfield_vndf(const HeightfieldVndf& m, const microgeom::Heightfield& field, const VndfOutputs& outputs) {
  const TracedHistogram& h = m.histogram;
  const TraceResult& r = m.trace;
  const AnalyticSmith analytic = analytic_reference(field);
  const VndfRunRecord run = vndf_run_record(h);
  const std::string& surface = run.surface;
  const nlohmann::json j = heightfield_vndf_json(m, field, outputs.out);
  write_outputs(h, j, outputs);

  fmt::print("trace vndf  heightfield {}  theta {}  phi {}  reference {} ({})\n", surface, run.theta_deg, run.phi_deg,
             analytic.describe(), m.reference_source);
  fmt::print("rays {}  front-facing first hits {}  back-facing {}  convex-edge grazes passed over {}  leaked {}  {}{}\n",
             r.rays, r.hits, m.diagnostics.backfacing, m.diagnostics.edge_grazes, m.diagnostics.leaked,
             speed_text(r, false), partial_note(r));
  print_comparisons(m.comparisons);
  fmt::print("wrote {}{}\n", outputs.out, outputs.json.empty() ? "" : " and " + outputs.json);
  return r.partial ? kExitInterrupted : kExitOk;
}

}  // namespace microsim::app
