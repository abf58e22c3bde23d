// microsim CLI: what `microsim plan` and `microsim run` print and write: the plan table (stdout), a line per
// finished measurement (stderr), and the JSON documents (plan, results.json).
#pragma once

#include "experiment/plan.h"
#include "experiment/run.h"
#include "experiment/spec.h"

#include <nlohmann/json.hpp>

#include <string>

namespace microsim::app {

// One row per measurement: quantity, model, units, order cap, predicted time, then the reasons.
void print_plan_table(const experiment::ExperimentPlan& plan, const experiment::ExperimentSpec& spec);

// The results of a run as a table (stdout): measurement, model, target, achieved, met, the validation's test
// (pass, REJECTED), rounds, cost; then the summary line "All targets met: yes. Verdict: FAIL (rejected: NAME,
// ...)" (experiment/verdict.h: enough samples is one thing, what the tests found another).
void print_results_table(const experiment::ExperimentResults& results);

// One line on stderr when a measurement is done.
void print_measurement_line(const experiment::MeasurementResult& m);
// The overall progress on stderr after `done` measurements: a bar of the plan's predicted time done, and the
// predicted time left (the per-measurement bars are the library's stages, apps/progress_bar.h).
void print_overall_line(const experiment::ExperimentPlan& plan, std::size_t done);

}  // namespace microsim::app
