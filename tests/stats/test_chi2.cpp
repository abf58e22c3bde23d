// Tests of the chi-square harness: pooling and statistic by hand, impossible samples, uniformity of
// p-values under the null (Kolmogorov-Smirnov over 200 p-values at a fixed seed, level 0.01), power
// against a shifted distribution, the two-sample test, and the Sidak helpers.
#include "stats/chi2.h"
#include "core/random.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

using namespace microsim;

namespace {

// Counts of n draws from the discrete distribution p (inverse CDF), from CounterRng(seed, stream).
std::vector<double> multinomial(const std::vector<double>& p, int n, std::uint64_t seed, std::uint64_t stream) {
  std::vector<double> cdf(p.size());
  std::partial_sum(p.begin(), p.end(), cdf.begin());
  std::vector<double> counts(p.size(), 0.0);
  CounterRng rng(seed, stream);
  for (int i = 0; i < n; ++i) {
    const double u = rng.uniform() * cdf.back();
    const auto it = std::upper_bound(cdf.begin(), cdf.end(), u);
    counts[std::min<std::size_t>(it - cdf.begin(), p.size() - 1)] += 1;
  }
  return counts;
}

// 40 cells, probabilities falling geometrically so that the tail cells need pooling at N = 1000.
std::vector<double> geometric_cells() {
  std::vector<double> p(40);
  double s = 0;
  for (int i = 0; i < 40; ++i) s += (p[i] = std::pow(0.88, i));
  for (double& x : p) x /= s;
  return p;
}

// The same distribution with 10% of the mass of cell 0 moved to cell 1.
std::vector<double> shifted_cells() {
  std::vector<double> p = geometric_cells();
  const double moved = 0.1 * p[0];
  p[0] -= moved;
  p[1] += moved;
  return p;
}

// Upper tail of chi-squared with 3 degrees of freedom, closed form: erfc(sqrt(x/2)) + sqrt(2x/pi) e^(-x/2).
double chi2_sf_3(double x) { return std::erfc(std::sqrt(x / 2)) + std::sqrt(2 * x / std::numbers::pi) * std::exp(-x / 2); }

}  // namespace

TEST(ChiSquare, StatisticAndPoolingByHand) {
  const std::vector<double> p = {0.5, 0.3, 0.15, 0.03, 0.02};  // expected counts 50, 30, 15, 3, 2 at N = 100
  const std::vector<double> o = {48, 33, 14, 4, 1};
  const ChiSquareResult r = goodness_of_fit(o, p, 100);
  // Cells 3 and 4 (expected 3 + 2 = 5) form the pool; pooled O = 5, E = 5.
  const double stat = 4.0 / 50 + 9.0 / 30 + 1.0 / 15 + 0.0;
  EXPECT_NEAR(r.statistic, stat, 1e-12);
  EXPECT_EQ(r.cells, 4);
  EXPECT_EQ(r.pooled_cells, 2);
  EXPECT_EQ(r.dof, 3);
  EXPECT_NEAR(r.p_value, chi2_sf_3(stat), 1e-12);
  EXPECT_FALSE(r.rejected);
  EXPECT_TRUE(r.reason.empty());
  ASSERT_FALSE(r.worst_cells.empty());
  EXPECT_EQ(r.worst_cells.front().bin, 1);  // (33 - 30)^2 / 30 is the largest term
  EXPECT_DOUBLE_EQ(r.worst_cells.front().observed, 33);
  EXPECT_DOUBLE_EQ(r.worst_cells.front().expected, 30);
}

TEST(ChiSquare, PoolGrowsUntilItReachesTheThreshold) {
  const std::vector<double> p = {0.9, 0.06, 0.02, 0.01, 0.01};  // expected 90, 6, 2, 1, 1
  const std::vector<double> o = {88, 7, 3, 1, 1};
  const ChiSquareResult r = goodness_of_fit(o, p, 100);
  // The pool {1, 1, 2} has 4 < 5 expected: cell 1 (6 expected) joins it. Cells: {90}, pool {10}.
  EXPECT_EQ(r.cells, 2);
  EXPECT_EQ(r.pooled_cells, 4);
  EXPECT_EQ(r.dof, 1);
  EXPECT_NEAR(r.statistic, 4.0 / 90 + 4.0 / 10, 1e-12);
}

