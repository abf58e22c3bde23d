// measure: `compare-scattering` as a library call (the command line and Python's compare_scattering): two or
// three scattering results side by side with one verdict.
//
// Scatter files (`microsim scatter`: explicit surfaces, the Smith random walk, the analytic single
// scattering, or the analytic expectation computed for the first file's configuration) are compared order by
// order; traced histograms (`microsim trace vndf`: two assemblies of one NDF, say) binning by binning. Each
// comparison (stats/scatter_compare.h) is the TV distance of the shapes with its noise floor, the albedo (or
// hit-fraction) difference with its p-value, and the weighted chi-square homogeneity test of the shapes
// (Gagunashvili 2010, "Chi-square tests for comparing weighted histograms", NIM A 614, 287). The verdict
// holds every test at the family-wise level (Sidak). Too little data for a test is an error
// (std::invalid_argument naming every such comparison), never a pass.
#pragma once

#include "core/run_control.h"
#include "stats/histogram_compare.h"
#include "stats/histogram_io.h"
#include "stats/scatter_compare.h"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace microsim {

// One compared result: its file (or "analytic"), label (A, B, C) and content.
struct ScatterInput {
  std::string name, label;
  ScatterFile file;
};
struct TracedInput {
  std::string name, label;
  TracedHistogram histogram;
};

template <typename Comparisons>
struct InputPair {
  std::size_t a = 0, b = 0;  // indices of the inputs
  Comparisons comparisons;
};

// Scatter files: every pair, every channel and order both model.
struct ScatterComparison {
  std::vector<ScatterInput> inputs;
  std::vector<int> orders;  // order bins compared (kTotalOrder: the total)
  std::vector<InputPair<std::vector<LobeComparison>>> pairs;
  ComparisonFamily family;
  double level = 0;
};

// Traced histograms: every pair, every binning both have; `note` warns that tiles differ by their facets.
struct TracedComparisonSet {
  std::vector<TracedInput> inputs;
  std::vector<InputPair<std::vector<TracedComparison>>> pairs;
  ComparisonFamily family;
  double level = 0;
  std::string note;
};

struct CompareScatteringRequest {
  std::vector<std::string> files;  // 2 or 3 (1 or 2 with analytic), all scatter files or all traced histograms
  bool analytic = false;           // add the analytic single scattering of the first file's configuration
  std::string orders;              // scatter files: "1,2,3,4,5+,total" when empty
  double level = 0.01;             // family-wise significance level, in (0, 1)
};

// Exactly one of the two is set.
struct CompareScatteringResult {
  std::optional<ScatterComparison> scatter;
  std::optional<TracedComparisonSet> traced;
  bool rejected() const { return scatter ? scatter->family.rejected : traced->family.rejected; }
};

// The order bins of a list of 1, 2, 3, 4, 5+, total (std::invalid_argument naming the bad or repeated one).
std::vector<int> parse_scatter_orders(std::string_view text);

// Reads the files and compares them. std::invalid_argument (bad input: a missing or foreign file, kinds
// mixed, a file given twice, options that do not apply, too little data) naming the file or value;
// Cancelled when run is cancelled during the analytic cubature.
CompareScatteringResult compare_scattering_files(const CompareScatteringRequest& request, const RunControl& run);

// The comparison as the command line's --json writes it.
nlohmann::json to_json(const ScatterComparison& c);
nlohmann::json to_json(const TracedComparisonSet& c);
nlohmann::json to_json(const CompareScatteringResult& r);

}  // namespace microsim
