// microsim validate: statistical validation of a sampler of the zoo, of samples from a file, or of the
// whole zoo over a grid (--all). Tables on stdout, progress on stderr, --json for machines.
// Exit codes: 0 pass, 1 rejected, 2 bad usage or bad input. See docs/validation.md.
#include "command.h"
#include "number_options.h"
#include "microfacet/roughness.h"

#include "validate/compare.h"
#include "core/atomic_file.h"
#include "stats/histogram_io.h"
#include "progress_bar.h"
#include "validate/sample_io.h"
#include "validate/validate.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <algorithm>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace {

using microsim::app::UsageError;
namespace fs = std::filesystem;

struct Args {
  std::string sampler;
  std::string from;
  bool reflected = false;
  bool all = false;
  std::string alpha;
  std::optional<double> theta;
  double phi = 0;
  std::optional<long long> samples;
  unsigned long long seed = 1;
  bool use_float = false;
  int rows = 31;
  double significance = 0.01;
  std::string json;
  std::string against;             // "ellipsoid" or a traced histogram HIST.exr (compare.h)
  std::optional<long long> rays;   // with --against ellipsoid
  std::string plot;                // a figure of the binned counts (SVG), single validations only
};

// The --all grid (issue 2, section 4).
constexpr double kAllThetas[] = {0, 30, 60, 80, 89};
struct AlphaConfig {
  double ax, ay, phi;
};
// Isotropic roughness at phi = 0; anisotropic pairs seen from phi = 30 degrees so that both axes matter.
constexpr AlphaConfig kAllAlphas[] = {{1e-3, 1e-3, 0}, {0.05, 0.05, 0}, {0.3, 0.3, 0},    {1, 1, 0},
                                      {2, 2, 0},       {0.05, 0.5, 30}, {0.5, 0.05, 30}, {1e-3, 0.3, 30}};
constexpr long long kAllDefaultSamples = 200'000;
constexpr double kNegativeControlP = 1e-6;  // a negative control must be rejected with p below this

std::string names_list() {
  std::string s;
  for (const auto& n : microsim::sampler_names()) s += (s.empty() ? "" : ", ") + n;
  return s;
}

std::string fmt_p(double p) { return p >= 1e-3 ? fmt::format("{:.4f}", p) : fmt::format("{:.2e}", p); }

std::string fmt_alpha(double ax, double ay) {
  return ax == ay ? fmt::format("{:g}", ax) : fmt::format("{:g},{:g}", ax, ay);
}

const char* pass_fail(bool passed) { return passed ? "pass" : "FAIL"; }

void print_worst(const std::string& title, const microsim::ChiSquareResult& c, int n) {
  if (c.worst_cells.empty()) return;
  fmt::print("\nworst cells, {} (observed vs expected counts):\n", title);
  fmt::print("  {:<52} {:>12} {:>14} {:>12}\n", "cell", "observed", "expected", "(O-E)^2/E");
  int shown = 0;
  for (const auto& cell : c.worst_cells) {
    if (shown++ >= n) break;
    fmt::print("  {:<52} {:>12.0f} {:>14.2f} {:>12.3g}\n", cell.location, cell.observed, cell.expected, cell.contribution);
  }
}

