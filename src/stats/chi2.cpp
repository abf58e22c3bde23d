// microsim: chi-square goodness-of-fit and homogeneity tests with pooling of sparse cells (chi2.h).
#include "stats/chi2.h"
#include "stats/json_values.h"

#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/special_functions/gamma.hpp>
#include <boost/math/tools/minima.hpp>
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <stdexcept>

namespace microsim {
namespace {

// Cells sorted by weight (an expected count); the smallest, below min_weight, form the pool; if the
// pool is still below min_weight the next smallest cells join it, so that every cell of the statistic
// (the pool included) has an expected count of at least min_weight whenever that is possible.
struct Pooling {
  std::vector<int> single;
  std::vector<int> pooled;
};

Pooling pool_sparse_cells(std::vector<int> cells, const std::vector<double>& weight, double min_weight) {
  std::stable_sort(cells.begin(), cells.end(), [&](int a, int b) { return weight[a] < weight[b]; });
  Pooling p;
  double pool_weight = 0;
  std::size_t k = 0;
  for (; k < cells.size() && weight[cells[k]] < min_weight; ++k) {
    p.pooled.push_back(cells[k]);
    pool_weight += weight[cells[k]];
  }
  for (; !p.pooled.empty() && pool_weight < min_weight && k < cells.size(); ++k) {
    p.pooled.push_back(cells[k]);
    pool_weight += weight[cells[k]];
  }
  p.single.assign(cells.begin() + std::ptrdiff_t(k), cells.end());
  return p;
}

// The cells goodness_of_fit would test with n samples: those of positive expected count, after pooling.
int cells_after_pooling(std::span<const double> expected_probability, double n, double min_expected) {
  std::vector<double> expected(expected_probability.size());
  std::vector<int> cells;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    expected[i] = std::max(expected_probability[i], 0.0) * n;
    if (expected[i] > 0) cells.push_back(int(i));
  }
  const Pooling p = pool_sparse_cells(std::move(cells), expected, min_expected);
  return int(p.single.size()) + (p.pooled.empty() ? 0 : 1);
}

std::string cell_name(const ChiSquareOptions& options, int bin) {
  return options.describe_cell ? options.describe_cell(bin) : fmt::format("bin {}", bin);
}

double chi2_upper_tail(double statistic, int dof) {
  if (dof < 1) return 1.0;
  if (!std::isfinite(statistic)) return 0.0;
  const boost::math::chi_squared_distribution<double> dist(dof);
  return boost::math::cdf(boost::math::complement(dist, std::max(statistic, 0.0)));
}

void keep_worst(std::vector<CellReport>& cells, int n) {
  std::stable_sort(cells.begin(), cells.end(),
                   [](const CellReport& a, const CellReport& b) { return a.contribution > b.contribution; });
  if (int(cells.size()) > n) cells.resize(std::max(n, 0));
}

// The common end of both tests: degrees of freedom (cells after pooling - 1), p-value, verdict, and the
// worst cells by contribution, named.
void finish_test(ChiSquareResult& r, std::vector<CellReport> reports, const ChiSquareOptions& options) {
  r.dof = r.cells - 1;
  if (r.dof < 1) r.reason = "fewer than two cells after pooling: no test possible";
  r.p_value = chi2_upper_tail(r.statistic, r.dof);
  r.rejected = r.p_value < options.significance;
  keep_worst(reports, options.worst_cells);
  for (CellReport& c : reports)
    if (c.bin >= 0) c.location = cell_name(options, c.bin);
  r.worst_cells = std::move(reports);
}

// The statistic over the cells after pooling: one term per single cell, in order, then one for the pool.
// cell(cells) reports a set of cells (its observed and expected count and its term) from their sums.
template <class CellTerm>
void add_terms(ChiSquareResult& r, const Pooling& pooling, CellTerm&& cell, std::vector<CellReport>& reports) {
  for (int i : pooling.single) {
    CellReport c = cell(std::span<const int>(&i, 1));
    c.bin = i;
    r.statistic += c.contribution;
    reports.push_back(std::move(c));
  }
  r.cells = int(pooling.single.size());
  if (!pooling.pooled.empty()) {
    CellReport c = cell(std::span<const int>(pooling.pooled));
    c.location = fmt::format("pooled ({} cells)", pooling.pooled.size());
    r.statistic += c.contribution;
    reports.push_back(std::move(c));
    r.cells += 1;
    r.pooled_cells = int(pooling.pooled.size());
  }
}

ChiSquareResult new_result(const char* test, double samples, const ChiSquareOptions& options) {
  ChiSquareResult r;
  r.test = test;
  r.samples = samples;
  r.significance = options.significance;
  return r;
}

void reject(ChiSquareResult& r, std::string reason) {
  r.p_value = 0;
  r.rejected = true;
  r.statistic = std::numeric_limits<double>::infinity();
  r.reason = std::move(reason);
}

// Expected counts of a goodness-of-fit test: the cells of positive expectation, and the samples that fell
// where the expected probability is 0.
struct Expectation {
  std::vector<double> expected;
  std::vector<int> cells;
  double impossible = 0;
  int first_impossible = -1;
};

Expectation expected_counts(std::span<const double> observed, std::span<const double> expected_probability,
                            double n_samples) {
  const int n = int(observed.size());
  Expectation x;
  x.expected.resize(n);
  for (int i = 0; i < n; ++i) {
    const double p = expected_probability[i];
    if (!std::isfinite(p) || !std::isfinite(observed[i]))
      throw std::invalid_argument(fmt::format("goodness_of_fit: cell {} has a non-finite count or probability", i));
    x.expected[i] = std::max(p, 0.0) * n_samples;
    if (x.expected[i] > 0) {
      x.cells.push_back(i);
    } else if (observed[i] > 0) {
      x.impossible += observed[i];
      if (x.first_impossible < 0) x.first_impossible = i;
    }
  }
  return x;
}

}  // namespace

