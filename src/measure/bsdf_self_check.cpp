// The battery's tests against the BSDF itself and against the Smith walk (bsdf_self_check.h).
#include "measure/bsdf_self_check.h"

#include "core/random.h"
#include "scatter/smith_walk.h"
#include "stats/chi2.h"
#include "stats/scatter_compare.h"

#include <boost/math/distributions/chi_squared.hpp>
#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace microsim::battery {

namespace {

constexpr double kCellSolidAngle = 4 * std::numbers::pi / kCells;

// The second stage of a stochastic eval()'s tests. A stochastic eval() may be heavy-tailed (the Smith walk's
// next-event estimate, Heitz et al. 2016 sec. 6: rare high orders and rare high vertices carry much of the value,
// so that the sample kurtosis of its calls grows with their number), and then the standard error of a pair
// estimated from its own calls is mostly too small while their mean is mostly too low, at a few hundred calls
// and at thousands alike: a correct BSDF fails a chi-square. So a pair test of a stochastic eval() that rejects
// runs again on fresh, independent calls (kRecheckCalls times as many per pair), each pair's standard error at
// least (a) the first stage's scaled to the larger count (an independent estimate of its variance per call) and
// (b) |mean| times the largest relative standard deviation per call seen at any pair in either stage (pooled over
// the pairs: the tail a pair's own calls missed, another pair's met), and rejects only if the second stage
// rejects too. Rejecting needs the second stage to reject on its own calls, so the level of the whole is at most
// the second stage's. The integral test's second stage: fresh cell points, kRecheckPoints times as many.
constexpr int kRecheckCalls = 64, kRecheckReferenceWalks = 4, kRecheckPoints = 4;

// The largest relative standard deviation per call, se sqrt(calls) / |value|, over the estimates with a trusted
// standard error and a value other than 0.
double largest_cv(const std::vector<Estimate>& e, int calls) {
  double cv = 0;
  for (const Estimate& x : e)
    if (x.value != 0 && std::isfinite(x.standard_error)) cv = std::max(cv, x.standard_error * std::sqrt(double(calls)) / std::abs(x.value));
  return cv;
}

// Each trusted standard error at least |value| cv / sqrt(calls).
std::vector<Estimate> pooled(std::vector<Estimate> e, double cv, int calls) {
  for (Estimate& x : e)
    if (std::isfinite(x.standard_error)) x.standard_error = std::max(x.standard_error, std::abs(x.value) * cv / std::sqrt(double(calls)));
  return e;
}

// fresh's estimates, each standard error at least pilot's times sqrt(ratio) (ratio: pilot's calls over fresh's);
// an untrusted (NaN) standard error stays untrusted.
std::vector<Estimate> floored(std::vector<Estimate> fresh, const std::vector<Estimate>& pilot, double ratio) {
  for (std::size_t i = 0; i < fresh.size() && i < pilot.size(); ++i) {
    const double floor = pilot[i].standard_error * std::sqrt(ratio);
    if (std::isfinite(floor) && floor > fresh[i].standard_error) fresh[i].standard_error = floor;
  }
  return fresh;
}

// The line of a two-stage test: the second stage's verdict, both details, p the larger (a valid p of "both reject").
BatteryLine two_stage(const BatteryLine& first, const BatteryLine& second, int factor, const char* what) {
  BatteryLine l = second;
  l.detail = fmt::format("stage 1 rejected ({}; p {:.3g}); stage 2 on fresh {}, {} times as many: {}", first.detail,
                         first.p, what, factor, second.detail);
  l.p = std::max(first.p, second.p);
  return l;
}

// Per cell: the mean of a quantity's points times the cell's solid angle, and that mean's variance.
struct CellIntegrals {
  std::vector<double> value = std::vector<double>(kCells), variance = std::vector<double>(kCells);
  Estimate total() const {
    double t = 0, v = 0;
    for (int c = 0; c < kCells; ++c) t += value[std::size_t(c)], v += variance[std::size_t(c)];
    return {t, std::sqrt(v)};
  }
};

// values: one per point (cells in order, the strata of a cell in pairs of neighbours); each cell's integral and
// its variance by collapsed strata: with one point per stratum, the variance of the mean of M points is
// estimated as sum over the pairs of (f_a - f_b)^2 / M^2 (an overestimate by the strata's differences in mean).
CellIntegrals integrate(const std::vector<double>& values) {
  CellIntegrals r;
  const std::size_t per = values.size() / kCells;
  for (std::size_t c = 0; c < kCells; ++c) {
    const double* f = &values[c * per];
    double s = 0, d2 = 0;
    for (std::size_t k = 0; k < per; ++k) s += f[k];
    for (std::size_t k = 0; k + 1 < per; k += 2) d2 += (f[k] - f[k + 1]) * (f[k] - f[k + 1]);
    const double mean = s / double(per), var = per > 1 ? d2 / (double(per) * double(per)) : 0;
    r.value[c] = mean * kCellSolidAngle;
    r.variance[c] = var * kCellSolidAngle * kCellSolidAngle;
  }
  return r;
}

// The channel mean of eval() and pdf() at the points from wi.
void eval_points(const BsdfUnderTest& b, const Vec3<double>& wi, const std::vector<Vec3<double>>& w,
                 std::vector<double>& value, std::vector<double>& pdf, bool with_pdf = true) {
  const std::size_t n = w.size(), c = std::size_t(b.channels);
  std::vector<Vec3<double>> in(n, wi);
  std::vector<double> v(n * c);
  b.eval(in, w, v);
  value.assign(n, 0);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t k = 0; k < c; ++k) value[i] += v[c * i + k] / double(c);
  if (b.pdf && with_pdf) {
    pdf.assign(n, 0);
    b.pdf(in, w, pdf);
  }
}

