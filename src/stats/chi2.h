// microsim: a reusable chi-square harness for histograms of directions (or anything else binned).
//
// - goodness_of_fit: Pearson's chi-square test of observed counts against expected probabilities
//   (Pearson 1900). Cells whose expected count is below `min_expected` (5, the classical rule of
//   thumb, e.g. Cochran 1954) are pooled into one cell, smallest first; if the pool itself stays below
//   the threshold, the next smallest cells join it. The statistic sum (O - E)^2 / E has
//   cells - 1 degrees of freedom; the p-value is the upper tail of the chi-squared distribution
//   (Boost.Math, complement form: accurate down to 1e-300). A sample in a cell whose expected
//   probability is 0, or outside every cell, is impossible under the null: the test rejects at once
//   with p = 0. (Mitsuba 3's chi2.py follows the same scheme; this is an independent implementation.)
// - two_sample_homogeneity: chi-square test that two histograms with unequal totals Na, Nb come from
//   the same distribution: sum (K1 a_i - K2 b_i)^2 / (a_i + b_i), K1 = sqrt(Nb / Na),
//   K2 = sqrt(Na / Nb) (NIST/SEMATECH e-Handbook of Statistical Methods, sec. 1.3.5.15, "Chi-square
//   two sample test"; Press et al., Numerical Recipes, 3rd ed., sec. 14.3), sparse cells pooled the same
//   way, cells - 1 degrees of freedom.
// - Sidak correction for a batch of n independent tests at family-wise level alpha (Sidak 1967):
//   each test is run at 1 - (1 - alpha)^(1/n).
#pragma once

#include <nlohmann/json_fwd.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace microsim {

// One cell of a report: a bin of the caller's histogram (bin >= 0) or the pooled cell (bin = -1).
struct CellReport {
  int bin = -1;
  double observed = 0;
  double expected = 0;      // expected count under the null
  double contribution = 0;  // its term of the statistic
  std::string location;     // where the bin is (from ChiSquareOptions::describe_cell), or "pooled (k cells)"
};

struct ChiSquareResult {
  std::string test;        // "goodness_of_fit", "two_sample_homogeneity" or "weighted_homogeneity"
  double statistic = 0;
  int dof = 0;
  double p_value = 1;
  double significance = 0.01;  // the level the verdict below used
  bool rejected = false;       // p_value < significance (or an impossible sample)
  std::string reason;          // why the test rejected at once, or why it could not run ("" otherwise)
  double samples = 0;          // N (goodness of fit) or Na + Nb (two samples)
  int cells = 0;               // cells in the statistic, the pooled cell included
  int pooled_cells = 0;        // histogram cells merged into the pooled cell
  std::vector<CellReport> worst_cells;  // largest contributions first
};

struct ChiSquareOptions {
  double min_expected = 5;     // pooling threshold on the expected count
  double significance = 0.01;  // level of the verdict `rejected`
  int worst_cells = 8;         // how many cells to report
  // Names a bin for the report (e.g. DirectionBinning::describe_bin); empty: "bin i".
  std::function<std::string(int)> describe_cell;
};

// observed[i]: count in cell i; expected_probability[i]: its probability under the null; n_samples:
// the number of samples drawn (the expected count of cell i is n_samples * expected_probability[i]);
// outside_domain: samples that fell in no cell at all (rejects when > 0). The sizes must agree
// (std::invalid_argument otherwise).
ChiSquareResult goodness_of_fit(std::span<const double> observed, std::span<const double> expected_probability,
                                double n_samples, const ChiSquareOptions& options = {}, double outside_domain = 0);

// Two histograms over the same cells; throws std::invalid_argument when the sizes differ or a
// histogram is empty.
ChiSquareResult two_sample_homogeneity(std::span<const double> counts_a, std::span<const double> counts_b,
                                       const ChiSquareOptions& options = {});