ChiSquareResult goodness_of_fit(std::span<const double> observed, std::span<const double> expected_probability,
                                double n_samples, const ChiSquareOptions& options, double outside_domain) {
  if (observed.size() != expected_probability.size())
    throw std::invalid_argument(fmt::format("goodness_of_fit: {} observed cells but {} expected probabilities",
                                            observed.size(), expected_probability.size()));
  if (!(n_samples > 0) || !std::isfinite(n_samples))
    throw std::invalid_argument(fmt::format("goodness_of_fit: the number of samples must be positive, got {}", n_samples));
  ChiSquareResult r = new_result("goodness_of_fit", n_samples, options);
  if (outside_domain > 0) {
    reject(r, fmt::format("{} sample(s) outside the domain", outside_domain));
    return r;
  }
  Expectation x = expected_counts(observed, expected_probability, n_samples);
  if (x.impossible > 0) {
    const int first = x.first_impossible;
    reject(r, fmt::format("{} sample(s) where the expected probability is 0 (first: {})", x.impossible,
                          cell_name(options, first)));
    r.worst_cells.push_back({first, observed[first], 0.0, r.statistic, cell_name(options, first)});
    return r;
  }
  const Pooling pooling = pool_sparse_cells(std::move(x.cells), x.expected, options.min_expected);
  auto cell = [&](std::span<const int> cells) {
    double o = 0, e = 0;
    for (int i : cells) {
      o += observed[i];
      e += x.expected[i];
    }
    return CellReport{-1, o, e, (o - e) * (o - e) / e, {}};
  };
  std::vector<CellReport> reports;
  add_terms(r, pooling, cell, reports);
  finish_test(r, std::move(reports), options);
  return r;
}

