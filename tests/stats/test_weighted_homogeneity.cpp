// The weighted chi-square homogeneity test (stats/chi2.h weighted_homogeneity, Gagunashvili 2010): at fixed
// seeds, histograms of one distribution pass at the stated level (the rejection rate over many seeds is
// the level, and the p-values are uniform), a shifted distribution is rejected (the negative control), an
// exact expectation works as one side, and too little data is an error, never a pass.
#include "stats/chi2.h"

#include "core/random.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace microsim {
namespace {

constexpr int kCells = 30;

// The probability of cell i (a smooth lobe), optionally tilted by `shift` (0: none).
std::vector<double> cell_probabilities(double shift) {
  std::vector<double> p(kCells);
  double total = 0;
  for (int i = 0; i < kCells; ++i) total += p[i] = std::exp(-0.1 * i) * (1 + shift * (double(i) / kCells - 0.5));
  for (double& x : p) x /= total;
  return p;
}

// The mean weight of an event in cell i: the mean squared weight differs from cell to cell by a factor 25.
double weight_scale(int i) { return 0.2 + 1.8 * double(i % 7) / 6; }

struct Weighted {
  std::vector<double> w, s;
};

// n events drawn from p (inverse CDF), each with weight scale(i) * U (U uniform in [0, 1)).
Weighted draw(const std::vector<double>& p, int n, CounterRng& rng) {
  Weighted h{std::vector<double>(kCells, 0.0), std::vector<double>(kCells, 0.0)};
  std::vector<double> cdf(kCells);
  double acc = 0;
  for (int i = 0; i < kCells; ++i) cdf[i] = acc += p[i];
  for (int k = 0; k < n; ++k) {
    const double u = rng.uniform() * acc;
    const int i = int(std::min<std::ptrdiff_t>(std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin(), kCells - 1));
    const double w = weight_scale(i) * rng.uniform();
    h.w[i] += w;
    h.s[i] += w * w;
  }
  return h;
}

// The exact expectation of draw(p, n): n p_i scale(i) / 2.
Weighted exact(const std::vector<double>& p) {
  Weighted h{std::vector<double>(kCells, 0.0), std::vector<double>(kCells, 0.0)};
  for (int i = 0; i < kCells; ++i) h.w[i] = p[i] * weight_scale(i) / 2;
  return h;
}

// Over `runs` seeds: how many of the tests rejected at level 0.01, and the KS p-value of their p-values.
struct Level {
  int rejected = 0;
  double ks_p = 0;
};

Level null_level(int runs, bool exact_second) {
  const std::vector<double> p = cell_probabilities(0);
  std::vector<double> p_values;
  Level l;
  for (int seed = 0; seed < runs; ++seed) {
    CounterRng rng(std::uint64_t(seed), 77);
    const Weighted a = draw(p, 20000, rng);
    const Weighted b = exact_second ? exact(p) : draw(p, 5000, rng);
    const ChiSquareResult r = weighted_homogeneity(a.w, a.s, b.w, b.s);
    p_values.push_back(r.p_value);
    l.rejected += r.p_value < 0.01;
  }
  l.ks_p = ks_test_uniform(p_values).p_value;
  return l;
}

// 400 runs at level 0.01 expect 4 rejections; more than 12 has probability 1e-4 under a correct test.
TEST(WeightedHomogeneity, SameDistributionPassesAtTheStatedLevel) {
  const Level l = null_level(400, false);
  EXPECT_LE(l.rejected, 12);
  EXPECT_GT(l.ks_p, 1e-3) << "p-values are not uniform under the null";
}

TEST(WeightedHomogeneity, AgainstAnExactExpectationPassesAtTheStatedLevel) {
  const Level l = null_level(400, true);
  EXPECT_LE(l.rejected, 12);
  EXPECT_GT(l.ks_p, 1e-3) << "p-values are not uniform under the null";
}

TEST(WeightedHomogeneity, TotalsDoNotMatterOnlyTheShape) {
  const std::vector<double> p = cell_probabilities(0);
  CounterRng rng(5, 1);
  Weighted a = draw(p, 20000, rng), b = draw(p, 20000, rng);
  const double before = weighted_homogeneity(a.w, a.s, b.w, b.s).statistic;
  for (int i = 0; i < kCells; ++i) b.w[i] *= 3, b.s[i] *= 9;  // another scale (e.g. per path vs per run)
  EXPECT_NEAR(weighted_homogeneity(a.w, a.s, b.w, b.s).statistic, before, 1e-6 * before);
}

TEST(WeightedHomogeneity, ShiftedDistributionIsRejected) {  // the negative control
  CounterRng rng(3, 9);
  const Weighted a = draw(cell_probabilities(0), 20000, rng), b = draw(cell_probabilities(0.3), 20000, rng);
  const ChiSquareResult r = weighted_homogeneity(a.w, a.s, b.w, b.s);
  EXPECT_TRUE(r.rejected);
  EXPECT_LT(r.p_value, 1e-6);
  const Weighted e = exact(cell_probabilities(0.3));
  EXPECT_LT(weighted_homogeneity(a.w, a.s, e.w, e.s).p_value, 1e-6);
}

TEST(WeightedHomogeneity, WeightWhereTheExpectationHasNoneIsRejected) {
  const std::vector<double> p = cell_probabilities(0);
  CounterRng rng(8, 2);
  const Weighted a = draw(p, 20000, rng);
  Weighted e = exact(p);
  e.w[3] = 0;  // the measurement has weight in cell 3, the expectation none
  EXPECT_LT(weighted_homogeneity(a.w, a.s, e.w, e.s).p_value, 1e-6);
}

TEST(WeightedHomogeneity, TooLittleDataIsAnErrorNeverAPass) {
  const std::vector<double> p = cell_probabilities(0);
  CounterRng rng(1, 1);
  const Weighted a = draw(p, 12, rng), b = draw(p, 12, rng);
  EXPECT_THROW(weighted_homogeneity(a.w, a.s, b.w, b.s), InsufficientData);
  const std::vector<double> zero(kCells, 0.0);
  EXPECT_THROW(weighted_homogeneity(a.w, a.s, zero, zero), std::invalid_argument);  // an empty histogram
  const Weighted e = exact(p);
  EXPECT_THROW(weighted_homogeneity(e.w, e.s, e.w, e.s), std::invalid_argument);  // nothing random
}

}  // namespace
}  // namespace microsim
