// experiment: the verdict of a run (verdict.h).
#include "experiment/verdict.h"
#include "experiment/measurement.h"

namespace microsim::experiment {

std::string to_string(Verdict verdict) {
  switch (verdict) {
    case Verdict::pass: return "pass";
    case Verdict::fail: return "fail";
    case Verdict::none: return "none";
    case Verdict::incomplete: return "incomplete";
  }
  return "none";
}

namespace {
// The report of the test a measurement ran to its end (the registry's kind_test_report), or null: it tests
// nothing, its test was cut short (it runs again when resumed), or its traced reference could not serve its
// sample count (verdict "none", compare.h reference_bias).
const nlohmann::json* test_report(const MeasurementResult& m) {
  const nlohmann::json* report = m.ran && !m.partial ? kind_test_report(m.values) : nullptr;
  return report != nullptr && report->at("verdict") != "none" ? report : nullptr;
}
}  // namespace

bool validation_tested(const MeasurementResult& m) { return test_report(m) != nullptr; }

bool validation_rejected(const MeasurementResult& m) {
  const nlohmann::json* report = test_report(m);
  return report != nullptr && report->at("verdict") == "fail";
}

RunVerdict run_verdict(const ExperimentResults& results) {
  RunVerdict v;
  for (const MeasurementResult& m : results.measurements) {
    v.tested += validation_tested(m) ? 1 : 0;
    if (validation_rejected(m)) v.rejected.push_back(m.decision.label);
    if (m.decision.tests && !m.partial && !validation_tested(m)) v.untested.push_back(m.decision.label);
  }
  v.verdict = !v.rejected.empty()                   ? Verdict::fail
              : results.partial                     ? Verdict::incomplete
              : v.tested > 0 && v.untested.empty() ? Verdict::pass
                                                    : Verdict::none;
  return v;
}

bool all_targets_met(const ExperimentResults& results) {
  bool met = !results.partial;
  for (const MeasurementResult& m : results.measurements) met = met && (!m.ran || m.met);
  return met;
}

nlohmann::json verdict_json(const RunVerdict& verdict) {
  return {{"verdict", to_string(verdict.verdict)}, {"rejected", verdict.rejected}, {"tested", verdict.tested},
          {"untested", verdict.untested}};
}

}  // namespace microsim::experiment