ChiSquareResult two_sample_homogeneity(std::span<const double> a, std::span<const double> b,
                                       const ChiSquareOptions& options) {
  if (a.size() != b.size())
    throw std::invalid_argument(
        fmt::format("two_sample_homogeneity: histograms of {} and {} cells", a.size(), b.size()));
  const double na = std::accumulate(a.begin(), a.end(), 0.0), nb = std::accumulate(b.begin(), b.end(), 0.0);
  if (!(na > 0) || !(nb > 0) || !std::isfinite(na) || !std::isfinite(nb))
    throw std::invalid_argument(
        fmt::format("two_sample_homogeneity: both histograms need positive finite totals, got {} and {}", na, nb));
  ChiSquareResult r = new_result("two_sample_homogeneity", na + nb, options);
  const double k1 = std::sqrt(nb / na), k2 = std::sqrt(na / nb);
  const int n = int(a.size());
  // Under homogeneity cell i expects Na (a_i + b_i) / (Na + Nb) counts of a and Nb (...) of b; pool
  // on the smaller of the two.
  std::vector<double> weight(n, 0.0);
  std::vector<int> cells;
  for (int i = 0; i < n; ++i) {
    if (a[i] < 0 || b[i] < 0) throw std::invalid_argument(fmt::format("two_sample_homogeneity: negative count in cell {}", i));
    const double s = a[i] + b[i];
    if (s > 0) {
      weight[i] = s * std::min(na, nb) / (na + nb);
      cells.push_back(i);
    }
  }
  const Pooling pooling = pool_sparse_cells(std::move(cells), weight, options.min_expected);
  auto cell = [&](std::span<const int> cells) {
    double pa = 0, pb = 0;
    for (int i : cells) {
      pa += a[i];
      pb += b[i];
    }
    const double d = k1 * pa - k2 * pb;
    return CellReport{-1, pa, na * (pa + pb) / (na + nb), d * d / (pa + pb), {}};
  };
  std::vector<CellReport> reports;
  add_terms(r, pooling, cell, reports);
  finish_test(r, std::move(reports), options);
  return r;
}

namespace {

// The four sums of a set of cells of two weighted histograms.
struct WeightedCell {
  double a = 0, u = 0;  // histogram 1: sum of weights, sum of squared weights
  double b = 0, t = 0;  // histogram 2
  // (b - lambda a)^2 / (t + lambda^2 u): the cell's term at the ratio lambda (0 / 0 = 0, x / 0 = inf).
  double term(double lambda) const {
    const double d = b - lambda * a, v = t + lambda * lambda * u;
    if (v > 0) return d * d / v;
    return d == 0 ? 0.0 : std::numeric_limits<double>::infinity();
  }
};

// The effective count w^2 / s of a cell of one histogram: infinite for an exact non-empty one.
double effective_count(double w, double s) {
  if (!(w > 0)) return 0.0;
  return s > 0 ? w * w / s : std::numeric_limits<double>::infinity();
}

void check_weighted_inputs(std::span<const double> w1, std::span<const double> s1, std::span<const double> w2,
                           std::span<const double> s2) {
  if (w1.size() != s1.size() || w2.size() != s2.size() || w1.size() != w2.size())
    throw std::invalid_argument(fmt::format("weighted_homogeneity: cells {}, {}, {}, {} differ", w1.size(), s1.size(),
                                            w2.size(), s2.size()));
  for (std::size_t i = 0; i < w1.size(); ++i)
    for (double v : {w1[i], s1[i], w2[i], s2[i]})
      if (!(v >= 0) || !std::isfinite(v))
        throw std::invalid_argument(fmt::format("weighted_homogeneity: cell {} has a sum {} (finite, >= 0 needed)", i, v));
  const auto total = [](std::span<const double> x) { return std::accumulate(x.begin(), x.end(), 0.0); };
  if (!(total(w1) > 0) || !(total(w2) > 0))
    throw std::invalid_argument("weighted_homogeneity: a histogram is empty");
  if (total(s1) == 0 && total(s2) == 0)
    throw std::invalid_argument("weighted_homogeneity: both histograms are exact: there is nothing random to test");
}

// The ratio lambda minimising the sum of the cells' terms: the best of a grid over lambda0 * [1/100, 100]
// (log-spaced), refined by Brent's method between its neighbours.
double fitted_ratio(const std::vector<WeightedCell>& cells, double lambda0) {
  const auto statistic = [&](double log_lambda) {
    double x = 0;
    for (const WeightedCell& c : cells) x += c.term(std::exp(log_lambda));
    return x;
  };
  const int steps = 40;
  const double lo = std::log(lambda0) - std::log(100.0), step = 2 * std::log(100.0) / steps;
  int best = steps / 2;
  for (int k = 0; k <= steps; ++k)
    if (statistic(lo + k * step) < statistic(lo + best * step)) best = k;
  const auto [x, fx] = boost::math::tools::brent_find_minima(statistic, lo + (best - 1) * step, lo + (best + 1) * step, 40);
  return std::exp(x);
}

}  // namespace

