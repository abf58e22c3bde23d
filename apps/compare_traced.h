// microsim compare-scattering on traced direction histograms (files of `microsim trace vndf`): the visible
// normals of two or three runs compared binning by binning (stats/histogram_compare.h), with the verdict,
// the JSON and the figure of the scattering comparison.
#pragma once

#include "core/estimate.h"
#include "stats/histogram_io.h"

#include <nlohmann/json.hpp>

#include <string>
#include <utility>
#include <vector>

namespace microsim::app {

struct TracedInput {
  std::string name;  // the file
  TracedHistogram histogram;
};

// A finite number, or null; an estimate as {value, standard_error} (the comparisons' JSON).
nlohmann::json json_number(double v);
nlohmann::json json_estimate(const Estimate& e);

// Compares every pair, writes --json and --svg (when named), prints the table; returns the exit code (0
// passed, 1 rejected). Too little data or no shared binning is a UsageError (nothing written).
int compare_traced_inputs(const std::vector<TracedInput>& inputs, double level, const std::string& json,
                          const std::string& svg);

}  // namespace microsim::app