double channel_mean(const double* v, int channels) {
  double s = 0;
  for (int k = 0; k < channels; ++k) s += v[k];
  return s / channels;
}

std::string chi2_detail(const ChiSquareResult& r) {
  return fmt::format("chi2 {:.4g}, {} dof, {} cells", r.statistic, r.dof, r.cells);
}

// A weighted chi-square line (shapes; InsufficientData: never a pass).
BatteryLine shape_line(const std::string& test, const std::string& view, const std::string& what,
                       std::span<const double> w1, std::span<const double> s1, std::span<const double> w2,
                       std::span<const double> s2, double level) {
  ChiSquareOptions co;
  co.significance = level;
  try {
    const ChiSquareResult r = weighted_homogeneity(w1, s1, w2, s2, co);
    return {test, view, fmt::format("{}: {}", what, chi2_detail(r)), r.p_value, r.p_value >= level};
  } catch (const InsufficientData& e) {
    return {test, view, fmt::format("{}: too little data ({})", what, e.what()), 0, false};
  }
}

// The weighted histogram of samples per cell (sums / drawn) and its variances.
void weighted_cells(const ViewSamples& s, int channels, std::vector<double>& w, std::vector<double>& var) {
  w.assign(kCells, 0), var.assign(kCells, 0);
  const double n = double(s.drawn);
  for (std::size_t i = 0; i < s.wo.size(); ++i) {
    const double x = channel_mean(&s.weight[std::size_t(channels) * i], channels);
    if (!std::isfinite(x) || !s.wo[i].allFinite()) continue;
    const std::size_t c = std::size_t(sphere_cell(s.wo[i]));
    w[c] += x / n, var[c] += x * x / (n * n);
  }
}

Estimate mean_weight(const ViewSamples& s, int channels) {
  double s1 = 0, s2 = 0;
  for (std::size_t i = 0; i < s.wo.size(); ++i) {
    const double x = channel_mean(&s.weight[std::size_t(channels) * i], channels);
    if (std::isfinite(x)) s1 += x, s2 += x * x;
  }
  const double n = double(s.drawn), mean = s1 / n;
  return {mean, std::sqrt(std::max(0.0, s2 / n - mean * mean) / (n - 1))};
}

