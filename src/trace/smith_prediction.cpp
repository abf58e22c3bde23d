// microsim: Smith predictions for heightfields, analytic and empirical (see smith_prediction.h).
#include "trace/smith_prediction.h"

#include "core/strict_parse.h"

#include <fmt/core.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>

namespace microsim {

// ---- analytic --------------------------------------------------------------------------------------------

AnalyticSmith::AnalyticSmith(NdfKind ndf, double alpha_x, double alpha_y)
    : ndf_(ndf), ax_(std::max(alpha_x, kMinAlpha)), ay_(std::max(alpha_y, kMinAlpha)) {
  if (!std::isfinite(alpha_x) || !std::isfinite(alpha_y) || !(alpha_x > 0) || !(alpha_y > 0)) {
    throw std::invalid_argument(fmt::format("Smith reference roughness ({}, {}) must be positive and finite", alpha_x, alpha_y));
  }
}

std::string AnalyticSmith::describe() const { return fmt::format("{} alpha ({:.6g}, {:.6g})", to_string(ndf_), ax_, ay_); }

double AnalyticSmith::D(const Vec3<double>& m) const {
  if (ndf_ == NdfKind::ggx) return GGX<double>(ax_, ay_).D(m);
  if (!(m.z() > 0)) return 0.0;
  const Vec3<double> u = m.normalized();
  const double mz = u.z();
  const double e = sqr(u.x() / (mz * ax_)) + sqr(u.y() / (mz * ay_));  // |stretched slope|^2
  return std::exp(-e) / (kPi<double> * ax_ * ay_ * sqr(sqr(mz)));
}

double AnalyticSmith::Lambda(const Vec3<double>& w) const {
  if (ndf_ == NdfKind::ggx) return GGX<double>(ax_, ay_).Lambda(w);
  const double z = std::abs(w.z());
  const double r2 = sqr(ax_ * w.x()) + sqr(ay_ * w.y());  // alpha(phi)^2 sin^2 theta (for unit w)
  if (r2 == 0) return 0.0;
  if (z == 0) return std::numeric_limits<double>::infinity();
  const double a = z / std::sqrt(r2);  // 1 / (alpha(phi) tan theta)
  // (erf(a) - 1)/2 + exp(-a^2)/(2 a sqrt(pi)), written with erfc so that neither term is a difference
  // of two numbers near 1; for large a both terms underflow towards 0 together (Lambda -> 0).
  const double value = 0.5 * (std::exp(-a * a) / (a * std::sqrt(kPi<double>)) - std::erfc(a));
  return std::max(value, 0.0);  // round-off can leave a tiny negative at large a
}

double AnalyticSmith::G1(const Vec3<double>& w) const {
  if (!(w.z() > 0)) return 0.0;
  const double l = Lambda(w);
  return std::isfinite(l) ? 1.0 / (1.0 + l) : 0.0;
}

double AnalyticSmith::G2(const Vec3<double>& wi, const Vec3<double>& wo) const {
  if (!(wi.z() > 0) || !(wo.z() > 0)) return 0.0;
  const double li = Lambda(wi), lo = Lambda(wo);
  if (!std::isfinite(li) || !std::isfinite(lo)) return 0.0;
  return 1.0 / (1.0 + li + lo);
}

double AnalyticSmith::vndf(const Vec3<double>& w, const Vec3<double>& m) const {
  if (ndf_ == NdfKind::ggx) return GGX<double>(ax_, ay_).visible_normal_pdf(w, m);
  if (!(w.z() > 0)) return 0.0;
  const double wm = w.dot(m);
  if (!(wm > 0)) return 0.0;
  return G1(w) * wm * D(m) / w.z();
}

namespace {

// The reference stated in a heightmap's metadata (alpha_x, alpha_y, reference_ndf). Stated roughness that
// is not a number is an error, not a reason to fit silently.
AnalyticSmith stated_reference(const std::map<std::string, std::string>& md) {
  const auto alpha = [&](const std::string& key) {
    const std::string& text = md.at(key);
    const std::optional<double> v = reader::parse_finite_double(text);
    if (!v || !(*v > 0))
      throw std::invalid_argument(fmt::format("heightmap attribute microsim.{} = {} is not a finite number > 0", key,
                                              reader::quote_excerpt(text)));
    return *v;
  };
  const auto ref = md.find("reference_ndf");
  const std::optional<NdfKind> named = ref == md.end() ? NdfKind::ggx : ndf_kind_from_string(ref->second);
  if (!named)
    throw std::invalid_argument(fmt::format("heightmap attribute microsim.reference_ndf = {} is neither 'ggx' nor "
                                            "'beckmann'", reader::quote_excerpt(ref->second)));
  const NdfKind ndf = *named;
  const double alpha_x = alpha("alpha_x"), alpha_y = alpha("alpha_y");
  return AnalyticSmith(ndf, alpha_x, alpha_y);
}

// A GGX fit from the median |slope| per axis (the |x-slope| of GGX has median alpha_x / sqrt(3)).
AnalyticSmith fitted_reference(const microgeom::Heightfield& field) {
  const int n = field.resolution();
  std::vector<float> sx(field.triangle_count()), sy(field.triangle_count());
  tbb::parallel_for(0, n, [&](int j) {
    for (int i = 0; i < n; ++i) {
      for (int t = 0; t < 2; ++t) {
        const Eigen::Vector2d s = field.triangle_slope(i, j, t);
        const std::size_t k = field.triangle_id(i, j, t);
        sx[k] = float(std::abs(s.x()));
        sy[k] = float(std::abs(s.y()));
      }
    }
  });
  auto median = [](std::vector<float>& v) {
    auto mid = v.begin() + std::ptrdiff_t(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    return double(*mid);
  };
  const double alpha_x = std::sqrt(3.0) * median(sx), alpha_y = std::sqrt(3.0) * median(sy);
  return AnalyticSmith(NdfKind::ggx, std::max(alpha_x, kMinAlpha), std::max(alpha_y, kMinAlpha));
}

}  // namespace

AnalyticSmith analytic_reference(const microgeom::Heightfield& field, std::string* source) {
  if (field.metadata.count("alpha_x") && field.metadata.count("alpha_y")) {
    AnalyticSmith stated = stated_reference(field.metadata);
    if (source) *source = "metadata";
    return stated;
  }
  AnalyticSmith fitted = fitted_reference(field);
  if (source) *source = "fitted";
  return fitted;
}

// ---- empirical -------------------------------------------------------------------------------------------

namespace {
constexpr int kRowsPerBlock = 8;

// Calls f(sx, sy) for the two triangles of every cell of row j, in a fixed order.
template <class F> inline void for_each_slope_in_row(const microgeom::Heightfield& field, int j, F&& f) {
  const int n = field.resolution();
  const double inv_h = 1.0 / field.cell_size();
  const int j1 = j + 1 == n ? 0 : j + 1;
  for (int i = 0; i < n; ++i) {
    const int i1 = i + 1 == n ? 0 : i + 1;
    const double h00 = field.height_unchecked(i, j), h10 = field.height_unchecked(i1, j),
                 h01 = field.height_unchecked(i, j1), h11 = field.height_unchecked(i1, j1);
    f((h10 - h00) * inv_h, (h11 - h10) * inv_h);  // triangle 0 (Heightfield's slopes)
    f((h11 - h01) * inv_h, (h01 - h00) * inv_h);  // triangle 1
  }
}
}  // namespace

double deterministic_row_sum(int n, const std::function<double(int)>& f) {
  const int blocks = (n + kRowsPerBlock - 1) / kRowsPerBlock;
  std::vector<double> partial(std::size_t(blocks), 0.0);
  tbb::parallel_for(0, blocks, [&](int b) {
    double s = 0;
    for (int j = b * kRowsPerBlock; j < std::min(n, (b + 1) * kRowsPerBlock); ++j) s += f(j);
    partial[std::size_t(b)] = s;
  });
  double total = 0;
  for (double p : partial) total += p;
  return total;
}

struct EmpiricalSmith::Tables {
  // Per azimuth k: suffix sums over bins b' >= b of the count and of the sum of positive projected slopes.
  std::vector<std::vector<double>> count_suffix, sum_suffix;
  double triangles = 0;
};

EmpiricalSmith::EmpiricalSmith(const microgeom::Heightfield& field) : field_(field) {
  sorted_heights_ = field.heights();
  std::sort(sorted_heights_.begin(), sorted_heights_.end());
}

EmpiricalSmith::~EmpiricalSmith() = default;

double EmpiricalSmith::Lambda(const Vec3<double>& w) const {
  if (!(w.z() > 0)) return std::numeric_limits<double>::infinity();
  if (w.x() == 0 && w.y() == 0) return 0.0;
  const double wx = w.x(), wy = w.y(), wz = w.z();
  const double sum = deterministic_row_sum(field_.resolution(), [&](int j) {
    double s = 0;
    for_each_slope_in_row(field_, j, [&](double sx, double sy) { s += std::max(sx * wx + sy * wy - wz, 0.0); });
    return s;
  });
  return sum / (double(field_.triangle_count()) * wz);
}

double EmpiricalSmith::projected_area(const Vec3<double>& w) const {
  const double wx = w.x(), wy = w.y(), wz = w.z();
  const double sum = deterministic_row_sum(field_.resolution(), [&](int j) {
    double s = 0;
    for_each_slope_in_row(field_, j, [&](double sx, double sy) { s += std::max(wz - sx * wx - sy * wy, 0.0); });
    return s;
  });
  return sum / double(field_.triangle_count());
}

double EmpiricalSmith::G2(const Vec3<double>& wi, const Vec3<double>& wo) const {
  if (!(wi.z() > 0) || !(wo.z() > 0)) return 0.0;
  const double li = Lambda(wi), lo = Lambda(wo);
  if (!std::isfinite(li) || !std::isfinite(lo)) return 0.0;
  return 1.0 / (1.0 + li + lo);
}

std::vector<double> EmpiricalSmith::vndf_bin_probabilities(const DirectionBinning& binning, const Vec3<double>& w) const {
  const int n = field_.resolution();
  const int blocks = (n + kRowsPerBlock - 1) / kRowsPerBlock;
  const std::size_t bins = std::size_t(binning.size());
  std::vector<std::vector<double>> partial(static_cast<std::size_t>(blocks));
  std::vector<double> partial_total(std::size_t(blocks), 0.0);
  const double wx = w.x(), wy = w.y(), wz = w.z();
  tbb::parallel_for(0, blocks, [&](int b) {
    std::vector<double> local(bins, 0.0);
    double total = 0;
    for (int j = b * kRowsPerBlock; j < std::min(n, (b + 1) * kRowsPerBlock); ++j) {
      for_each_slope_in_row(field_, j, [&](double sx, double sy) {
        const double weight = wz - sx * wx - sy * wy;  // <w, m> / mz
        if (!(weight > 0)) return;
        total += weight;
        const auto bin = binning.bin_of(Vec3<double>(-sx, -sy, 1.0));
        if (bin) local[std::size_t(*bin)] += weight;
      });
    }
    partial[std::size_t(b)] = std::move(local);
    partial_total[std::size_t(b)] = total;
  });
  std::vector<double> p(bins, 0.0);
  double total = 0;
  for (int b = 0; b < blocks; ++b) {
    for (std::size_t k = 0; k < bins; ++k) p[k] += partial[std::size_t(b)][k];
    total += partial_total[std::size_t(b)];
  }
  if (total > 0)
    for (double& x : p) x /= total;
  return p;
}

void EmpiricalSmith::build_tables() const {
  auto tables = std::make_unique<Tables>();
  tables->count_suffix.resize(kAzimuths);
  tables->sum_suffix.resize(kAzimuths);
  tables->triangles = double(field_.triangle_count());
  const int n = field_.resolution();
  // One task per azimuth, each a sequential pass over all triangles: deterministic.
  tbb::parallel_for(0, kAzimuths, [&](int k) {
    const double phi = 2.0 * kPi<double> * k / kAzimuths;
    const double c = std::cos(phi), s = std::sin(phi);
    std::vector<double> count(kSlopeBins + 1, 0.0), sum(kSlopeBins + 1, 0.0);
    for (int j = 0; j < n; ++j) {
      for_each_slope_in_row(field_, j, [&](double sx, double sy) {
        const double p = sx * c + sy * s;
        if (!(p > 0)) return;
        const int b = std::min(int(p / (1.0 + p) * kSlopeBins), kSlopeBins - 1);
        count[std::size_t(b)] += 1.0;
        sum[std::size_t(b)] += p;
      });
    }
    for (int b = kSlopeBins - 1; b >= 0; --b) {
      count[std::size_t(b)] += count[std::size_t(b) + 1];
      sum[std::size_t(b)] += sum[std::size_t(b) + 1];
    }
    tables->count_suffix[std::size_t(k)] = std::move(count);
    tables->sum_suffix[std::size_t(k)] = std::move(sum);
  });
  tables_ = std::move(tables);
}

double EmpiricalSmith::Lambda_tabulated(const Vec3<double>& w) const {
  if (!(w.z() > 0)) return std::numeric_limits<double>::infinity();
  const double rxy = std::hypot(w.x(), w.y());
  if (rxy == 0) return 0.0;
  std::call_once(tables_once_, [this] { build_tables(); });
  const Tables& t = *tables_;
  const double mu = w.z() / rxy;  // cot(theta)
  // E[(p - mu)+] for azimuth k from its suffix sums; inside mu's bin, slopes taken as uniform in p.
  auto excess = [&](int k) {
    const auto& cs = t.count_suffix[std::size_t(k)];
    const auto& ss = t.sum_suffix[std::size_t(k)];
    const double q = mu / (1.0 + mu);
    const int b = std::min(int(q * kSlopeBins), kSlopeBins - 1);
    double e = (ss[std::size_t(b) + 1] - mu * cs[std::size_t(b) + 1]);
    const double in_bin = cs[std::size_t(b)] - cs[std::size_t(b) + 1];
    if (in_bin > 0) {
      const double q_hi = double(b + 1) / kSlopeBins;
      const double p_lo = double(b) / kSlopeBins / (1.0 - double(b) / kSlopeBins);
      if (b + 1 < kSlopeBins) {
        const double p_hi = q_hi / (1.0 - q_hi);
        e += in_bin * sqr(std::max(p_hi - mu, 0.0)) / (2.0 * (p_hi - p_lo));
      } else {  // the last bin is unbounded: use its mean slope
        const double mean = (ss[std::size_t(b)] - ss[std::size_t(b) + 1]) / in_bin;
        e += in_bin * std::max(mean - mu, 0.0);
      }
    }
    return std::max(e, 0.0) / t.triangles;
  };
  double phi = std::atan2(w.y(), w.x());
  if (phi < 0) phi += 2.0 * kPi<double>;
  const double x = phi / (2.0 * kPi<double>) * kAzimuths;
  const int k0 = std::min(int(x), kAzimuths - 1);
  const double f = x - k0;
  const int k1 = (k0 + 1) % kAzimuths;
  return ((1.0 - f) * excess(k0) + f * excess(k1)) / mu;
}

double EmpiricalSmith::G2_tabulated(const Vec3<double>& wi, const Vec3<double>& wo) const {
  if (!(wi.z() > 0) || !(wo.z() > 0)) return 0.0;
  const double li = Lambda_tabulated(wi), lo = Lambda_tabulated(wo);
  if (!std::isfinite(li) || !std::isfinite(lo)) return 0.0;
  return 1.0 / (1.0 + li + lo);
}

double EmpiricalSmith::height_cdf(double z) const {
  const auto it = std::upper_bound(sorted_heights_.begin(), sorted_heights_.end(), float(z));
  return double(it - sorted_heights_.begin()) / double(sorted_heights_.size());
}

double EmpiricalSmith::height_masking(double c1, double lambda) {
  if (!(c1 > 0)) return 0.0;
  if (!std::isfinite(lambda)) return c1 >= 1.0 ? 1.0 : 0.0;
  return std::pow(std::min(c1, 1.0), lambda);
}

}  // namespace microsim