TEST(ChiSquare, ImpossibleSamplesRejectAtOnce) {
  const std::vector<double> p = {0.5, 0.5, 0.0};
  const ChiSquareResult r = goodness_of_fit(std::vector<double>{50, 49, 1}, p, 100);
  EXPECT_TRUE(r.rejected);
  EXPECT_EQ(r.p_value, 0.0);
  EXPECT_NE(r.reason.find("expected probability is 0"), std::string::npos);
  const ChiSquareResult outside = goodness_of_fit(std::vector<double>{50, 49, 0}, p, 100, {}, 1);
  EXPECT_TRUE(outside.rejected);
  EXPECT_EQ(outside.p_value, 0.0);
  EXPECT_NE(outside.reason.find("outside the domain"), std::string::npos);
  // Cells with zero probability and no samples are simply left out.
  const ChiSquareResult fine = goodness_of_fit(std::vector<double>{50, 50, 0}, p, 100);
  EXPECT_FALSE(fine.rejected);
  EXPECT_EQ(fine.cells, 2);
  EXPECT_THROW(goodness_of_fit(std::vector<double>{1, 2}, p, 3), std::invalid_argument);
  EXPECT_THROW(goodness_of_fit(std::vector<double>{1, 2, 0}, p, 0), std::invalid_argument);
}

// Under the null, 200 p-values (N = 1000 each, fixed seed) are uniform: Kolmogorov-Smirnov at level 0.01.
TEST(ChiSquare, PValuesAreUniformUnderTheNull) {
  const std::vector<double> p = geometric_cells();
  std::vector<double> pvalues;
  for (int rep = 0; rep < 200; ++rep) pvalues.push_back(goodness_of_fit(multinomial(p, 1000, 2024, rep), p, 1000).p_value);
  const KolmogorovResult ks = ks_test_uniform(pvalues);
  EXPECT_GT(ks.p_value, 0.01) << "KS statistic " << ks.statistic;
  const auto small = std::count_if(pvalues.begin(), pvalues.end(), [](double x) { return x < 0.01; });
  EXPECT_LE(small, 8);  // expected 2 of 200; P(>= 9) < 1e-3 under the null
}

TEST(ChiSquare, RejectsAShiftedDistribution) {
  const std::vector<double> p = geometric_cells();
  const ChiSquareResult r = goodness_of_fit(multinomial(shifted_cells(), 200000, 7, 0), p, 200000);
  EXPECT_TRUE(r.rejected);
  EXPECT_LT(r.p_value, 1e-6);
  ASSERT_FALSE(r.worst_cells.empty());
  EXPECT_LE(r.worst_cells.front().bin, 1);  // the worst cell is one of the two that changed
}

TEST(ChiSquare, TwoSampleHomogeneityIsUniformUnderTheNullAndHasPower) {
  const std::vector<double> p = geometric_cells();
  std::vector<double> pvalues;
  for (int rep = 0; rep < 200; ++rep)
    pvalues.push_back(two_sample_homogeneity(multinomial(p, 1000, 99, 2 * rep), multinomial(p, 3000, 99, 2 * rep + 1)).p_value);
  const KolmogorovResult ks = ks_test_uniform(pvalues);
  EXPECT_GT(ks.p_value, 0.01) << "KS statistic " << ks.statistic;

  const auto a = multinomial(p, 100000, 5, 0), b = multinomial(shifted_cells(), 300000, 5, 1);
  const ChiSquareResult r = two_sample_homogeneity(a, b);
  EXPECT_TRUE(r.rejected);
  EXPECT_LT(r.p_value, 1e-6);
  // The statistic is symmetric in the two histograms.
  EXPECT_NEAR(two_sample_homogeneity(b, a).statistic, r.statistic, 1e-9 * r.statistic);
  EXPECT_THROW(two_sample_homogeneity(std::vector<double>{1, 2}, std::vector<double>{1}), std::invalid_argument);
  EXPECT_THROW(two_sample_homogeneity(std::vector<double>{0, 0}, std::vector<double>{1, 1}), std::invalid_argument);
}

TEST(ChiSquare, TwoSampleStatisticByHand) {
  // Na = 100, Nb = 400: K1 = 2, K2 = 0.5. Cells (a, b): (60, 250), (40, 150).
  const ChiSquareResult r = two_sample_homogeneity(std::vector<double>{60, 40}, std::vector<double>{250, 150});
  const double stat = std::pow(2 * 60 - 0.5 * 250, 2) / 310 + std::pow(2 * 40 - 0.5 * 150, 2) / 190;
  EXPECT_NEAR(r.statistic, stat, 1e-12);
  EXPECT_EQ(r.dof, 1);
}