// --plot: observed, expected and residual maps of both binnings (figure.h), written atomically.
void write_plot(const std::string& path, const microsim::ValidationReport& r, const std::string& source) {
  using namespace microsim;
  const double theta = std::acos(std::clamp(r.wi.z(), -1.0, 1.0)) * 180 / kPi<double>;
  const double phi = std::atan2(r.wi.y(), r.wi.x()) * 180 / kPi<double>;
  const std::string title = fmt::format("alpha {}, theta {:g} deg, phi {:g} deg, {} samples ({})",
                                        fmt_alpha(r.alpha_x, r.alpha_y), theta, phi, r.samples, to_string(r.precision));
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
void print_check(const char* title, const microsim::SubTest& t, const std::string& value, const std::string& bound) {
  if (!t.applicable) {
    fmt::print("  {:<34} {:>14} {:>7} {:>11}  n/a\n", title, "", "", "");
    return;
  }
  fmt::print("  {:<34} {:>14} {:>7} {:>11}  {}\n", title, value, "", bound, pass_fail(t.passed));
}

void print_tests(const microsim::ValidationReport& r) {
  using namespace microsim;
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
  print_check("returned pdf (max rel. error)", pdf, fmt::format("{:.2e}", pdf.value), fmt::format("<= {:.0e}", pdf.tolerance));
  print_check("claimed pdf integral", integral, fmt::format("{:.9f}", integral.value),
              fmt::format("<= 1+{:.0e}", integral.tolerance));
  fmt::print("  {:<34} {:>14} {:>7} {:>11}  {}\n", "samples outside the domain", r.outside_domain, "", "0",
             pass_fail(r.check("domain").passed));
  if (pdf.applicable && pdf.passed && pdf.value > pdf.tolerance)
    fmt::print("  (returned pdf: errors above {:.0e} only where rounding the direction to {} changes the claimed pdf "
               "as much)\n",
               pdf.tolerance, to_string(r.precision));
}

// The worst cells of each binned test, the test with the smallest p first (and in more detail).
void print_worst_cells(const microsim::ValidationReport& r) {
  std::vector<const microsim::BinnedTest*> order;
  for (const microsim::BinnedTest& b : r.binned) order.push_back(&b);
  std::stable_sort(order.begin(), order.end(), [](const auto* a, const auto* b) { return a->chi2.p_value < b->chi2.p_value; });
  for (std::size_t k = 0; k < order.size(); ++k)
    print_worst(fmt::format("{} bins", order[k]->binning), order[k]->chi2, k == 0 ? 6 : 3);
}

void print_report(const microsim::ValidationReport& r, const std::string& source) {
  using namespace microsim;
  const double theta = std::acos(std::clamp(r.wi.z(), -1.0, 1.0)) * 180 / kPi<double>;
  const double phi = std::atan2(r.wi.y(), r.wi.x()) * 180 / kPi<double>;
  fmt::print("microsim validate: {} ({}), alpha {}, theta {:g} deg, phi {:g} deg, {} samples ({}), seed {}\n", source,
             to_string(r.domain), fmt_alpha(r.alpha_x, r.alpha_y), theta, phi, r.samples, to_string(r.precision), r.seed);
  fmt::print("verdict: {}   p-value {} (Sidak-adjusted over {} statistical tests, level {})   statistic {:.2f}   dof {}\n\n",
             r.passed ? "PASS" : "FAIL", fmt_p(r.p_value), r.statistical_tests, r.significance, r.statistic, r.dof);
  print_tests(r);
  if (r.failed_samples > 0) fmt::print("  ({} sample(s) failed: counted in the remainder cells)\n", r.failed_samples);
  print_worst_cells(r);
  if (!r.failures.empty()) {
    fmt::print("\nrejected because:\n");
    for (const auto& f : r.failures) fmt::print("  - {}\n", f);
  }
  fmt::print("\ntime {:.2f} s\n", r.seconds);
}

microsim::ValidationOptions base_options(const Args& a) {
  microsim::ValidationOptions o;
  o.seed = a.seed;
  o.rows = a.rows;
  o.significance = a.significance;
  o.precision = a.use_float ? microsim::Precision::float32 : microsim::Precision::float64;
  return o;
}

// Runs a validation; a malformed --from file (the reader's message names the line or index) and too few
// samples for the tests (the message says how many are needed) are bad input: exit 2.
template <class F> auto usage_errors_of(F&& validation, const std::string& file = "") {
  const std::string where = file.empty() ? "" : fmt::format("--from '{}': ", file);
  try {
    return validation();
  } catch (const microsim::SampleFileError& e) {
    throw UsageError(e.what());
  } catch (const microsim::InsufficientData& e) {
    throw UsageError(where + e.what());
  }
}

// A --from file, opened for streaming (bounded memory whatever its size).
microsim::DirectionSampleReader open_samples_or_usage_error(const std::string& path) {
  return usage_errors_of([&] { return microsim::DirectionSampleReader(path); });
}

// --against ellipsoid | HIST.exr: two-sample chi-square against the traced oracle (compare.h); same report,
// verdict, exit codes and JSON keys (plus "against").
int run_against(const Args& a, const microsim::GGX<double>& ggx, const microsim::Vec3<double>& wi,
                microsim::ValidationOptions o) {
  using namespace microsim;
  // Too few samples for any test: refused before the oracle is traced.
  if (a.from.empty()) usage_errors_of([&] { require_samples_for_any_test(std::uint64_t(a.samples.value_or(1'000'000))); });
  TracedHistogram traced;
  std::string oracle;
  if (a.against == "ellipsoid") {
    OracleTraceOptions t;
    t.rays = std::uint64_t(a.rays.value_or(4'000'000));
    t.seed = oracle_seed(a.seed);
    t.rows = a.rows;
    const auto progress = std::make_shared<CliProgress>(true);
    t.run = cli_run_control(0, progress);
    traced = trace_vndf_histogram(ggx, wi, t);
    progress->finish();
    if (traced.partial) return microsim::app::interrupted_nothing_written("validate", "while tracing the oracle", "no verdict");
    oracle = fmt::format("the traced ellipsoid ({} rays, {} hits, seed {})", traced.rays, traced.hits, t.seed);
  } else {
    try {
      traced = read_histogram_exr(a.against);
    } catch (const HistogramIoError& e) {
      throw UsageError(fmt::format("--against: {}", e.what()));
    }
    if (traced.partial) fmt::print(stderr, "validate: note: '{}' is a partial (interrupted) trace\n", a.against);
    oracle = fmt::format("'{}' ({} rays, {} hits, {})", a.against, traced.rays, traced.hits,
                         traced.attributes.count("target") ? traced.attributes.at("target") : "traced");
  }
  ValidationReport report;
  std::string source;
  try {
    if (!a.from.empty()) {
      DirectionSampleReader samples = open_samples_or_usage_error(a.from);
      report = usage_errors_of([&] { return compare_sample_file_to_trace(samples, a.from, ggx, wi, o, traced); }, a.from);
      source = fmt::format("samples from '{}'", a.from);
    } else {
      const SamplerInfo* s = find_sampler(a.sampler);
      if (!s) throw UsageError(fmt::format("--sampler: unknown sampler '{}' (valid: {})", a.sampler, names_list()));
      o.samples = std::uint64_t(a.samples.value_or(1'000'000));
      report = usage_errors_of([&] { return compare_sampler_to_trace(*s, ggx, wi, o, traced); });
      source = fmt::format("sampler {}", s->name);
    }
  } catch (const std::invalid_argument& e) {
    throw UsageError(fmt::format("--against: {}", e.what()));
  }
  if (interrupted()) return microsim::app::interrupted_nothing_written("validate", "while comparing with the oracle", "no verdict");
  source += " against " + oracle + ", two-sample chi-square";
  print_report(report, source);
  if (!a.json.empty()) {
    nlohmann::json j = to_json(report);
    j["against"] = a.against;
    j["oracle_rays"] = traced.rays;
    j["oracle_hits"] = traced.hits;
    write_file_atomically(a.json, j.dump(2) + "\n");
  }
  if (!a.plot.empty()) write_plot(a.plot, report, source);
  return report.passed ? microsim::app::kExitOk : microsim::app::kExitRejected;
}

int run_single(const Args& a) {
  using namespace microsim;
  if (a.alpha.empty()) throw UsageError("--alpha is required (e.g. --alpha 0.3 or --alpha 0.05,0.5)");
  if (!a.theta) throw UsageError("--theta is required (degrees in [0, 90))");
  const auto [ax, ay] = microsim::parse_alpha("--alpha", a.alpha);
  const GGX<double> ggx(ax, ay);
  const Vec3<double> wi = direction_from_degrees(*a.theta, a.phi);
  ValidationOptions o = base_options(a);
  const auto progress = std::make_shared<CliProgress>(true);
  o.run = cli_run_control(0, progress);
  install_interrupt_handler();
  if (!a.against.empty()) return run_against(a, ggx, wi, o);
  ValidationReport report;
  std::string source;
  if (!a.from.empty()) {
    DirectionSampleReader samples = open_samples_or_usage_error(a.from);
    const SampleDomain domain = a.reflected ? SampleDomain::reflected_direction : SampleDomain::microfacet_normal;
    report = usage_errors_of([&] { return validate_sample_file(samples, domain, ggx, wi, o); }, a.from);
    report.sampler = a.from;
    source = fmt::format("samples from '{}'", a.from);
  } else {
    const SamplerInfo* s = find_sampler(a.sampler);
    if (!s) throw UsageError(fmt::format("--sampler: unknown sampler '{}' (valid: {})", a.sampler, names_list()));
    o.samples = std::uint64_t(a.samples.value_or(1'000'000));
    report = usage_errors_of([&] { return validate_sampler(*s, ggx, wi, o); });
    source = fmt::format("sampler {}", s->name);
  }
  progress->finish();
  if (interrupted()) return microsim::app::interrupted_nothing_written("validate", "while validating", "no verdict");
  print_report(report, source);
  if (!a.json.empty()) write_file_atomically(a.json, to_json(report).dump(2) + "\n");
  if (!a.plot.empty()) write_plot(a.plot, report, source);
  return report.passed ? microsim::app::kExitOk : microsim::app::kExitRejected;
}

// ---- validate --all: the rendering of the batch -----------------------------------------------------------

// How one sampler fared over the grid.
struct Summary {
  int total = 0, passed = 0;
  double min_p = 1, max_p = 0, seconds = 0;
  bool expectation_met = true;  // correct: all pass; negative control: all rejected with p < 1e-6
};

void add_to_summary(Summary& sm, const microsim::SamplerInfo& s, const microsim::ValidationReport& r) {
  sm.total += 1;
  sm.passed += r.passed;
  sm.min_p = std::min(sm.min_p, r.p_value);
  sm.max_p = std::max(sm.max_p, r.p_value);
  sm.seconds += r.seconds;
  if (s.negative_control) {
    if (r.passed || !(r.p_value < kNegativeControlP)) sm.expectation_met = false;
  } else if (!r.passed) {
    sm.expectation_met = false;
  }
}

void print_all_header(const Args& a, const microsim::ValidationOptions& o, std::size_t samplers, int n_configs,
                      int n_validations) {
  fmt::print("microsim validate --all: {} samplers x {} configurations, {} samples each ({}), seed {}\n", samplers,
             n_configs, o.samples, microsim::to_string(o.precision), a.seed);
  fmt::print("family-wise level {} over {} validations (Sidak): each validation at {:.3e}; negative controls must "
             "be rejected with p < {:g}\n\n",
             a.significance, n_validations, o.significance, kNegativeControlP);
  fmt::print("{:<15} {:>10} {:>6} {:>6}  {:>9} {:>10} {:>10} {:>10} {:>10} {:>9}  {:>7}\n", "sampler", "alpha", "theta",
             "phi", "verdict", "p-value", "p sphere", "p lobe", "p weight", "pdf err", "time s");
}

// One row of the batch table (printed at once) and its JSON record.
nlohmann::json render_all_row(const microsim::SamplerInfo& s, const AlphaConfig& ac, double theta,
                              const microsim::ValidationReport& r) {
  const microsim::SubTest& weight = r.check("weight_mean");
  const microsim::SubTest& pdf = r.check("returned_pdf");
  fmt::print("{:<15} {:>10} {:>6g} {:>6g}  {:>9} {:>10} {:>10} {:>10} {:>10} {:>9}  {:>7.2f}\n", s.name,
             fmt_alpha(ac.ax, ac.ay), theta, ac.phi, r.passed ? "pass" : (s.negative_control ? "rejected" : "FAIL"),
             fmt_p(r.p_value), fmt_p(r.chi2("sphere").p_value), fmt_p(r.chi2("lobe").p_value),
             weight.applicable ? fmt_p(weight.p_value) : "n/a", pdf.applicable ? fmt::format("{:.1e}", pdf.value) : "n/a",
             r.seconds);
  std::fflush(stdout);
  nlohmann::json j = to_json(r);
  j["negative_control"] = s.negative_control;
  j["theta_deg"] = theta;
  j["phi_deg"] = ac.phi;
  return j;
}

// The summary table per sampler (and its JSON); true when every sampler met its expectation.
bool print_summary(std::span<const microsim::SamplerInfo> samplers, const std::map<std::string, Summary>& summary,
                   nlohmann::json& summary_json) {
  bool all_met = true;
  fmt::print("\nsummary per sampler:\n");
  fmt::print("{:<15} {:>8} {:>12} {:>12} {:>12} {:>9}  {}\n", "sampler", "passed", "min p", "max p", "expected", "time s",
             "outcome");
  for (const microsim::SamplerInfo& s : samplers) {
    const auto it = summary.find(std::string(s.name));
    if (it == summary.end()) continue;
    const Summary& sm = it->second;
    all_met = all_met && sm.expectation_met;
    fmt::print("{:<15} {:>4}/{:<3} {:>12} {:>12} {:>12} {:>9.1f}  {}\n", s.name, sm.passed, sm.total, fmt_p(sm.min_p),
               fmt_p(sm.max_p), s.negative_control ? "all rejected" : "all pass", sm.seconds,
               sm.expectation_met ? "as expected" : "UNEXPECTED");
    summary_json.push_back({{"sampler", s.name},
                            {"negative_control", s.negative_control},
                            {"passed", sm.passed},
                            {"total", sm.total},
                            {"min_p_value", sm.min_p},
                            {"max_p_value", sm.max_p},
                            {"expectation_met", sm.expectation_met},
                            {"seconds", sm.seconds}});
  }
  return all_met;
}

struct BatchTotals {
  int requested = 0;
  std::size_t done = 0;
  int references = 0;  // claimed pdfs integrated (once per configuration and pdf)
  double seconds = 0, reference_seconds = 0;
  bool partial = false, all_met = false;
};

void print_overall(const BatchTotals& t) {
  fmt::print("\nexpected counts (adaptive cubature of {} claimed pdfs x 2 binnings): {:.1f} s\n", t.references,
             t.reference_seconds);
  if (t.partial) {
    fmt::print("overall: INTERRUPTED: partial results, {} of {} validations in {:.1f} s (no verdict)\n", t.done,
               t.requested, t.seconds);
  } else {
    fmt::print("overall: {} ({} validations in {:.1f} s)\n",
               t.all_met ? "PASS: every correct sampler passes and every negative control is rejected" : "FAIL", t.done,
               t.seconds);
  }
}

// The batch's JSON but for its summary and results: the verdict, the run's parameters and totals.
nlohmann::json batch_json(const Args& a, const microsim::ValidationOptions& o, const BatchTotals& t) {
  nlohmann::json j;
  j["verdict"] = t.partial ? "interrupted" : t.all_met ? "pass" : "fail";
  j["partial"] = t.partial;
  j["validations_requested"] = t.requested;
  j["validations_done"] = t.done;
  j["samples"] = o.samples;
  j["seed"] = a.seed;
  j["precision"] = microsim::to_string(o.precision);
  j["significance"] = a.significance;
  j["per_validation_significance"] = o.significance;
  j["negative_control_p_threshold"] = kNegativeControlP;
  j["seconds"] = t.seconds;
  j["reference_seconds"] = t.reference_seconds;
  return j;
}

int run_all(const Args& a) {
  using namespace microsim;
  if (!a.alpha.empty() || a.theta) throw UsageError("--all runs its own grid: drop --alpha/--theta/--phi");
  install_interrupt_handler();
  const auto t0 = std::chrono::steady_clock::now();
  const auto samplers = sampler_registry();
  const int n_configs = int(std::size(kAllAlphas) * std::size(kAllThetas));
  const int n_validations = n_configs * int(samplers.size());
  ValidationOptions o = base_options(a);
  o.samples = std::uint64_t(a.samples.value_or(kAllDefaultSamples));
  // Too few samples for any test: refused before any work (each validation checks its own bound too).
  usage_errors_of([&] { require_samples_for_any_test(o.samples); });
  // Sidak over the batch: each validation (itself Sidak over its own tests) runs at the level that
  // keeps the family-wise level of the whole batch at --significance.
  o.significance = sidak_significance(a.significance, n_validations);

  print_all_header(a, o, samplers.size(), n_configs, n_validations);

  ProgressBar bar("validate --all", std::uint64_t(n_validations));
  nlohmann::json results = nlohmann::json::array();
  std::map<std::string, Summary> summary;
  bool partial = false;
  int index = 0;
  int reference_count = 0;
  double reference_seconds = 0;  // adaptive cubature of the claimed pdfs (once per configuration and pdf)
  for (const AlphaConfig& ac : kAllAlphas) {
    for (double theta : kAllThetas) {
      const GGX<double> ggx(ac.ax, ac.ay);
      const Vec3<double> wi = direction_from_degrees(theta, ac.phi);
      // One reference per claimed pdf, shared by the samplers that claim it.
      std::map<ClaimedPdf, std::shared_ptr<const ReferenceDistribution>> references;
      for (const SamplerInfo& s : samplers) {
        if (interrupted()) {
          partial = true;
          break;
        }
        auto& ref = references[s.claims];
        if (!ref) {
          const auto t_ref = std::chrono::steady_clock::now();
          ref = claimed_reference(s, ggx, wi, o.rows);
          ++reference_count;
          reference_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t_ref).count();
        }
        ValidationOptions vo = o;
        vo.seed = a.seed + std::uint64_t(index);  // independent streams per validation
        ++index;
        const auto t_start = std::chrono::steady_clock::now();
        ValidationReport r = usage_errors_of([&] { return validate_sampler(s, ggx, wi, vo, ref); });
        r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
        add_to_summary(summary[std::string(s.name)], s, r);
        results.push_back(render_all_row(s, ac, theta, r));
        bar.add(1);
      }
      if (partial) break;
    }
    if (partial) break;
  }
  bar.finish();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  nlohmann::json summary_json = nlohmann::json::array();
  const bool all_met = print_summary(samplers, summary, summary_json) && !partial;
  const BatchTotals totals{n_validations, results.size(), reference_count, seconds, reference_seconds, partial, all_met};
  print_overall(totals);
  if (!a.json.empty()) {
    nlohmann::json j = batch_json(a, o, totals);
    j["summary"] = summary_json;
    j["results"] = results;
    write_file_atomically(a.json, j.dump(2) + "\n");
  }
  if (partial) {
    fmt::print(stderr, "validate --all: interrupted: partial results{}\n",
               a.json.empty() ? "" : fmt::format(", written marked partial to '{}'", a.json));
    return microsim::app::kExitInterrupted;
  }
  return all_met ? microsim::app::kExitOk : microsim::app::kExitRejected;
}

