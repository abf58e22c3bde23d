// experiment: the verdict of a run (`microsim run`): what its statistical tests found, apart from whether each
// target was met. A validation measurement tests a sampler or a dump against a reference (validate/validate.h:
// pass or fail at the spec's level); every other kind measures values to a target accuracy and tests nothing.
// `met` says a measurement ran enough samples for its target; the verdict says whether a test rejected. A
// validation that met its target and rejected is a failure of the run, never a success:
//   fail        at least one validation rejected (final: a finished measurement is kept when the run resumes);
//   incomplete  the run was interrupted before every measurement ran, and none rejected so far;
//   pass        every measurement ran and every validation's test ran to its end, none rejected;
//   none        every measurement ran, none rejected, and not every validation tested: the spec asks for no
//               test, or a validation could not give a verdict (not runnable, or its traced reference could not
//               serve its sample count: `untested` names them). A test that did not run is never a pass.
// A validation the plan could not run (not runnable) tests nothing: the plan and the report say why.
// Derived from the results alone (the validations' values), so a resumed run gives the same verdict. This is
// the one place that decides it: results.json (results_json), the report and the command's exit code read it.
#pragma once

#include "experiment/run.h"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <string>
#include <vector>

namespace microsim::experiment {

enum class Verdict { pass, fail, none, incomplete };
std::string to_string(Verdict verdict);  // "pass", "fail", "none", "incomplete"

struct RunVerdict {
  Verdict verdict = Verdict::none;
  std::vector<std::string> rejected;  // the labels of the validations that rejected, in plan order
  std::size_t tested = 0;             // the validations whose test ran to its end (passed or rejected)
  std::vector<std::string> untested;  // the labels of the validations that ran but could not test, in plan order
};

// Whether a measurement's test ran to its end (its values hold its kind's test report, measurement.h
// kind_test_report: a validation's); and whether that test rejected.
bool validation_tested(const MeasurementResult& m);
bool validation_rejected(const MeasurementResult& m);

RunVerdict run_verdict(const ExperimentResults& results);

// Enough samples: the run is complete and every measurement that ran met its target (results.json's
// all_targets_met). Says nothing of what the tests found: a rejected validation may have met its target.
bool all_targets_met(const ExperimentResults& results);

// results.json's members of the verdict: "verdict", "rejected" (labels), "tested" (a count) and "untested"
// (labels).
nlohmann::json verdict_json(const RunVerdict& verdict);

}  // namespace microsim::experiment
