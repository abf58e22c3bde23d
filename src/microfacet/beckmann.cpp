// microsim: the exact inversion of the Beckmann visible-slope CDF (beckmann.h).
//
// In the standard (alpha = 1) configuration seen from (sin t, 0, cos t), the visible slopes have density
// proportional to (cos t - x sin t)+ exp(-x^2 - y^2) (Heitz & d'Eon 2014, appendix): y is independent of x
// and Gaussian, and for sin t > 0 the marginal of x is proportional to
//     p(x) = (a - x) exp(-x^2),   x < a = cot t,
// on either side of the horizon (a < 0: the view is below it, only steep slopes x < a < 0 face it). With
// s = a - x >= 0 (the distance to the visibility edge) the two tails of p are
//     H(x) = int_-inf^x p = exp(-x^2) / 2 + a (sqrt(pi) / 2) erfc(-x)            (lower tail)
//     G(x) = int_x^a p = int_0^s sigma exp(-(a - sigma)^2) d sigma                (upper tail)
// and the total is N = H(a). We solve ln H(x) = ln(u N) for u <= 1/2 and ln G(x) = ln((1 - u) N) above, so
// that each side of the distribution is inverted from the tail that keeps its relative precision, by
// Halley's method (Boost.Math's halley_iterate, bracketed: samplers_impl.h halley_root). Everything is in
// logarithms, so that nothing underflows for views far below the horizon (a -> -inf, where the whole
// distribution sits within about 1 / |a| of the edge) or far from it.
//
// How each tail is evaluated without cancellation:
// - H for x <= -3: with Laplace's continued fraction for erfc (beckmann.h, erfc_fraction_tail c(z)),
//   H = exp(-x^2) (s + c(-x)) / (2 (-x + c(-x))): two positive terms. For x > -3, directly (a >= 0: both
//   terms positive; a < 0, so -3 < x < a < 0: a loss of at most a factor 20).
// - G where exp(-t^2) varies by at most e^2.5 over [x, a]: 20-point Gauss-Legendre on the scaled
//   integrand (exact to rounding there). Elsewhere G = N - H, as N (1 - exp(ln H - ln N)), which then keeps
//   G / N above about 0.3 for a < 0; for a >= 0 and x >= 3 (the top of a narrow lobe seen near the normal)
//   by the continued fraction instead: exp(x^2) G = ((s - c(x)) / (x + c(x)) + exp(-s (a + x)) c(a) /
//   (a + c(a))) / 2, whose first term is at least 0.4 of the sum there.
#include "microfacet/beckmann.h"

#include <boost/math/quadrature/gauss.hpp>
#include <boost/math/special_functions/erf.hpp>

#include <cmath>
#include <tuple>

namespace microsim::detail {
namespace {

constexpr double kLn2 = 0.693147180559945309417;
// The exponent spread over [x, a] below which the upper tail is integrated by Gauss-Legendre.
constexpr double kQuadratureSpread = 2.5;
// The variates are kept in [2^-64, 1 - 2^-54]: u = 0 would ask for the limit x = -inf (a horizontal normal,
// of density 0), a set of probability 2^-53.
constexpr double kMinU = 0x1p-64;

double c_tail(double z) { return erfc_fraction_tail(z); }

// The marginal of the visible slope x for a = cot t (see the file comment).
struct SlopeMarginal {
  double a;

  // ln H(x), s = a - x.
  double ln_lower(double x, double s) const {
    const double z = -x;
    if (z >= 3) {
      const double c = c_tail(z);
      return -z * z + std::log((s + c) / (2 * (z + c)));
    }
    if (z >= 0) return -z * z + std::log(0.5 + 0.5 * a * kSqrtPi * std::exp(z * z) * std::erfc(z));
    return std::log(0.5 * std::exp(-z * z) + 0.5 * a * kSqrtPi * std::erfc(z));
  }

  double ln_total() const { return ln_lower(a, 0.0); }

  // ln G(x) by quadrature: int_0^s sigma exp(-(t^2 - t0^2)) d sigma (t = a - sigma), t0 the point of [x, a]
  // nearest 0, times exp(-t0^2). t - t0 is formed from sigma without cancellation.
  double ln_upper_quadrature(double x, double s) const {
    enum { at_zero, at_a, at_x } where = (x <= 0 && a >= 0) ? at_zero : (a < 0 ? at_a : at_x);
    const double t0 = where == at_zero ? 0.0 : (where == at_a ? a : x);
    const auto f = [&](double sigma) {
      const double d = where == at_zero ? a - sigma : (where == at_a ? -sigma : s - sigma);  // t - t0
      return sigma * std::exp(-d * (d + 2 * t0));
    };
    const double integral = boost::math::quadrature::gauss<double, 20>::integrate(f, 0.0, s);
    return -t0 * t0 + std::log(integral);
  }

  // ln G(x), s = a - x.
  double ln_upper(double x, double s) const {
    const double t0 = (x <= 0 && a >= 0) ? 0.0 : std::min(std::abs(x), std::abs(a));
    const double spread = std::max(x * x, a * a) - t0 * t0;
    if (spread <= kQuadratureSpread) return ln_upper_quadrature(x, s);
    if (a >= 0 && x >= 3) {
      const double cx = c_tail(x), ca = c_tail(a);
      return -x * x - kLn2 + std::log((s - cx) / (x + cx) + std::exp(-s * (a + x)) * ca / (a + ca));
    }
    const double ln_n = ln_total();
    return ln_n + std::log(-std::expm1(std::min(ln_lower(x, s) - ln_n, 0.0)));
  }

