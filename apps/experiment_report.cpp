#include "experiment_report.h"

#include "experiment/verdict.h"

#include <fmt/format.h>

#include <cstdio>

namespace microsim::app {
namespace {

std::string units_text(const experiment::Decision& d) {
  if (d.units == 0) return d.unit.empty() ? "-" : "?";
  return fmt::format("{} {}", d.units, d.unit);
}

std::string seconds_text(double s) { return s > 0 ? fmt::format("{:.3g} s", s) : "-"; }

// A measurement's statistical test: a validation's pass or REJECTED, "-" for the kinds that test nothing.
std::string test_text(const experiment::MeasurementResult& m) {
  if (!experiment::validation_tested(m)) return "-";
  return experiment::validation_rejected(m) ? "REJECTED" : "pass";
}

// "All targets met: yes. Verdict: FAIL (rejected: NAME, ...)": enough samples, and what the tests found.
std::string summary_line(const experiment::ExperimentResults& results) {
  const experiment::RunVerdict v = experiment::run_verdict(results);
  std::string verdict;
  switch (v.verdict) {
    case experiment::Verdict::fail: verdict = fmt::format("FAIL (rejected: {})", fmt::join(v.rejected, ", ")); break;
    case experiment::Verdict::pass: verdict = fmt::format("pass ({} test(s), none rejected)", v.tested); break;
    case experiment::Verdict::none:
      verdict = v.untested.empty() ? "none (no statistical test in this run)"
                                   : fmt::format("none ({} test(s) ran, none rejected; no verdict from: {})", v.tested,
                                                 fmt::join(v.untested, ", "));
      break;
    case experiment::Verdict::incomplete: verdict = "incomplete (interrupted; none rejected so far)"; break;
  }
  return fmt::format("All targets met: {}. Verdict: {}", experiment::all_targets_met(results) ? "yes" : "no", verdict);
}

}  // namespace

void print_plan_table(const experiment::ExperimentPlan& plan, const experiment::ExperimentSpec& spec) {
  fmt::print("plan of {} ({} measurements; pilots took {:.3g} s)\n\n", spec.name, plan.decisions.size(),
             plan.pilot_seconds);
  fmt::print("| # | measurement | model | count | order cap | predicted | runnable |\n|---|---|---|---|---|---|---|\n");
  for (std::size_t i = 0; i < plan.decisions.size(); ++i) {
    const experiment::Decision& d = plan.decisions[i];
    fmt::print("| {} | {} | {} | {} | {} | {} | {} |\n", i, d.label, to_string(d.model.model), units_text(d),
               d.order_cap > 0 ? std::to_string(d.order_cap) : "-", seconds_text(d.predicted_seconds),
               d.runnable ? "yes" : "no");
  }
  fmt::print("\npredicted total: {}\n\nreasons:\n", seconds_text(plan.predicted_seconds));
  for (std::size_t i = 0; i < plan.decisions.size(); ++i) {
    const experiment::Decision& d = plan.decisions[i];
    fmt::print("  [{}] model: {}\n      count: {}\n", i, d.model.reason, d.count_reason);
    if (!d.cap_reason.empty()) fmt::print("      order cap: {}\n", d.cap_reason);
    if (!d.surface.kind.empty())
      fmt::print("      surface: {} {}, {}^2, l {} cells, NDF matched {}: {}\n", d.surface.kind, d.surface.name,
                 d.surface.resolution, d.surface.corr_cells, d.surface.ndf_match, d.surface.reason);
    if (!d.runnable) fmt::print("      not run: {}\n", d.not_runnable);
  }
}

void print_results_table(const experiment::ExperimentResults& results) {
  fmt::print("\n| # | measurement | model | target | achieved | met | test | rounds | units | seconds |\n"
             "|---|---|---|---|---|---|---|---|---|---|\n");
  for (std::size_t i = 0; i < results.measurements.size(); ++i) {
    const experiment::MeasurementResult& m = results.measurements[i];
    if (!m.ran) {
      fmt::print("| {} | {} | {} | - | - | not run | - | - | - | - |\n", i, m.decision.label, to_string(m.decision.model.model));
      continue;
    }
    fmt::print("| {} | {} | {} | {:.3g} | {:.3g} | {}{} | {} | {} | {} | {:.3g} |\n", i, m.decision.label,
               to_string(m.decision.model.model), m.target, m.achieved, m.met ? "yes" : "NO",
               m.partial ? " (partial)" : "", test_text(m), m.rounds.size(), m.units, m.seconds);
  }
  fmt::print("\n{}\n", summary_line(results));
}

void print_measurement_line(const experiment::MeasurementResult& m) {
  if (!m.ran) {
    fmt::print(stderr, "run: {}: not run ({})\n", m.decision.label, m.decision.not_runnable);
    return;
  }
  fmt::print(stderr, "run: {}: {} after {} round(s), achieved {:.3g} (target {:.3g}), {:.3g} s{}{}\n", m.decision.label,
             m.met ? "met" : "NOT met", m.rounds.size(), m.achieved, m.target, m.seconds, m.partial ? ", partial" : "",
             experiment::validation_rejected(m) ? "; its test REJECTED" : "");
}


void print_overall_line(const experiment::ExperimentPlan& plan, std::size_t done) {
  double past = 0, left = 0;
  for (std::size_t i = 0; i < plan.decisions.size(); ++i) (i < done ? past : left) += plan.decisions[i].predicted_seconds;
  constexpr int kWidth = 30;
  const double fraction = past + left > 0 ? past / (past + left) : 1.0;
  const int filled = int(fraction * kWidth);
  fmt::print(stderr, "run: overall [{}{}] {} of {} measurements, predicted time left {}\n", std::string(filled, '#'),
             std::string(kWidth - filled, '.'), done, plan.decisions.size(), seconds_text(left));
}

}  // namespace microsim::app