BatteryResiduals residual_map(const std::string& test, const std::string& view, const std::vector<double>& a,
                              const std::vector<double>& va, const std::vector<double>& b, const std::vector<double>& vb) {
  double sa = 0, sb = 0;
  for (int c = 0; c < kCells; ++c) sa += a[std::size_t(c)], sb += b[std::size_t(c)];
  const double lambda = sb > 0 ? sa / sb : 1;
  BatteryResiduals r{test, view, kCellsZ, kCellsPhi, std::vector<double>(kCells, NAN)};
  for (std::size_t c = 0; c < kCells; ++c) {
    const double var = va[c] + lambda * lambda * vb[c], d = a[c] - lambda * b[c];
    if (var > 0) r.z[c] = d / std::sqrt(var);
    else if (d != 0) r.z[c] = d > 0 ? INFINITY : -INFINITY;
  }
  return r;
}

BatteryLine density_line(const ViewSamples& s, const CellIntegrals& pdf, const std::string& view, double level,
                         std::vector<BatteryResiduals>& residuals) {
  std::vector<double> counts(kCells, 0);
  for (const Vec3<double>& w : s.wo)
    if (w.allFinite()) counts[std::size_t(sphere_cell(w))] += 1;
  residuals.push_back(residual_map("density", view, counts, counts, pdf.value, pdf.variance));
  return shape_line("density", view, "sample counts against the integral of pdf() per cell", counts, counts,
                    pdf.value, pdf.variance, level);
}

double chi2_survival(double statistic, int dof) {
  if (dof < 1) return 1;
  return boost::math::cdf(boost::math::complement(boost::math::chi_squared(dof), statistic));
}

// The mean and standard error of a stochastic eval()'s channel mean at the pairs, from `repeats` calls each; a
// pair where fewer than half the calls gave a value other than 0 has no standard error to trust (an estimator
// with rare large contributions, the walk's at a pair its higher orders reach) and gets a NaN standard error.
std::vector<Estimate> repeated_eval(const BsdfUnderTest& b, const std::vector<BsdfQuery>& pairs, bool swap, int repeats) {
  const std::size_t r = std::size_t(std::max(2, repeats)), c = std::size_t(b.channels);
  std::vector<Vec3<double>> wi, wo;
  for (const BsdfQuery& q : pairs)
    for (std::size_t k = 0; k < r; ++k) wi.push_back(swap ? q.wo : q.wi), wo.push_back(swap ? q.wi : q.wo);
  std::vector<double> v(wi.size() * c);
  b.eval(wi, wo, v);
  std::vector<Estimate> out;
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    double s1 = 0, s2 = 0;
    std::size_t nonzero = 0;
    for (std::size_t k = 0; k < r; ++k) {
      const double x = channel_mean(&v[c * (p * r + k)], b.channels);
      s1 += x, s2 += x * x, nonzero += x != 0;
    }
    const double mean = s1 / double(r);
    const bool trusted = !b.stochastic_eval || nonzero == 0 || 2 * nonzero >= r;
    out.push_back({mean, trusted ? std::sqrt(std::max(0.0, s2 / double(r) - mean * mean) / double(r - 1)) : NAN});
  }
  return out;
}

// The chi-square over pairs of (a - b)^2 / (se_a^2 + se_b^2), pairs where both are exactly 0 left out, and
// those with an untrusted (NaN) standard error counted apart.
struct PairChi2 {
  double statistic = 0, worst_z = 0;
  int dof = 0, untrusted = 0;
  std::size_t worst = 0;
};
void add_pair(PairChi2& r, std::size_t i, const Estimate& a, const Estimate& b) {
  if (std::isnan(a.standard_error) || std::isnan(b.standard_error)) {
    ++r.untrusted;
    return;
  }
  const double var = a.standard_error * a.standard_error + b.standard_error * b.standard_error, d = a.value - b.value;
  if (var == 0 && d == 0) return;
  const double z2 = var > 0 ? d * d / var : INFINITY;
  r.statistic += z2, ++r.dof;
  if (z2 > r.worst_z * r.worst_z) r.worst_z = std::sqrt(z2), r.worst = i;
}