  // (f, f', f'') in x of ln P(x) - target for the tail P = H (lower) or G: P' = +-p, p = s exp(-x^2),
  // (ln P)' = r = +-p / P and (ln P)'' = r p'/p - r^2 with p'/p = -1/s - 2x.
  std::tuple<double, double, double> log_tail(double x, double s, bool lower, double target) const {
    const double ln_p = lower ? ln_lower(x, s) : ln_upper(x, s);
    const double ratio = std::exp(std::log(s) - x * x - ln_p);
    const double r = lower ? ratio : -ratio;
    return {ln_p - target, r, r * (-1 / s - 2 * x) - r * r};
  }
};

// x ~ N(0, 1/2) from u (the view along the normal: every slope is visible with the same weight).
double gaussian_slope(double u) { return beckmann_slope_y(u); }

// Views on or above the horizon (a >= 0). The lower half is solved in x on [-30, min(a - 2^-28, 30)]: at -30
// the lower tail is beyond any target (ln H = -900 against ln(u N) >= ln(2^-64 / 2)). The upper half is
// solved in s = a - x when the edge is near (a < 30), on [2^-28, a + 30] (G / N < 2^-56 at the lower end),
// so that Halley's stopping rule, relative to the unknown, follows the scale of the distribution near the
// edge; with the edge far away (a >= 30, where G / N < e^-800 near it) in x on [-30, 30].
double slope_above_horizon(const SlopeMarginal& pm, double u) {
  const bool lower = u <= 0.5;
  const double target = pm.ln_total() + (lower ? std::log(u) : std::log1p(-u));
  // Start between the two exact limits: a = 0 (H / N = exp(-x^2)) and a = inf (a Gaussian of variance 1/2).
  const double w = pm.a / (1 + pm.a);
  const double guess = w * gaussian_slope(u) + (1 - w) * -std::sqrt(-std::log(u));
  auto in_x = [&](double x) { return pm.log_tail(x, pm.a - x, lower, target); };
  if (lower || pm.a >= 30) {
    const double lo = -30, hi = std::min(pm.a - 0x1p-28, 30.0);
    return halley_root(in_x, std::clamp(guess, lo, hi), lo, hi);
  }
  auto in_s = [&](double s) {
    const auto [f, d1, d2] = pm.log_tail(pm.a - s, s, false, target);
    return std::make_tuple(f, -d1, d2);
  };
  // Near the edge G ~ exp(-a^2) s^2 / 2: the smaller of that guess and the blend above.
  const double s_edge = std::exp(0.5 * (kLn2 + target + pm.a * pm.a));
  const double lo = 0x1p-28, hi = pm.a + 30;
  return pm.a - halley_root(in_s, std::clamp(std::min(s_edge, pm.a - guess), lo, hi), lo, hi);
}

// Views below the horizon (a = -b < 0): solve in s = a - x on [2^-30, 30] / (1 + b): the distribution is
// s exp(-(b + s)^2), about 1 / b wide as b grows, and x = a - s would lose s entirely for large b.
double slope_below_horizon(const SlopeMarginal& pm, double u) {
  const bool lower = u <= 0.5;
  const double target = pm.ln_total() + (lower ? std::log(u) : std::log1p(-u));
  const double b = -pm.a, lo = 0x1p-30 / (1 + b), hi = 30 / (1 + b);
  // The tail P(S > s) = u: exp(-tau) for b = 0, exp(-tau) (1 + tau) for large b, tau = 2 b s + s^2.
  const double l = -std::log(u), tau = l + (b / (1 + b)) * std::log1p(l);
  const double guess = tau / (b + std::sqrt(b * b + tau));
  auto g = [&](double s) {
    const auto [f, d1, d2] = pm.log_tail(pm.a - s, s, lower, target);
    return std::make_tuple(f, -d1, d2);
  };
  return pm.a - halley_root(g, std::clamp(guess, lo, hi), lo, hi);
}

}  // namespace

double beckmann_slope_y(double u) {
  u = std::clamp(u, kMinU, 1 - 0x1p-54);
  return u < 0.5 ? -boost::math::erfc_inv(2 * u) : boost::math::erfc_inv(2 * (1 - u));
}

std::optional<double> beckmann_visible_slope_x(double cos_t, double sin_t, double u) {
  u = std::clamp(u, kMinU, 1 - 0x1p-54);
  if (!(sin_t > 0)) {
    if (cos_t > 0) return gaussian_slope(u);
    return std::nullopt;  // straight up from below: no upper microfacet faces the view
  }
  const SlopeMarginal pm{cos_t / sin_t};
  if (!std::isfinite(pm.a)) return pm.a > 0 ? std::optional<double>(gaussian_slope(u)) : std::nullopt;
  return pm.a >= 0 ? slope_above_horizon(pm, u) : slope_below_horizon(pm, u);
}

Vec3<double> beckmann_upper_visible_normal(double ax, double ay, const Vec3<double>& v, Vec2<double> u) {
  if (!v.allFinite() || !u.allFinite()) return Vec3<double>::Zero();
  const Vec3<double> vs = normalized_or_zero(Vec3<double>(ax * v.x(), ay * v.y(), v.z()));
  if (vs.isZero()) return Vec3<double>::Zero();
  const double sin_t = sin_theta(vs);
  const std::optional<double> x = beckmann_visible_slope_x(vs.z(), sin_t, u.x());
  if (!x) return Vec3<double>::Zero();
  const double y = beckmann_slope_y(u.y());
  const double cp = cos_phi(vs), sp = sin_phi(vs);
  // Rotate the standard slopes to the view's azimuth, unstretch; the normal is (-sx, -sy, 1) normalised.
  const double sx = ax * (cp * *x - sp * y), sy = ay * (sp * *x + cp * y);
  const Vec3<double> m = normalized_or_zero(Vec3<double>(-sx, -sy, 1.0));
  return m.allFinite() ? m : Vec3<double>::Zero();
}

}  // namespace microsim::detail
