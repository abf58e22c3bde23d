// stats: two scattering results compared order by order (`microsim compare-scattering`): measured
// histograms (explicit surfaces, the Smith random walk) and expectations (the analytic single scattering).
//
// Everything is per launched path: a lobe is, per bin, the estimated expected weight per launched path and
// the variance of that estimate (sum of squared weights / paths^2, the variance of a weighted histogram's
// bin; 0 for an expectation). Per channel and order (1, 2, 3, 4, 5+ and the total over orders; an
// expectation has order 1 only) a comparison gives
//   - the total-variation distance of the two lobes' SHAPES, 1/2 sum |p_a - p_b| with p = lobe / albedo,
//     and its noise floor, the value expected from the noise alone: 1/2 sum sqrt(2/pi) sigma_i with
//     sigma_i^2 = var(p_a,i) + var(p_b,i) (the mean of |N(0, sigma^2)|);
//   - the albedos (sum over bins) with their standard errors, their difference with its standard error,
//     and the two-sided p-value of that difference (normal);
//   - the weighted chi-square homogeneity test of the shapes (stats/chi2.h weighted_homogeneity,
//     Gagunashvili 2010), or why it could not run (too little data: never a pass).
#pragma once

#include "stats/chi2.h"
#include "stats/scatter_io.h"

#include <optional>
#include <string>
#include <vector>

namespace microsim {

inline constexpr int kTotalOrder = -1;  // the order bin of the total over orders

// "order1" .. "order4", "order5plus", "total" (kTotalOrder).
std::string scatter_order_name(int order_bin);

struct ScatterLobe {
  std::vector<double> mean, variance;  // per bin, per launched path
  Estimate albedo;                     // sum over the bins
  bool exact = false;                  // an expectation
};

// The lobe of one channel and order bin (kTotalOrder: all orders) of a file; nullopt when the file does not
// model it (an expectation beyond order 1).
std::optional<ScatterLobe> scatter_lobe(const ScatterFile& file, int channel, int order_bin);

struct LobeComparison {
  int channel = 0;
  int order_bin = 0;  // kTotalOrder for the total
  double tv = 0, tv_noise_floor = 0;  // NaN when a lobe is empty
  Estimate albedo_a, albedo_b, difference;
  double difference_p = 1;  // two-sided p of the albedo difference
  std::optional<ChiSquareResult> chi2;  // nullopt: too little data (see insufficient)
  std::string insufficient;             // why the homogeneity test could not run
};

// The two-sided p of the difference of two estimates, with both standard errors (normal); 1 or 0 for an exact
// difference of zero or not.
double difference_p(const Estimate& a, const Estimate& b);

// The family of a comparison's tests: per lobe comparison, the chi-square of its shapes and its albedo difference,
// each at the Sidak share of the family-wise `level`. Every comparison must have its chi-square test.
struct ComparisonFamily {
  int tests = 0;
  double per_test = 0;
  bool rejected = false;
};
ComparisonFamily comparison_family(const std::vector<const LobeComparison*>& lobes, double level);

// Compares two lobes of the same binning (std::invalid_argument when their sizes differ).
LobeComparison compare_lobes(const ScatterLobe& a, const ScatterLobe& b, const ChiSquareOptions& options);

// The chi-square options of a scattering comparison: cells of at least 10 effective entries (weighted
// bins estimate their own variance, so twice Cochran's 5 of an expected count).
inline ChiSquareOptions effective_entry_options() {
  ChiSquareOptions o;
  o.min_expected = 10;
  return o;
}

// Per bin, the residual of the shapes, (p_a - p_b) / sqrt(var p_a + var p_b) with p = lobe / albedo (for the
// figure); NaN where a measured lobe's bin has fewer than min_effective effective entries (mean^2 / variance),
// 0 where both are empty.
std::vector<double> shape_residuals(const ScatterLobe& a, const ScatterLobe& b, double min_effective);

struct ScatterComparisonOptions {
  std::vector<int> order_bins{0, 1, 2, 3, 4, kTotalOrder};  // which orders to compare (when both files model them)
  ChiSquareOptions chi2 = effective_entry_options();          // min_expected: effective entries per cell
};

// The comparisons of two files: every channel, every selected order both model. Throws
// std::invalid_argument naming both when their binnings or channels differ, or when they share no order.
std::vector<LobeComparison> compare_scatter_files(const ScatterFile& a, const std::string& a_name, const ScatterFile& b,
                                                  const std::string& b_name, const ScatterComparisonOptions& options);

}  // namespace microsim