BatteryLine pair_line(const std::string& test, const PairChi2& r, const std::vector<BsdfQuery>& pairs,
                      const Estimate& worst_a, const Estimate& worst_b, const std::string& what, double level) {
  const double p = chi2_survival(r.statistic, r.dof);
  const BsdfQuery& q = pairs.empty() ? BsdfQuery{} : pairs[r.worst];
  std::string detail = fmt::format("{} over {} pairs ({} with too few non-zero estimates left out): chi2 {:.4g}, {} dof",
                                   what, pairs.size(), r.untrusted, r.statistic, r.dof);
  if (r.dof > 0)
    detail += fmt::format("; worst (z {:.3g}) {:.5g} +- {:.2g} against {:.5g} +- {:.2g} at wi ({:.3f}, {:.3f}, {:.3f}), "
                          "wo ({:.3f}, {:.3f}, {:.3f})", r.worst_z, worst_a.value, worst_a.standard_error, worst_b.value,
                          worst_b.standard_error, q.wi.x(), q.wi.y(), q.wi.z(), q.wo.x(), q.wo.y(), q.wo.z());
  return {test, "bsdf-queries", detail, p, r.dof > 0 && p >= level};
}

ScatterOptions walk_options(const Material& m, const Vec3<double>& wi, std::uint64_t paths, std::uint64_t seed,
                            const BatteryOptions& o) {
  ScatterOptions s;
  s.wi = wi, s.material = m, s.paths = paths, s.seed = seed, s.max_order = o.max_order, s.run = o.run;
  return s;
}

SmithMicrosurface walk_surface(const GGX<double>& ggx) {
  SmithMicrosurface s;
  s.alpha_x = ggx.alpha_x(), s.alpha_y = ggx.alpha_y();
  return s;
}

double index_at(const Material& m, const Vec3<double>& w) { return m.transmits() && w.z() < 0 ? m.eta() : 1.0; }

// The walk's next-event estimate at each pair (paths walks, seed + i for pair i), as the BSDF's eval(): f |cos wo|
// in the BSDF's transport mode, the channel mean, with its standard error.
std::vector<Estimate> walk_reference(const Material& m, const GGX<double>& ggx, const std::vector<BsdfQuery>& pairs,
                                     const BsdfConvention& convention, std::uint64_t paths, std::uint64_t seed,
                                     const BatteryOptions& o) {
  std::vector<Estimate> reference;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    if (o.run.cancelled()) throw Cancelled("the walk's eval");
    const SmithWalkEval e = smith_walk_eval(walk_surface(ggx), walk_options(m, pairs[i].wi, paths, seed + i, o), pairs[i].wo);
    // The walk's f is in importance transport; radiance holds (n_wi / n_wo)^2 more.
    const double n = index_at(m, pairs[i].wi) / index_at(m, pairs[i].wo);
    const double scale = std::abs(pairs[i].wo.z()) * (convention.transport == TransportMode::radiance ? n * n : 1.0);
    double v = 0, var = 0;
    for (int c = 0; c < m.channels(); ++c) {
      const Estimate x = e.value(c);
      v += x.value * scale / m.channels(), var += std::pow(x.standard_error * scale / m.channels(), 2);
    }
    reference.push_back({v, std::sqrt(var)});
  }
  return reference;
}

BatteryLine eval_stage(const std::vector<BsdfQuery>& pairs, const std::vector<Estimate>& given,
                       const std::vector<Estimate>& reference, double level) {
  PairChi2 chi;
  for (std::size_t i = 0; i < pairs.size(); ++i) add_pair(chi, i, given[i], reference[i]);
  return pair_line("eval", chi, pairs, given.empty() ? Estimate{} : given[chi.worst],
                   reference.empty() ? Estimate{} : reference[chi.worst], "eval() against the walk's next-event eval",
                   level);
}

