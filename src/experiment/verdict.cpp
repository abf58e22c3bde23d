// experiment: the verdict of a run (verdict.h).
#include "experiment/verdict.h"

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

// A validation's values hold the validator's report (validate.h to_json), whose verdict is "pass" or "fail";
// a validation cut short holds none (it runs again when resumed), and one whose traced reference could not
// serve its sample count holds "none" (compare.h reference_bias): neither was tested.
bool validation_tested(const MeasurementResult& m) {
  return m.ran && !m.partial && m.values.is_object() && m.values.contains("validation") &&
         m.values.at("validation").is_object() && m.values.at("validation").contains("verdict") &&
         m.values.at("validation").at("verdict") != "none";
}

bool validation_rejected(const MeasurementResult& m) {
  return validation_tested(m) && m.values.at("validation").at("verdict") == "fail";
}

RunVerdict run_verdict(const ExperimentResults& results) {
  RunVerdict v;
  for (const MeasurementResult& m : results.measurements) {
    v.tested += validation_tested(m) ? 1 : 0;
    if (validation_rejected(m)) v.rejected.push_back(m.decision.label);
  }
  v.verdict = !v.rejected.empty() ? Verdict::fail
              : results.partial   ? Verdict::incomplete
              : v.tested > 0      ? Verdict::pass
                                  : Verdict::none;
  return v;
}

bool all_targets_met(const ExperimentResults& results) {
  bool met = !results.partial;
  for (const MeasurementResult& m : results.measurements) met = met && (!m.ran || m.met);
  return met;
}

nlohmann::json verdict_json(const RunVerdict& verdict) {
  return {{"verdict", to_string(verdict.verdict)}, {"rejected", verdict.rejected}, {"tested", verdict.tested}};
}

}  // namespace microsim::experiment
