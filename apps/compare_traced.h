// microsim compare-scattering: the table on stdout and the figure of a comparison (measure/compare_scattering.h
// compares; this file renders).
#pragma once

#include "measure/compare_scattering.h"

#include <string>

namespace microsim::app {

void print_scatter_comparison(const ScatterComparison& c);
void print_traced_comparison(const TracedComparisonSet& c);

// The SVG figure of channel 0: one row per order (scatter files) or binning (traced histograms), the inputs'
// lobes and every pair's shape residuals.
std::string scatter_comparison_figure(const ScatterComparison& c);
std::string traced_comparison_figure(const TracedComparisonSet& c);

}  // namespace microsim::app