ChiSquareResult weighted_homogeneity(std::span<const double> w1, std::span<const double> s1, std::span<const double> w2,
                                     std::span<const double> s2, const ChiSquareOptions& options) {
  check_weighted_inputs(w1, s1, w2, s2);
  const int n = int(w1.size());
  std::vector<double> weight(n, 0.0);
  std::vector<int> cells;
  double a = 0, b = 0, effective = 0;
  for (int i = 0; i < n; ++i) {
    if (w1[i] == 0 && w2[i] == 0) continue;
    weight[i] = std::min(effective_count(w1[i], s1[i]), effective_count(w2[i], s2[i]));
    cells.push_back(i);
    a += w1[i];
    b += w2[i];
  }
  for (const auto& [w, s] : {std::pair{w1, s1}, std::pair{w2, s2}}) {
    const double e = effective_count(std::accumulate(w.begin(), w.end(), 0.0), std::accumulate(s.begin(), s.end(), 0.0));
    if (std::isfinite(e)) effective += e;
  }
  ChiSquareResult r = new_result("weighted_homogeneity", effective, options);
  const Pooling pooling = pool_sparse_cells(std::move(cells), weight, options.min_expected);
  std::vector<WeightedCell> sums;
  auto sum_of = [&](std::span<const int> set) {
    WeightedCell c;
    for (int i : set) c.a += w1[i], c.u += s1[i], c.b += w2[i], c.t += s2[i];
    return c;
  };
  for (int i : pooling.single) sums.push_back(sum_of(std::span<const int>(&i, 1)));
  if (!pooling.pooled.empty()) sums.push_back(sum_of(pooling.pooled));
  if (sums.size() < 2)
    throw InsufficientData(fmt::format("{:.4g} effective entries pool into a single cell: the weighted homogeneity test "
                                       "needs two cells of at least {} effective entries each",
                                       effective, options.min_expected),
                           std::uint64_t(std::min(effective, 1e18)), std::uint64_t(2 * options.min_expected));
  const double lambda = fitted_ratio(sums, b / a);
  auto cell = [&](std::span<const int> set) {
    const WeightedCell c = sum_of(set);
    const double v = c.t + lambda * lambda * c.u;
    const double expected = v > 0 ? (c.a * c.t + lambda * c.b * c.u) / v : c.a;  // the fitted q of histogram 1
    return CellReport{-1, c.a, expected, c.term(lambda), {}};
  };
  std::vector<CellReport> reports;
  add_terms(r, pooling, cell, reports);
  finish_test(r, std::move(reports), options);
  return r;
}