BatteryLine reciprocity_stage(const BsdfUnderTest& b, const Material& m, const std::vector<BsdfQuery>& pairs,
                              const std::vector<Estimate>& forward, const std::vector<Estimate>& backward, double level) {
  PairChi2 chi;
  std::vector<Estimate> a, e;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const double ci = std::abs(pairs[i].wi.z()), co = std::abs(pairs[i].wo.z());
    const double ratio = reciprocal_ratio(m, b.convention, pairs[i].wi, pairs[i].wo);
    a.push_back({backward[i].value / ci, backward[i].standard_error / ci});
    e.push_back({forward[i].value / co * ratio, forward[i].standard_error / co * ratio});
    add_pair(chi, i, a.back(), e.back());
  }
  return pair_line("reciprocity", chi, pairs, a.empty() ? Estimate{} : a[chi.worst], e.empty() ? Estimate{} : e[chi.worst],
                   "f(wo, wi) against reciprocity's f(wi, wo)", level);
}

// A stochastic eval()'s integral test that rejected, again on fresh cell points (kRecheckPoints times as many, another
// seed: fresh calls), each cell's variance at least the first stage's scaled to the larger count; the line and the
// view's integral residual map become the second stage's.
void recheck_integral(const BsdfUnderTest& b, const Vec3<double>& wi, const ViewSamples& s, const std::string& view,
                      double level, const BatteryOptions& o, const std::vector<double>& first_values,
                      std::vector<BatteryLine>& lines, std::vector<BatteryResiduals>& residuals) {
  const auto line = std::find_if(lines.begin(), lines.end(), [](const BatteryLine& l) { return l.test == "integral"; });
  if (line == lines.end() || line->passed) return;
  const std::vector<Vec3<double>> points =
      cell_points(o.points_per_cell * kRecheckPoints, ~(o.seed + std::uint64_t(sphere_cell(wi))));
  std::vector<double> value, unused;
  eval_points(b, wi, points, value, unused, false);
  const CellIntegrals first = integrate(first_values);
  CellIntegrals second = integrate(value);
  const double ratio = double(first_values.size()) / double(value.size());
  for (std::size_t c = 0; c < kCells; ++c) second.variance[c] = std::max(second.variance[c], first.variance[c] * ratio);
  std::vector<double> w, var;
  weighted_cells(s, b.channels, w, var);
  for (BatteryResiduals& r : residuals)
    if (r.test == "integral" && r.view == view) r = residual_map("integral", view, w, var, second.value, second.variance);
  *line = two_stage(*line, shape_line("integral", view, "weighted samples against the integral of eval() per cell", w, var,
                                      second.value, second.variance, level),
                    kRecheckPoints, "cell points");
}

}  // namespace

DominantValue weight_dominance(const ViewSamples& s, int channels) {
  DominanceTally t;
  for (std::size_t i = 0; i < s.wo.size(); ++i) t.add(channel_mean(&s.weight[std::size_t(channels) * i], channels));
  t.add_zeros(s.drawn - s.wo.size());
  return t.result();
}

void fail_if_dominated(const DominantValue& d, BatteryLine& line) {
  if (!d.dominates()) return;
  line.passed = false;
  line.tested = true;
  line.detail += "; " + d.firefly();
}

int cell_strata(int points_per_cell) { return std::max(2, 2 * int(std::lround(std::sqrt(double(points_per_cell)) / 2))); }

std::vector<Vec3<double>> cell_points(int points_per_cell, std::uint64_t seed) {
  const int n = cell_strata(points_per_cell);
  std::vector<Vec3<double>> w;
  w.reserve(std::size_t(kCells * n * n));
  for (int c = 0; c < kCells; ++c) {
    CounterRng rng(seed ^ 0x5e1fc4ecull, std::uint64_t(c));
    const int iz = c / kCellsPhi, ip = c % kCellsPhi;
    for (int a = 0; a < n; ++a)
      for (int b = 0; b < n; ++b) {
        const double z = -1 + 2 * (iz + (a + rng.uniform()) / n) / kCellsZ;
        const double phi = 2 * std::numbers::pi * (ip + (b + rng.uniform()) / n) / kCellsPhi;
        const double r = std::sqrt(std::max(0.0, 1 - z * z));
        w.emplace_back(r * std::cos(phi), r * std::sin(phi), z);
      }
  }
  return w;
}

int sphere_cell(const Vec3<double>& w) {
  const int iz = std::clamp(int((w.z() + 1) / 2 * kCellsZ), 0, kCellsZ - 1);
  double phi = std::atan2(w.y(), w.x());
  if (phi < 0) phi += 2 * std::numbers::pi;
  const int ip = std::clamp(int(phi / (2 * std::numbers::pi) * kCellsPhi), 0, kCellsPhi - 1);
  return iz * kCellsPhi + ip;
}