// Two WEIGHTED histograms over the same cells (Gagunashvili 2010, "Chi-square tests for comparing weighted
// histograms", Nucl. Instrum. Meth. A 614, 287-296, arXiv:0905.4221; first in his 2006 "Comparison of
// weighted and unweighted histograms", arXiv:physics/0605123): w1[i], w2[i] are the cells' sums of weights,
// s1[i], s2[i] the sums of their squared weights (the variances of the w; any scale per histogram, e.g.
// per launched path: w / n and s / n^2). An exact expectation (no noise) is a histogram with s = 0 (only one of
// the two may be). H0: w2 = lambda w1 in expectation for some lambda (the same distribution, whatever the
// totals). Per cell, minimising over the cell's expectation q of (w1 - q)^2 / s1 + (w2 - lambda q)^2 / s2
// leaves (w2 - lambda w1)^2 / (s2 + lambda^2 s1), Gagunashvili's statistic when lambda = W2 / W1. Here lambda
// is fitted too (the minimum of the sum over lambda, found on a grid in log lambda then by Brent's method):
// the statistic is then the minimum of a weighted least-squares fit of r + 1 parameters to 2 r values,
// chi-squared with r - 1 degrees of freedom whatever the weights (with lambda fixed at W2 / W1 the statistic
// is inflated when the mean squared weight differs between cells), and for an exact w1 it is Gagunashvili's
// test of a weighted histogram against given probabilities with the fitted total.
// Pooling: the effective count of a cell in a histogram is w^2 / s (infinite for an exact one); cells whose
// smaller effective count is below options.min_expected are pooled as in goodness_of_fit; cells empty in
// both are left out. Throws InsufficientData when fewer than two cells remain (too little data is never a
// pass), std::invalid_argument when sizes differ, a value is negative or not finite, a histogram is empty,
// or both are exact.
ChiSquareResult weighted_homogeneity(std::span<const double> w1, std::span<const double> s1, std::span<const double> w2,
                                     std::span<const double> s2, const ChiSquareOptions& options = {});

// Too few samples for a test to be able to reject: never a pass. `given` samples were
// supplied, `needed` are required by the rule of the test (see goodness_of_fit_minimum_samples).
struct InsufficientData : std::invalid_argument {
  InsufficientData(const std::string& what, std::uint64_t given_samples, std::uint64_t needed_samples)
      : std::invalid_argument(what), given(given_samples), needed(needed_samples) {}
  std::uint64_t given = 0, needed = 0;
};
// "No number of samples suffices": every cell but one has probability 0.
inline constexpr std::uint64_t kNoSampleCountSuffices = UINT64_MAX;

// The smallest number of samples n for which goodness_of_fit with these expected probabilities can
// reject at all, i.e. leaves at least two cells (one degree of freedom) after pooling. With the pooling
// rule above (every cell below min_expected pooled, the pool grown from the smallest cells until it
// reaches min_expected) that is exactly when the largest cell and the rest both expect at least
// min_expected: n p_max >= min_expected and n (1 - p_max) >= min_expected, so
//   n >= min_expected / min(p_max, 1 - p_max)   (at least 2 min_expected = 10 samples for any test).
// Computed with the same arithmetic as the test (kNoSampleCountSuffices when one cell holds all the mass).
std::uint64_t goodness_of_fit_minimum_samples(std::span<const double> expected_probability, double min_expected = 5);
// The same bound for any binning: two cells of min_expected.
constexpr std::uint64_t minimum_samples_for_any_test(double min_expected = 5) {
  return std::uint64_t(2 * min_expected + 0.999999);
}

// Per-test level that keeps the family-wise level alpha over n independent tests: 1 - (1 - alpha)^(1/n)
// (Sidak 1967).
double sidak_significance(double alpha, int n_tests);
// The family-wise p-value of the smallest of n p-values: 1 - (1 - p_min)^n.
double sidak_adjusted_p(double p_min, int n_tests);