std::uint64_t goodness_of_fit_minimum_samples(std::span<const double> p, double min_expected) {
  double p_max = 0, total = 0;
  for (double x : p) {
    if (!std::isfinite(x))
      throw std::invalid_argument("goodness_of_fit_minimum_samples: non-finite expected probability");
    p_max = std::max(p_max, std::max(x, 0.0));
    total += std::max(x, 0.0);
  }
  const double smaller = std::min(p_max, total - p_max);
  if (!(smaller > 0)) return kNoSampleCountSuffices;
  const double estimate = std::ceil(min_expected / smaller);
  if (!(estimate < 0x1p62)) return kNoSampleCountSuffices;
  // The closed form can be off by one in rounding: settle it with the test's own pooling.
  auto n = std::uint64_t(std::max(estimate, 1.0));
  for (int k = 0; k < 8 && n > 1 && cells_after_pooling(p, double(n - 1), min_expected) >= 2; ++k) --n;
  for (int k = 0; k < 8 && cells_after_pooling(p, double(n), min_expected) < 2; ++k) ++n;
  return n;
}

double sidak_significance(double alpha, int n_tests) {
  if (n_tests < 1) throw std::invalid_argument(fmt::format("sidak_significance: n_tests must be >= 1, got {}", n_tests));
  // A level of 0 rejects nothing and 1 everything: a verdict at either would say nothing.
  if (!(alpha > 0 && alpha < 1))
    throw std::invalid_argument(fmt::format("the significance level must be in (0, 1), got {}", alpha));
  // 1 - (1 - alpha)^(1/n), without cancellation for small alpha.
  return -std::expm1(std::log1p(-alpha) / n_tests);
}

double sidak_adjusted_p(double p_min, int n_tests) {
  if (n_tests < 1) throw std::invalid_argument(fmt::format("sidak_adjusted_p: n_tests must be >= 1, got {}", n_tests));
  if (!(p_min < 1)) return 1.0;
  return -std::expm1(n_tests * std::log1p(-std::max(p_min, 0.0)));
}

namespace {
// Chebyshev's inequality, P(|X - E X| >= t) <= Var X / t^2: a p-value for any distribution of the mean.
double chebyshev_p(double deviation, double se) {
  const double r = se / deviation;
  return deviation == 0 ? 1.0 : std::min(1.0, r * r);
}
}  // namespace

double skewed_mean_p(double deviation, double se, double skew, double least) {
  if (!std::isfinite(deviation)) return 0.0;
  if (!(se > 0)) return deviation == 0 ? 1.0 : 0.0;
  // Nearly symmetric: the normal (the gamma's shape would pass 4e6, where Boost's series can fail to converge).
  if (!(std::abs(skew) >= 1e-3)) {
    if (0.5 * std::erfc(-least / se / std::sqrt(2.0)) > kSkewedMeanSupportMass) return chebyshev_p(deviation, se);
    return std::min(1.0, std::erfc(std::abs(deviation / se) / std::sqrt(2.0)));
  }
  // X = G - k theta, G ~ Gamma(k, theta): mean 0, sd se, skewness 2 / sqrt(k); mirrored for a negative skew.
  const double k = 4 / (skew * skew), theta = se * std::abs(skew) / 2;
  const auto g_of = [&](double x) { return (skew > 0 ? x : -x) / theta + k; };  // G / theta at deviation x
  // The approximation's mass below `least`, where the mean cannot be.
  const double g_least = g_of(least);
  const double outside = skew > 0 ? (g_least <= 0 ? 0.0 : boost::math::gamma_p(k, g_least))
                                  : (g_least <= 0 ? 1.0 : boost::math::gamma_q(k, g_least));
  if (outside > kSkewedMeanSupportMass) return chebyshev_p(deviation, se);
  const double g = g_of(deviation);
  if (g <= 0) return 0.0;  // below the gamma's support
  const double lower = boost::math::gamma_p(k, g), upper = boost::math::gamma_q(k, g);
  return std::min(1.0, 2 * std::min(lower, upper));
}