int run(const Args& a) {
  microsim::app::check_distinct_outputs({{"--from", a.from}, {"--against", a.against == "ellipsoid" ? "" : a.against}},
                                        {{"--json", a.json}, {"--plot", a.plot}});
  const int modes = int(!a.sampler.empty()) + int(!a.from.empty()) + int(a.all);
  if (modes != 1) throw UsageError("give exactly one of --sampler NAME, --from FILE, --all");
  if (a.reflected && a.from.empty()) throw UsageError("--reflected applies to --from FILE only");
  if (a.use_float && !a.from.empty()) throw UsageError("--float applies to --sampler and --all, not to --from");
  if (a.samples && !a.from.empty()) throw UsageError("--samples does not apply to --from (the file gives the samples)");
  if (a.theta && !(*a.theta >= 0 && *a.theta < 90))
    throw UsageError(fmt::format("--theta must be in [0, 90) degrees, got {}", *a.theta));
  if (!std::isfinite(a.phi)) throw UsageError(fmt::format("--phi must be finite, got {}", a.phi));
  if (!(a.significance > 0 && a.significance < 1))
    throw UsageError(fmt::format("--significance must be in (0, 1), got {}", a.significance));
  if (!a.against.empty()) {
    if (a.all) throw UsageError("--against applies to --sampler and --from, not to --all");
    if (a.reflected) throw UsageError("--against: the traced oracle measures microfacet normals, not reflected directions");
    if (a.against != "ellipsoid" && fs::path(a.against).extension() != ".exr")
      throw UsageError(fmt::format("--against '{}': use 'ellipsoid' or a histogram .exr from `microsim trace vndf`", a.against));
  }
  if (a.rays && a.against != "ellipsoid") throw UsageError("--rays applies to --against ellipsoid only");
  if (!a.json.empty()) {
    const fs::path parent = fs::path(a.json).parent_path();
    if (!parent.empty() && !fs::is_directory(parent))
      throw UsageError(fmt::format("--json: directory '{}' does not exist", parent.string()));
  }
  if (!a.plot.empty()) {
    if (a.all) throw UsageError("--plot draws one validation; it does not apply to --all");
    if (fs::path(a.plot).extension() != ".svg")
      throw UsageError(fmt::format("--plot: '{}' must end in .svg (the figure is SVG)", a.plot));
    const fs::path parent = fs::path(a.plot).parent_path();
    if (!parent.empty() && !fs::is_directory(parent))
      throw UsageError(fmt::format("--plot: directory '{}' does not exist", parent.string()));
  }
  return a.all ? run_all(a) : run_single(a);
}

