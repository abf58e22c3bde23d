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

// The results of a run as a table (stdout): measurement, model, target, achieved, met, rounds, cost.
void print_results_table(const experiment::ExperimentResults& results);

// One line on stderr when a measurement is done.
void print_measurement_line(const experiment::MeasurementResult& m);

}  // namespace microsim::app