std::vector<BatteryLine> self_tests(const BsdfUnderTest& b, const Vec3<double>& wi, const ViewSamples& s,
                                    const std::string& view, double level, const BatteryOptions& o,
                                    std::vector<BatteryResiduals>& residuals) {
  const std::vector<Vec3<double>> points = cell_points(o.points_per_cell, o.seed + std::uint64_t(sphere_cell(wi)));
  std::vector<double> value, pdf;
  eval_points(b, wi, points, value, pdf);
  std::vector<BatteryLine> lines = cell_tests(s, b.channels, value, pdf, view, level, residuals);
  if (b.stochastic_eval) recheck_integral(b, wi, s, view, level, o, value, lines, residuals);
  return lines;
}

std::vector<BatteryLine> cell_tests(const ViewSamples& s, int channels, const std::vector<double>& value,
                                    const std::vector<double>& pdf, const std::string& view, double level,
                                    std::vector<BatteryResiduals>& residuals) {
  const CellIntegrals eval_cells = integrate(value);
  std::vector<BatteryLine> lines;
  if (!pdf.empty()) lines.push_back(density_line(s, integrate(pdf), view, level, residuals));
  std::vector<double> w, var;
  weighted_cells(s, channels, w, var);
  residuals.push_back(residual_map("integral", view, w, var, eval_cells.value, eval_cells.variance));
  lines.push_back(shape_line("integral", view, "weighted samples against the integral of eval() per cell", w, var,
                             eval_cells.value, eval_cells.variance, level));
  const DominantValue dominant = weight_dominance(s, channels);
  fail_if_dominated(dominant, lines.back());
  const Estimate mean = mean_weight(s, channels), integral = eval_cells.total();
  const double p = difference_p(mean, integral);
  lines.push_back({"furnace", view,
                   fmt::format("mean weight {:.5f} +- {:.5f}, integral of eval cos {:.5f} +- {:.5f}", mean.value,
                               mean.standard_error, integral.value, integral.standard_error),
                   p, p >= level});
  fail_if_dominated(dominant, lines.back());
  return lines;
}

BatteryLine sampling_against_walk(const BsdfUnderTest& b, const Material& m, const GGX<double>& ggx,
                                  const Vec3<double>& wi, const ViewSamples& s, const std::string& view, double level,
                                  const BatteryOptions& o) {
  const WalkSamples walk = smith_walk_samples(walk_surface(ggx), walk_options(m, wi, o.samples, o.seed ^ 0x3a1c0ull, o));
  ViewSamples ref;
  ref.drawn = o.samples;
  const std::size_t row = std::size_t(3 + walk.channels);
  for (std::size_t i = 0; i + row <= walk.rows.size(); i += row) {
    ref.wo.emplace_back(walk.rows[i], walk.rows[i + 1], walk.rows[i + 2]);
    ref.weight.insert(ref.weight.end(), walk.rows.begin() + std::ptrdiff_t(i + 3), walk.rows.begin() + std::ptrdiff_t(i + row));
  }
  std::vector<double> w1, s1, w2, s2;
  weighted_cells(s, b.channels, w1, s1);
  weighted_cells(ref, walk.channels, w2, s2);
  BatteryLine shape = shape_line("sampling", view, "weighted samples against the walk's", w1, s1, w2, s2, level);
  const Estimate a = mean_weight(s, b.channels), r = mean_weight(ref, walk.channels);
  const double p = difference_p(a, r);
  shape.detail += fmt::format("; albedo {:.5f} +- {:.5f} against the walk's {:.5f} +- {:.5f} (p {:.3g})", a.value,
                              a.standard_error, r.value, r.standard_error, p);
  shape.passed = shape.passed && p >= level;
  shape.p = std::min(shape.p, p);
  fail_if_dominated(weight_dominance(s, b.channels), shape);
  return shape;
}