// Two-sided p of a sample mean's deviation from its expectation, given its standard error `se` and
// skewness `skew` under the null: the translated gamma with those three moments (Seal 1977, "Approximations
// to risk theory's F(x, t) by means of the gamma distribution", ASTIN Bulletin 9), the normal when
// |skew| < 1e-3. A mean of few nonzero terms (a bin that few samples reach) is skewed; the normal's tails
// then misstate p by a factor of a few at the levels a Sidak correction over hundreds of bins asks.
// p = 2 min(P(X <= deviation), P(X >= deviation)), at most 1; 0 for a non-finite deviation.
// `least`: the smallest deviation the mean can take (-m1 for a mean of terms >= 0 whose mean is m1). Where the
// approximation puts more than kSkewedMeanSupportMass of its mass below it (a mean of a few rare nonzero terms:
// the gamma then sits mostly where the mean cannot be, and calls the likeliest outcome, no term at all, extreme),
// p is Chebyshev's bound min(1, (se / deviation)^2), which holds for any distribution.
inline constexpr double kSkewedMeanSupportMass = 1e-6;
double skewed_mean_p(double deviation, double se, double skew, double least = -INFINITY);

// The largest share a sample mean's test accepts; an honest weight sample of 1e4 bounded values holds ~1e-3.
inline constexpr double kMaxDominantShare = 0.1;

// The value of a sample that holds the largest share of its sum of squared deviations from the mean, with
// `zeros` more values of 0 (lost samples, weighing 0); non-finite values are skipped. A test of a mean from
// its own standard error needs every share small: the central limit theorem holds for sums of asymptotically
// negligible terms only (Lindeberg 1922; Feller 1935: max_i var_i / sum var -> 0 is necessary). One value
// holding a large share (a firefly) raises the mean and the standard error that should expose it together:
// z ~ sqrt(number of such values), whatever their size.
struct DominantValue {
  double share = 0;         // in [0, 1]
  std::uint64_t index = 0;  // in x (the order of add())
  double value = 0;
  double count = 0;         // values (zeros included)
  // More than a mean's test accepts: kMaxDominantShare, or for few values five times what the largest of n
  // normal values holds (2 ln n / n), which an honest small sample can reach.
  double limit() const { return std::max(kMaxDominantShare, 10 * std::log(count) / count); }
  bool dominates() const { return count > 1 && share > limit(); }
  // "the sample of row I (weight W) holds S% of the weights' spread (at most L% for a mean's test of N
  // samples): a firefly", what a failed test's detail says.
  std::string firefly() const;
};
DominantValue dominant_value(std::span<const double> x, std::uint64_t zeros = 0);
// The same over values streamed one at a time (Welford's running sum of squared deviations; the largest
// deviation is the largest or the smallest value's).
class DominanceTally {
public:
  void add(double x);  // non-finite values are counted in the index but skipped
  void add_zeros(std::uint64_t n);
  DominantValue result() const;

private:
  double n_ = 0, mean_ = 0, m2_ = 0, lo_ = 0, hi_ = 0;
  std::uint64_t seen_ = 0, lo_at_ = 0, hi_at_ = 0;
  bool any_ = false;
};

// One-sample Kolmogorov-Smirnov test of values against the uniform distribution on [0, 1]
// (e.g. p-values under a null): D = sup |F_n - F|, p from the asymptotic Kolmogorov distribution
// with Stephens' small-sample correction (Stephens 1970): lambda = (sqrt(n) + 0.12 + 0.11 / sqrt(n)) D.
// (Written here: Boost.Math 1.74, the version this project builds with, has no Kolmogorov distribution.)
struct KolmogorovResult {
  double statistic = 0;
  double p_value = 1;
};
KolmogorovResult ks_test_uniform(std::span<const double> values);

nlohmann::json to_json(const ChiSquareResult& result);

}  // namespace microsim
