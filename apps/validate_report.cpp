#include "validate_report.h"

#include "command.h"
#include "progress_bar.h"

#include "core/atomic_file.h"
#include "stats/figure.h"
#include "stats/histogram_io.h"

#include <fmt/core.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>

namespace microsim::app {

namespace {

std::string fmt_p(double p) { return p >= 1e-3 ? fmt::format("{:.4f}", p) : fmt::format("{:.2e}", p); }

std::string fmt_alpha(double ax, double ay) {
  return ax == ay ? fmt::format("{:g}", ax) : fmt::format("{:g},{:g}", ax, ay);
}

const char* pass_fail(bool passed) { return passed ? "pass" : "FAIL"; }

void print_worst(const std::string& title, const ChiSquareResult& c, int n) {
  if (c.worst_cells.empty()) return;
  fmt::print("\nworst cells, {} (observed vs expected counts):\n", title);
  fmt::print("  {:<52} {:>12} {:>14} {:>12}\n", "cell", "observed", "expected", "(O-E)^2/E");
  int shown = 0;
  for (const auto& cell : c.worst_cells) {
    if (shown++ >= n) break;
    fmt::print("  {:<52} {:>12.0f} {:>14.2f} {:>12.3g}\n", cell.location, cell.observed, cell.expected, cell.contribution);
  }
}

// How the samples were held: a file's storage (a float32 dump is not "double"), else the sampler's precision.
std::string stored_as(const ValidationReport& r) { return r.storage.empty() ? to_string(r.precision) : r.storage; }

// --plot: observed, expected and residual maps of both binnings (figure.h), written atomically.
void write_plot(const std::string& path, const ValidationReport& r, const std::string& source) {
  const double theta = std::acos(std::clamp(r.wi.z(), -1.0, 1.0)) * 180 / kPi<double>;
  const double phi = std::atan2(r.wi.y(), r.wi.x()) * 180 / kPi<double>;
  const std::string title = fmt::format("alpha {}, theta {:g} deg, phi {:g} deg, {} samples ({})",
                                        fmt_alpha(r.alpha_x, r.alpha_y), theta, phi, r.samples, stored_as(r));
  std::string per_binning;
  for (const BinnedTest& b : r.binned)
    per_binning += fmt::format("{}{} bins p = {:.3g}", per_binning.empty() ? "" : ", ", b.binning, b.chi2.p_value);
  const std::string subtitle = fmt::format("{}\nverdict {}: p = {:.3g} (Sidak-adjusted); {}", source,
                                           r.passed ? "PASS" : "FAIL", r.p_value, per_binning);
  try {
    write_file_atomically(path, histogram_figure_svg(title, subtitle, r.histograms));
  } catch (const FileWriteError& e) {
    throw UsageError(fmt::format("--plot: {}", e.what()));
  }
}

// A row of the report's table: a hard check or a statistical test other than the binned ones, or "n/a".
void print_check(const char* title, const SubTest& t, const std::string& value, const std::string& bound) {
  if (!t.applicable) {
    fmt::print("  {:<34} {:>14} {:>7} {:>11}  n/a\n", title, "", "", "");
    return;
  }
  fmt::print("  {:<34} {:>14} {:>7} {:>11}  {}\n", title, value, "", bound, pass_fail(t.passed));
}

void print_tests(const ValidationReport& r) {
  fmt::print("  {:<34} {:>14} {:>7} {:>11}  {}\n", "test", "statistic", "dof", "p-value", "result");
  for (const BinnedTest& b : r.binned) {
    const ChiSquareResult& c = b.chi2;
    fmt::print("  {:<34} {:>14.2f} {:>7} {:>11}  {}{}\n", fmt::format("chi2, {} bins ({} cells)", b.binning, c.cells),
               c.statistic, c.dof, fmt_p(c.p_value), pass_fail(!c.rejected), c.reason.empty() ? "" : "  (" + c.reason + ")");
  }
  const SubTest& weight = r.check("weight_mean");
  const SubTest& pdf = r.check("returned_pdf");
  const SubTest& integral = r.check("pdf_integral");
  print_check("E[weight] = |wi.z|/G1", weight, fmt::format("{:.6g}", weight.value), fmt_p(weight.p_value));
  // "+r": the errors beyond the tolerance are within what rounding explains (the note below the table).
  const bool rounded = pdf.applicable && pdf.passed && pdf.value > pdf.tolerance;
  print_check("returned pdf (max rel. error)", pdf, fmt::format("{:.2e}", pdf.value),
              fmt::format("<= {:.0e}{}", pdf.tolerance, rounded ? "+r" : ""));
  print_check("claimed pdf integral", integral, fmt::format("{:.9f}", integral.value),
              fmt::format("<= 1+{:.0e}", integral.tolerance));
  for (const SubTest& c : r.checks) {
    if (c.name == "dropped_fraction")
      print_check("dropped samples", c, fmt::format("{:.4f}%", 100 * c.value), fmt_p(c.p_value));
    if (c.name == "bsdf_weight_sign" && !c.passed)
      print_check("weights: negative", c, fmt::format("{:.0f}", c.value), "0");
    if (c.name == "bsdf_albedo") print_check("weights: BSDF albedo", c, fmt::format("{:.6g}", c.value), fmt_p(c.p_value));
    if (c.name == "bsdf_bins")
      print_check("weights: BSDF flux per bin", c, fmt::format("z {:.2f}", c.value), fmt_p(c.p_value));
    if (c.name == "reference_bias")
      print_check("reference bias (P reject exact)", c, fmt::format("{:.3g}", c.value),
                  fmt::format("<= {:.3g}", c.tolerance));
  }
  fmt::print("  {:<34} {:>14} {:>7} {:>11}  {}\n", "samples outside the domain", r.outside_domain, "", "0",
             pass_fail(r.check("domain").passed));
  if (r.invalid_rows > 0)
    fmt::print("  ({} row(s) hold non-finite values or the zero vector: the sampler's failures; first at {})\n",
               r.invalid_rows, fmt::join(r.first_invalid_rows, ", "));
  if (rounded && r.storage == "text")
    fmt::print("  (returned pdf, +r: errors above {:.0e} only within the rounding of the printed digits, of the pdf and "
               "of the direction through the claimed pdf)\n",
               pdf.tolerance);
  else if (rounded)
    fmt::print("  (returned pdf, +r: errors above {:.0e} only where rounding the direction to {} (or float32 data's "
               "rounding) changes the claimed pdf as much, or where D computed from cos theta_m loses as much near a "
               "low roughness's peak)\n",
               pdf.tolerance, to_string(r.precision));
}

// The worst cells of each binned test, the test with the smallest p first (and in more detail).
void print_worst_cells(const ValidationReport& r) {
  std::vector<const BinnedTest*> order;
  for (const BinnedTest& b : r.binned) order.push_back(&b);
  std::stable_sort(order.begin(), order.end(), [](const auto* a, const auto* b) { return a->chi2.p_value < b->chi2.p_value; });
  for (std::size_t k = 0; k < order.size(); ++k)
    print_worst(fmt::format("{} bins", order[k]->binning), order[k]->chi2, k == 0 ? 6 : 3);
}

void print_report(const ValidationReport& r, const std::string& source) {
  const double theta = std::acos(std::clamp(r.wi.z(), -1.0, 1.0)) * 180 / kPi<double>;
  const double phi = std::atan2(r.wi.y(), r.wi.x()) * 180 / kPi<double>;
  const std::string stored = stored_as(r);
  const std::string seed = r.seeded ? fmt::format(", seed {}", r.seed) : "";
  fmt::print("microsim validate: {} ({}), alpha {}, theta {:g} deg, phi {:g} deg, {} samples ({}){}\n", source,
             to_string(r.domain), fmt_alpha(r.alpha_x, r.alpha_y), theta, phi, r.samples, stored, seed);
  // A check that is not statistical (a returned pdf, a negative weight) can fail with every p above the level.
  const char* verdict = r.passed                       ? "PASS"
                        : r.p_value >= r.significance ? "FAIL (a check below failed; the p-value passes)"
                                                      : "FAIL";
  fmt::print("verdict: {}   p-value {} (Sidak-adjusted over {} statistical tests, level {})   statistic {:.2f}   dof {}\n\n",
             verdict, fmt_p(r.p_value), r.statistical_tests, r.significance, r.statistic, r.dof);
  print_tests(r);
  if (r.failed_samples > 0) fmt::print("  ({} sample(s) failed: counted in the remainder cells)\n", r.failed_samples);
  print_worst_cells(r);
  if (!r.failures.empty()) {
    fmt::print("\nrejected because:\n");
    for (const auto& f : r.failures) fmt::print("  - {}\n", f);
  }
  for (const auto& h : r.hints) fmt::print("  - hint: {}\n", h);
  if (!r.notes.empty()) fmt::print("\nnote:\n");
  for (const auto& n : r.notes) fmt::print("  - {}\n", n);
  fmt::print("\ntime {:.2f} s\n", r.seconds);
}

}  // namespace

std::string sampler_source(const SamplerInfo& sampler) { return fmt::format("sampler {}", sampler.name); }

std::string oracle_source(const std::string& source, const std::string& oracle) {
  return source + " against " + oracle + ", two-sample chi-square";
}

std::string histogram_oracle(const std::string& path, const TracedHistogram& traced) {
  return fmt::format("'{}' ({} rays, {} hits, {})", path, traced.rays, traced.hits,
                     traced.attributes.count("target") ? traced.attributes.at("target") : "traced");
}

int report_validation(const ValidationReport& report, const std::string& source, const ValidationOutputs& outputs,
                      const nlohmann::json& extra) {
  print_report(report, source);
  if (!outputs.json.empty()) {
    nlohmann::json j = to_json(report);
    for (auto it = extra.begin(); it != extra.end(); ++it) j[it.key()] = it.value();
    write_file_atomically(outputs.json, j.dump(2) + "\n");
  }
  if (!outputs.plot.empty()) write_plot(outputs.plot, report, source);
  return report.passed ? kExitOk : kExitRejected;
}

TracedHistogram read_oracle_histogram(const std::string& option, const std::string& path) {
  TracedHistogram traced;
  try {
    traced = read_histogram_exr(path);
  } catch (const HistogramIoError& e) {
    throw UsageError(fmt::format("{}: {}", option, e.what()));
  }
  if (traced.partial) fmt::print(stderr, "validate: note: '{}' is a partial (interrupted) trace\n", path);
  return traced;
}

// ---- validate --all ----------------------------------------------------------------------------------------

namespace {

void print_zoo_row(const ZooRow& row) {
  const ValidationReport& r = row.report;
  const SubTest& weight = r.check("weight_mean");
  const SubTest& pdf = r.check("returned_pdf");
  fmt::print("{:<15} {:>10} {:>6g} {:>6g}  {:>9} {:>10} {:>10} {:>10} {:>10} {:>9}  {:>7.2f}\n", row.sampler,
             fmt_alpha(row.alpha_x, row.alpha_y), row.theta_deg, row.phi_deg, row.verdict, fmt_p(r.p_value),
             fmt_p(r.chi2("sphere").p_value), fmt_p(r.chi2("lobe").p_value),
             weight.applicable ? fmt_p(weight.p_value) : "n/a", pdf.applicable ? fmt::format("{:.1e}", pdf.value) : "n/a",
             r.seconds);
}

void print_bsdf_row(const ZooRow& row) {
  const ValidationReport& r = row.report;
  const SubTest& pdf = r.check("returned_pdf");
  fmt::print("{:<15} {:>6g} {:>6g} {:>7}  {:>9} {:>10} {:>10} {:>10} {:>10} {:>10} {:>9}  {:>7.2f}\n", row.sampler,
             row.alpha_x, row.theta_deg, row.inside ? "inside" : "outside", row.verdict, fmt_p(r.p_value),
             fmt_p(r.chi2("sphere").p_value), fmt_p(r.chi2("lobe").p_value), fmt_p(r.check("bsdf_albedo").p_value),
             fmt_p(r.check("bsdf_bins").p_value), pdf.applicable ? fmt::format("{:.1e}", pdf.value) : "n/a", r.seconds);
}

void print_bsdf_header(std::size_t validations) {
  fmt::print("\nBSDF samplers: {} validations (directions against the claimed pdf, weights f cos / pdf against the "
             "analytic BSDF; conductor {}+{}i, dielectric {} from outside and, mirrored, from inside)\n",
             validations, kZooConductorIor.real(), kZooConductorIor.imag(), kZooDielectricEta);
  fmt::print("{:<15} {:>6} {:>6} {:>7}  {:>9} {:>10} {:>10} {:>10} {:>10} {:>10} {:>9}  {:>7}\n", "sampler", "alpha",
             "theta", "side", "verdict", "p-value", "p sphere", "p lobe", "p albedo", "p bins", "pdf err", "time s");
}

void print_summary(const ZooResult& result) {
  fmt::print("\nsummary per sampler:\n");
  fmt::print("{:<15} {:>8} {:>12} {:>12} {:>12} {:>9}  {}\n", "sampler", "passed", "min p", "max p", "expected", "time s",
             "outcome");
  for (const ZooSummaryRow& sm : result.summary) {
    const std::string expected = !sm.negative_control  ? "all pass"
                                 : sm.without_effect ? fmt::format("rejected ({} no effect)", sm.without_effect)
                                                     : "all rejected";
    fmt::print("{:<15} {:>4}/{:<3} {:>12} {:>12} {:>12} {:>9.1f}  {}\n", sm.sampler, sm.passed, sm.total,
               fmt_p(sm.min_p), fmt_p(sm.max_p), expected, sm.seconds, sm.expectation_met ? "as expected" : "UNEXPECTED");
  }
}

}  // namespace

ZooReport::ZooReport(const ValidationRun& run) {
  const ValidationOptions& o = run.options;
  fmt::print("microsim validate --all: {} samplers x {} configurations, {} samples each ({}), seed {}\n",
             sampler_registry().size(), kZooConfigurations, o.samples, to_string(o.precision), run.seed);
  fmt::print("family-wise level {} over {} validations (Sidak): each validation at {:.3e}; negative controls must "
             "be rejected with p < {:g}\n\n",
             run.family_significance, run.cases.size(), o.significance, kNegativeControlP);
  fmt::print("{:<15} {:>10} {:>6} {:>6}  {:>9} {:>10} {:>10} {:>10} {:>10} {:>9}  {:>7}\n", "sampler", "alpha", "theta",
             "phi", "verdict", "p-value", "p sphere", "p lobe", "p weight", "pdf err", "time s");
}

ZooObserver ZooReport::observer() const {
  ZooObserver o;
  o.row = [](const ZooRow& row) {
    row.bsdf ? print_bsdf_row(row) : print_zoo_row(row);
    std::fflush(stdout);
  };
  o.bsdf_section = print_bsdf_header;
  return o;
}

int ZooReport::finish(const ZooResult& result, const std::string& json) const {
  print_summary(result);
  fmt::print("\nexpected counts (adaptive cubature of {} claimed pdfs x 2 binnings): {:.1f} s\n", result.references,
             result.reference_seconds);
  fmt::print("BSDF references (cubature of {} claimed pdfs x 2 binnings and BSDF fluxes, in parallel): {:.1f} s\n",
             result.bsdf_references, result.bsdf_reference_seconds);
  if (result.partial) {
    fmt::print("overall: INTERRUPTED: partial results, {} of {} validations in {:.1f} s (no verdict)\n",
               result.rows.size(), result.requested, result.seconds);
  } else {
    fmt::print("overall: {} ({} validations in {:.1f} s)\n",
               result.all_met ? "PASS: every correct sampler passes and every negative control is rejected" : "FAIL",
               result.rows.size(), result.seconds);
  }
  if (!json.empty()) write_file_atomically(json, to_json(result).dump(2) + "\n");
  if (result.partial)
    fmt::print(stderr, "validate --all: interrupted: partial results{}\n",
               json.empty() ? "" : fmt::format(", written marked partial to '{}'", json));
  return exit_code(result);
}

// ---- merge -------------------------------------------------------------------------------------------------

int report_merged_validation(const ValidationPart& merged, std::size_t parts, const std::string& json) {
  ValidationRun run;
  try {
    run = validation_run_of(merged);
  } catch (const HistogramMergeError& e) {
    throw UsageError(fmt::format("cannot merge: {}", e.what()));
  }
  fmt::print(stderr, "merge: {} validate parts, {} validation(s) of {} samples, blocks {}\n", parts,
             run.cases.size(), run.options.samples, merged.provenance.blocks.to_string());
  const std::optional<ZooReport> zoo = run.batch ? std::optional<ZooReport>(std::in_place, run) : std::nullopt;
  const auto progress = std::make_shared<CliProgress>(true);  // the batch's BSDF section; Ctrl-C stops it
  MergedValidation m;
  try {
    m = analyse_merged_validation(merged, cli_run_control(0, progress), zoo ? zoo->observer() : ZooObserver{});
  } catch (const HistogramMergeError& e) {
    throw UsageError(fmt::format("cannot merge: {}", e.what()));
  } catch (const HistogramIoError& e) {
    throw UsageError(fmt::format("the parts' --against: {}", e.what()));
  } catch (const InsufficientData& e) {
    throw UsageError(e.what());  // too few samples for the tests: bad input, as in the single run
  }
  progress->finish();
  if (m.batch) return zoo->finish(*m.batch, json);
  const std::string source = sampler_source(*m.run.cases.front().sampler);
  if (!m.traced) return report_validation(*m.report, source, {json, ""});
  if (m.traced->partial) fmt::print(stderr, "validate: note: '{}' is a partial (interrupted) trace\n", m.run.against);
  return report_validation(*m.report, oracle_source(source, histogram_oracle(m.run.against, *m.traced)), {json, ""},
                           merged_validation_json(m));
}

}  // namespace microsim::app