TEST(ChiSquare, Sidak) {
  EXPECT_NEAR(sidak_significance(0.01, 1), 0.01, 1e-15);
  EXPECT_NEAR(sidak_significance(0.05, 10), 1 - std::pow(0.95, 0.1), 1e-15);
  EXPECT_NEAR(sidak_adjusted_p(sidak_significance(0.01, 250), 250), 0.01, 1e-14);
  EXPECT_NEAR(sidak_adjusted_p(1e-20, 100), 1e-18, 1e-30);  // no cancellation at tiny p
  EXPECT_EQ(sidak_adjusted_p(0.0, 5), 0.0);
  EXPECT_EQ(sidak_adjusted_p(1.0, 5), 1.0);
  EXPECT_THROW(sidak_significance(0.01, 0), std::invalid_argument);
  for (const double level : {0.0, -1.0, 1.0, 2.0, std::nan("")})  // nothing or everything rejected: no verdict
    EXPECT_THROW(sidak_significance(level, 3), std::invalid_argument) << level;
}

// The mean of m Exp(1) variables is Gamma(m, 1 / m): mean 1, standard error 1 / sqrt(m), skewness 2 / sqrt(m),
// so the translated gamma is exact there: its tails in closed form for m = 1 and 2.
TEST(ChiSquare, SkewedMeanPIsTheGammasTails) {
  EXPECT_NEAR(skewed_mean_p(3.0, 1.0, 2.0), 2 * std::exp(-4.0), 1e-12);               // m = 1, x = 4
  EXPECT_NEAR(skewed_mean_p(-0.9, 1.0, 2.0), 2 * (1 - std::exp(-0.1)), 1e-12);        // x = 0.1
  EXPECT_NEAR(skewed_mean_p(-3.0, 1.0, -2.0), 2 * std::exp(-4.0), 1e-12);             // mirrored
  EXPECT_EQ(skewed_mean_p(-1.5, 1.0, 2.0), 0.0);                                       // x = -0.5: impossible
  EXPECT_NEAR(skewed_mean_p(2.0, 1 / std::sqrt(2.0), std::sqrt(2.0)), 2 * 7 * std::exp(-6.0), 1e-12);  // m = 2, x = 3
  // Nearly symmetric: the normal's; never above 1; a non-finite deviation rejects.
  EXPECT_NEAR(skewed_mean_p(1.959963984540054, 1.0, 0.0), 0.05, 1e-12);
  EXPECT_NEAR(skewed_mean_p(1.959963984540054, 1.0, 1e-4), 0.05, 1e-5);
  EXPECT_NEAR(skewed_mean_p(0.0, 1.0, 2.0), 2 * std::exp(-1.0), 1e-12);  // at the mean, not the median
  EXPECT_EQ(skewed_mean_p(NAN, 1.0, 0.5), 0.0);
  // The normal misstates the right tail of a skewed mean (the point of it): 3 se above is 0.0366 not 0.0027.
  EXPECT_GT(skewed_mean_p(3.0, 1.0, 2.0), 10 * skewed_mean_p(3.0, 1.0, 0.0));
}

// A mean of n terms c Bernoulli(q) (a bin that few nonzero weights reach; lambda = n q of them expected), against
// its moments as the weight test gives them: the fraction of draws with p below 0.01 (fixed seed, 20000 draws).
double rare_terms_rejection_rate(double lambda, bool support) {
  const double n = 1e5, q = lambda / n, c = 0.7;
  const double m1 = c * q, m2 = c * c * q, m3 = c * c * c * q;
  const double var = m2 - m1 * m1, se = std::sqrt(var / n);
  const double skew = (m3 - 3 * m1 * m2 + 2 * m1 * m1 * m1) / (var * std::sqrt(var) * std::sqrt(n));
  std::mt19937_64 rng(11);
  std::binomial_distribution<long long> terms(static_cast<long long>(n), q);
  int rejected = 0;
  constexpr int kDraws = 20000;
  for (int i = 0; i < kDraws; ++i) {
    const double deviation = c * double(terms(rng)) / n - m1;
    rejected += (support ? skewed_mean_p(deviation, se, skew, -m1) : skewed_mean_p(deviation, se, skew)) < 0.01;
  }
  return double(rejected) / kDraws;
}

