// stats: an expected scattering result, the exact counterpart of a measured ScatterHistogram
// (stats/scatter_histogram.h) for comparisons: per channel and bin, the expected weight per launched path
// of the paths that leave after ONE facet event (single scattering), e.g. the analytic single-scattering
// BSDF binned by cubature (scatter/analytic_scatter.h). Orders 2 and more are not modelled: comparisons
// with an expectation cover order 1 only.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace microsim {

struct ScatterExpectation {
  std::string binning_id;                  // the binning's description, as ScatterHistogram's
  std::vector<bool> reflection_bins;       // per bin: in the upper hemisphere
  std::vector<std::string> channel_names;  // one per weight channel
  // order1[c][b]: expected weight per launched path of order 1 in bin b, channel c (finite, >= 0).
  std::vector<std::vector<double>> order1;
  // Per channel: the summed error estimate of the cubature (0 for an exact expectation).
  std::vector<double> error_estimate;
  std::string producer;     // "scatter analytic", ...
  std::string measurement;  // the canonical parameters (as Provenance::measurement)

  int channels() const { return int(channel_names.size()); }
  std::size_t bins() const { return reflection_bins.size(); }
  bool operator==(const ScatterExpectation&) const = default;
};

}  // namespace microsim