KolmogorovResult ks_test_uniform(std::span<const double> values) {
  KolmogorovResult r;
  if (values.empty()) return r;
  std::vector<double> x(values.begin(), values.end());
  std::sort(x.begin(), x.end());
  const double n = double(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double f = std::clamp(x[i], 0.0, 1.0);
    r.statistic = std::max({r.statistic, (i + 1) / n - f, f - i / n});
  }
  const double sn = std::sqrt(n);
  const double lambda = (sn + 0.12 + 0.11 / sn) * r.statistic;
  // Kolmogorov's limiting distribution Q(lambda) = 2 sum_{k>=1} (-1)^(k-1) exp(-2 k^2 lambda^2); for small
  // lambda the equivalent (Jacobi theta) form 1 - sqrt(2 pi)/lambda sum exp(-(2k-1)^2 pi^2 / (8 lambda^2))
  // converges faster.
  double q = 0;
  if (lambda < 1e-3) {
    q = 1;
  } else if (lambda < 1.18) {
    const double pi2 = std::numbers::pi * std::numbers::pi;
    double s = 0;
    for (int k = 1; k <= 20; ++k) s += std::exp(-(2 * k - 1) * (2 * k - 1) * pi2 / (8 * lambda * lambda));
    q = 1 - std::sqrt(2 * std::numbers::pi) / lambda * s;
  } else {
    for (int k = 1; k <= 100; ++k) q += 2 * ((k % 2) ? 1 : -1) * std::exp(-2.0 * k * k * lambda * lambda);
  }
  r.p_value = std::clamp(q, 0.0, 1.0);
  return r;
}

nlohmann::json to_json(const ChiSquareResult& r) {
  nlohmann::json j;
  j["test"] = r.test;
  j["statistic"] = finite_or_null(r.statistic);
  j["dof"] = r.dof;
  j["p_value"] = r.p_value;
  j["significance"] = r.significance;
  j["rejected"] = r.rejected;
  j["reason"] = r.reason;
  j["samples"] = r.samples;
  j["cells"] = r.cells;
  j["pooled_cells"] = r.pooled_cells;
  nlohmann::json worst = nlohmann::json::array();
  for (const CellReport& c : r.worst_cells)
    worst.push_back({{"bin", c.bin}, {"location", c.location}, {"observed", c.observed}, {"expected", c.expected},
                     {"contribution", finite_or_null(c.contribution)}});
  j["worst_cells"] = worst;
  return j;
}

void DominanceTally::add(double x) {
  const std::uint64_t at = seen_++;
  if (!std::isfinite(x)) return;
  if (!any_ || x < lo_) lo_ = x, lo_at_ = at;
  if (!any_ || x > hi_) hi_ = x, hi_at_ = at;
  any_ = true;
  n_ += 1;
  const double d = x - mean_;
  mean_ += d / n_;
  m2_ += d * (x - mean_);
}

void DominanceTally::add_zeros(std::uint64_t n) {
  if (n == 0) return;
  const double k = double(n), total = n_ + k, d = -mean_;
  m2_ += d * d * n_ * k / total;
  mean_ += d * k / total;
  n_ = total;
}

DominantValue DominanceTally::result() const {
  if (!any_ || !(n_ > 1) || !(m2_ > 0)) return {};
  const double below = (lo_ - mean_) * (lo_ - mean_), above = (hi_ - mean_) * (hi_ - mean_);
  return above >= below ? DominantValue{std::min(1.0, above / m2_), hi_at_, hi_, n_}
                        : DominantValue{std::min(1.0, below / m2_), lo_at_, lo_, n_};
}

std::string DominantValue::firefly() const {
  return fmt::format("the sample of row {} (weight {:.6g}) holds {:.0f}% of the weights' spread (at most {:.0f}% for a "
                     "mean's test of {:.0f} samples): a firefly",
                     index, value, 100 * share, 100 * limit(), count);
}

DominantValue dominant_value(std::span<const double> x, std::uint64_t zeros) {
  DominanceTally t;
  for (const double v : x) t.add(v);
  t.add_zeros(zeros);
  return t.result();
}

}  // namespace microsim