std::vector<BsdfQuery> stochastic_pairs(const std::vector<BsdfQuery>& q, std::size_t count) {
  std::vector<BsdfQuery> usable;
  for (const BsdfQuery& x : q)
    if (std::abs(x.wi.z()) >= 0.1 && std::abs(x.wo.z()) >= 0.1) usable.push_back(x);
  if (usable.size() <= count) return usable;
  std::vector<BsdfQuery> out;
  for (std::size_t k = 0; k < count; ++k) out.push_back(usable[k * usable.size() / count]);
  return out;
}

BatteryLine eval_against_walk(const BsdfUnderTest& b, const Material& m, const GGX<double>& ggx,
                              const std::vector<BsdfQuery>& pairs, double level, const BatteryOptions& o) {
  const int r1 = b.stochastic_eval ? std::max(2, o.eval_repeats) : 2;
  const std::vector<Estimate> given = repeated_eval(b, pairs, false, r1);
  const std::vector<Estimate> reference = walk_reference(m, ggx, pairs, b.convention, o.reference_paths, o.seed, o);
  const BatteryLine first = eval_stage(pairs, given, reference, level);
  if (first.passed || !b.stochastic_eval) return first;
  // Stage 2: fresh calls of the BSDF, kRecheckCalls times as many, and fresh walks of the reference (another seed).
  const int r2 = r1 * kRecheckCalls;
  const double ratio = double(r1) / double(r2);
  const std::vector<Estimate> given2 = floored(repeated_eval(b, pairs, false, r2), given, ratio);
  const std::uint64_t paths = o.reference_paths * kRecheckReferenceWalks;
  const std::vector<Estimate> reference2 = floored(walk_reference(m, ggx, pairs, b.convention, paths, ~o.seed, o), reference,
                                                   1.0 / kRecheckReferenceWalks);
  const double cv = std::max(largest_cv(given, r1), largest_cv(given2, r2));
  const double cv_walk = std::max(largest_cv(reference, int(o.reference_paths)), largest_cv(reference2, int(paths)));
  BatteryLine second = eval_stage(pairs, pooled(given2, cv, r2), pooled(reference2, cv_walk, int(paths)), level);
  second.detail += fmt::format("; relative standard deviation per call (per walk of the reference) pooled over the "
                               "pairs {:.3g} ({:.3g})", cv, cv_walk);
  return two_stage(first, second, kRecheckCalls, "calls (and 4 times the reference's walks)");
}

BatteryLine stochastic_reciprocity(const BsdfUnderTest& b, const Material& m, const std::vector<BsdfQuery>& pairs,
                                   double level, const BatteryOptions& o) {
  const int r1 = std::max(2, o.eval_repeats);
  const std::vector<Estimate> forward = repeated_eval(b, pairs, false, r1), backward = repeated_eval(b, pairs, true, r1);
  const BatteryLine first = reciprocity_stage(b, m, pairs, forward, backward, level);
  if (first.passed || !b.stochastic_eval) return first;
  const int r2 = r1 * kRecheckCalls;
  const double ratio = double(r1) / double(r2);
  const std::vector<Estimate> forward2 = floored(repeated_eval(b, pairs, false, r2), forward, ratio);
  const std::vector<Estimate> backward2 = floored(repeated_eval(b, pairs, true, r2), backward, ratio);
  const double cv = std::max({largest_cv(forward, r1), largest_cv(backward, r1), largest_cv(forward2, r2),
                              largest_cv(backward2, r2)});
  BatteryLine second = reciprocity_stage(b, m, pairs, pooled(forward2, cv, r2), pooled(backward2, cv, r2), level);
  second.detail += fmt::format("; relative standard deviation per call pooled over the pairs {:.3g}", cv);
  return two_stage(first, second, kRecheckCalls, "calls");
}

double reciprocal_ratio(const Material& m, const BsdfConvention& c, const Vec3<double>& a, const Vec3<double>& b) {
  const double na = index_at(m, a), nb = index_at(m, b);
  if (na == nb) return 1.0;
  return c.transport == TransportMode::importance ? (na * na) / (nb * nb) : (nb * nb) / (na * na);
}

}  // namespace microsim::battery