// The mean cannot go below 0: where the translated gamma puts its mass there (few nonzero terms expected), the
// likeliest outcome (no term at all) was called extreme; Chebyshev's bound then holds the level. Negative control:
// without the support, lambda 1e-6 rejects nearly every draw.
TEST(ChiSquare, SkewedMeanPOfRareTermsHoldsItsLevel) {
  for (double lambda : {1e-6, 0.01, 0.3, 3.0, 40.0, 400.0}) {
    const double rate = rare_terms_rejection_rate(lambda, true);
    EXPECT_LE(rate, 0.01 + 3 * std::sqrt(0.01 * 0.99 / 20000)) << "lambda " << lambda;
  }
  EXPECT_GT(rare_terms_rejection_rate(1e-6, false), 0.99);
  // No term at all where 1e-8 of one is expected: p 1.
  EXPECT_EQ(skewed_mean_p(-1e-13, std::sqrt(1e-13 / 1e5), 1e4, -1e-13), 1.0);
}

TEST(ChiSquare, KolmogorovSmirnov) {
  std::vector<double> grid;
  for (int i = 0; i < 100; ++i) grid.push_back((i + 0.5) / 100);
  EXPECT_NEAR(ks_test_uniform(grid).statistic, 0.005, 1e-12);
  EXPECT_GT(ks_test_uniform(grid).p_value, 0.99);
  std::vector<double> clumped(100, 0.1);
  EXPECT_NEAR(ks_test_uniform(clumped).statistic, 0.9, 1e-12);
  EXPECT_LT(ks_test_uniform(clumped).p_value, 1e-20);
  // Asymptotic critical value at level 0.05 for large n: lambda = 1.358.
  std::vector<double> edge;
  const int n = 10000;
  const double d = 1.358 / (std::sqrt(double(n)) + 0.12 + 0.11 / std::sqrt(double(n)));
  for (int i = 0; i < n; ++i) edge.push_back(std::min(1.0, double(i) / n + d));  // D = d exactly
  EXPECT_NEAR(ks_test_uniform(edge).p_value, 0.05, 2e-3);
}

TEST(ChiSquare, JsonCarriesTheVerdict) {
  const nlohmann::json j = to_json(goodness_of_fit(std::vector<double>{48, 33, 14, 4, 1},
                                                   std::vector<double>{0.5, 0.3, 0.15, 0.03, 0.02}, 100));
  for (const char* key : {"statistic", "dof", "p_value", "rejected", "samples", "worst_cells", "cells"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["dof"], 3);
}

namespace microsim {
namespace {

// The largest share of the spread one value holds: tiny for 1e4 bounded values (uniform in [0, 1): at most
// (1/2)^2 / (1e4 / 12) = 3e-4), most of it for one firefly among them, and the same streamed with zeros
// (lost samples) as from the whole sample.
TEST(DominantValue, OneFireflyHoldsTheSpreadBoundedValuesDoNot) {
  std::vector<double> x(10'000);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = double((i * 7919) % 10'000) / 10'000.0;
  const DominantValue bounded = dominant_value(x);
  EXPECT_LT(bounded.share, 3.1e-4);
  x[4321] = 1e3;
  const DominantValue firefly = dominant_value(x);
  EXPECT_GT(firefly.share, 0.99);
  EXPECT_EQ(firefly.index, 4321u);
  EXPECT_EQ(firefly.value, 1e3);
  x.push_back(std::numeric_limits<double>::quiet_NaN());  // skipped
  DominanceTally t;
  for (const double v : x) t.add(v);
  t.add_zeros(500);
  std::vector<double> with_zeros(x.begin(), x.end() - 1);
  with_zeros.insert(with_zeros.end(), 500, 0.0);
  EXPECT_NEAR(t.result().share, dominant_value(with_zeros).share, 1e-12);
  EXPECT_EQ(t.result().index, 4321u);
  EXPECT_EQ(dominant_value(std::vector<double>{2.0, 2.0}).share, 0.0);  // no spread
  EXPECT_TRUE(firefly.dominates());
  EXPECT_FALSE(bounded.dominates());
  // 50 honest normal-like values: the largest can hold 10-20% of the spread; the limit for so few is looser.
  std::vector<double> few(50);
  for (std::size_t i = 0; i < few.size(); ++i) few[i] = std::sin(double(i) * 1.7) + (i == 7 ? 2.5 : 0.0);
  const DominantValue small = dominant_value(few);
  EXPECT_GT(small.share, 0.1);
  EXPECT_FALSE(small.dominates()) << small.share << " limit " << small.limit();
}

}  // namespace
}  // namespace microsim