microsim::app::CommandRegistration reg{"validate", [](CLI::App& app) {
  auto args = std::make_shared<Args>();
  auto* sub = app.add_subcommand(
      "validate",
      "Statistical validation of a GGX sampler (chi-square in sphere and lobe bins, returned pdf, E[weight], pdf "
      "integral). Exit 0 pass, 1 rejected, 2 bad usage/input.");
  sub->add_option("--sampler", args->sampler, "sampler of the zoo to validate (" + names_list() + ")");
  sub->add_option("--from", args->from,
                  "validate samples from FILE instead: .npy (float32/float64, shape (N,3)) or text, one x y z per line");
  sub->add_flag("--reflected", args->reflected,
                "with --from: rows are reflected directions (tested against the VNDF reflection pdf), not normals");
  sub->add_flag("--all", args->all, "validate the whole zoo over the standard grid (Sidak-corrected over the batch)");
  sub->add_option("--alpha", args->alpha,
                  "roughness AX or AX,AY, each in [1e-4, 10], anisotropy at most 1:1000 (docs/conventions.md)");
  using microsim::app::add_number_option;
  add_number_option(sub, "--theta", args->theta, microsim::app::real(), "view zenith angle in degrees, [0, 90)");
  add_number_option(sub, "--phi", args->phi, microsim::app::real(), "view azimuth in degrees (default 0)");
  add_number_option(sub, "--samples", args->samples, microsim::app::whole(1, microsim::kMaxSamples),
                    microsim::app::at_most("number of samples (default 1000000; 200000 per validation with --all)",
                                           microsim::kMaxSamples));
  add_number_option(sub, "--seed", args->seed, microsim::app::whole(), "random seed (default 1)");
  sub->add_flag("--float", args->use_float, "run the sampler's float version (default: double)");
  add_number_option(sub, "--rows", args->rows, microsim::app::binning_rows(3),
                    fmt::format("rows of the sphere and lobe binnings (odd, 3..{}; cols = 2 rows; default 31)",
                                microsim::kMaxBinningRows));
  add_number_option(sub, "--significance", args->significance, microsim::app::real(),
                    "family-wise significance level (default 0.01)");
  sub->add_option("--json", args->json, "write the results as JSON to PATH (atomically)");
  sub->add_option("--against", args->against,
                  "compare with the traced oracle instead of the analytic pdf (two-sample chi-square): 'ellipsoid' "
                  "(traced now) or a histogram HIST.exr from `microsim trace vndf`");
  add_number_option(sub, "--rays", args->rays, microsim::app::whole(1, microsim::kMaxRays),
                    microsim::app::at_most("rays traced for --against ellipsoid (default 4000000)",
                                           microsim::kMaxRays));
  sub->add_option("--plot", args->plot,
                  "also draw FIG.svg: observed and expected counts and Pearson residuals in the sphere and lobe bins");
  microsim::app::on_selected(sub, [args] { return run(*args); });
}};

}  // namespace
