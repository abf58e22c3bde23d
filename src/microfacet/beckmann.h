// microsim: the analytic anisotropic Smith-Beckmann microfacet model, templated on float and double, with
// the same interface as GGX (ggx.h), and an exact sampler of its visible normals.
//
// References (formulas written from these):
// - Walter, Marschner, Li, Torrance 2007, "Microfacet Models for Refraction through Rough Surfaces",
//   EGSR: Beckmann D(m) (eq. 25), its exact Smith G1 with erf (eq. 27).
// - Heitz 2014, "Understanding the Masking-Shadowing Function in Microfacet-Based BRDFs", JCGT 3(2):
//   Smith Lambda as the integral of the slope marginal above the view's slope (sec. 5), the
//   anisotropic form by stretching (sec. 5.4), the projected-area identity (eq. 7), the visible normal
//   distribution (eq. 16), the height-correlated G2 (eq. 99).
// - Heitz & d'Eon 2014, "Importance Sampling Microfacet-Based BSDFs using the Distribution of Visible
//   Normals", EGSR: visible slopes of the stretched (alpha = 1) configuration, x by inverting its marginal
//   CDF and y from its conditional (sec. 4 and appendix). For Beckmann y given x is a Gaussian; the
//   marginal CDF of x has no closed-form inverse, and the published code replaces it by a fitted rational
//   approximation that misses the steepest visible normals. Here it is inverted exactly (beckmann.cpp).
//
// Conventions as in ggx.h: z-up, directions point away from the surface, alpha clamped to kMinAlpha, views
// below the horizon see the back side (functions of (w, m) with w.z < 0 are the same functions of (-w, -m)),
// degenerate inputs give 0, never NaN.
#pragma once

#include "core/math.h"
#include "microfacet/ggx.h"
#include "microfacet/samplers.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

namespace microsim {

namespace detail {
inline constexpr double kSqrtPi = 1.77245385090551602729816748334;

// c(z) = 1 / (sqrt(pi) e^(z^2) erfc(z)) - z for z >= 3, by Laplace's continued fraction
// sqrt(pi) e^(z^2) erfc(z) = 1 / (z + (1/2) / (z + (2/2) / (z + (3/2) / (z + ...)))) (e.g. Abramowitz &
// Stegun 7.1.14), evaluated backwards from a depth that converges to double precision at z = 3 (measured).
// It gives the tails of erf without cancellation: erfc(z) = e^(-z^2) / (sqrt(pi) (z + c(z))).
template <class T> T erfc_fraction_tail(T z) {
  const int depth = std::min(48, 8 + int(T(320) / (z * z)));
  T t = 0;
  for (int k = depth; k >= 1; --k) t = (T(0.5) * T(k)) / (z + t);
  return t;
}
}  // namespace detail

template <class T> class Beckmann {
public:
  Beckmann(T alpha_x, T alpha_y) : ax_(std::max(alpha_x, T(kMinAlpha))), ay_(std::max(alpha_y, T(kMinAlpha))) {}
  explicit Beckmann(T alpha) : Beckmann(alpha, alpha) {}

  T alpha_x() const { return ax_; }
  T alpha_y() const { return ay_; }

  // Density of slopes (sx, sy) = (-mx/mz, -my/mz) per unit slope area: a Gaussian of variance alpha^2 / 2
  // per axis, P22 = exp(-sx^2/ax^2 - sy^2/ay^2) / (pi ax ay) (Heitz 2014 sec. 5, stretched).
  T slope_pdf(T sx, T sy) const {
    const T q = sqr(sx / ax_) + sqr(sy / ay_);
    if (std::isnan(q)) return T(0);
    return std::exp(-q) / (kPi<T> * ax_ * ay_);
  }

  // Beckmann D(m) = P22(slope) / mz^4 per unit solid angle (Walter 2007 eq. 25, anisotropic). m need not be
  // normalised. 0 where exp underflows (the factor 1/mz^4 cannot rescue it: D < 1e-300 there).
  T D(const Vec3<T>& m) const {
    if (!(m.z() > T(0)) || !m.allFinite()) return T(0);
    const T q = (sqr(m.x() / ax_) + sqr(m.y() / ay_)) / sqr(m.z());
    const T e = std::exp(-q);
    if (!(e > T(0))) return T(0);
    const T sec2 = m.squaredNorm() / sqr(m.z());  // 1 / cos^2(theta_m)
    return e * sqr(sec2) / (kPi<T> * ax_ * ay_);
  }

  // The projected slope scale of w: sigma = |(ax wx, ay wy)|, so that a = |wz| / sigma = 1 / (alpha(phi) tan).
  T slope_scale(const Vec3<T>& w) const { return std::sqrt(sqr(ax_ * w.x()) + sqr(ay_ * w.y())); }

  // Smith Lambda (Walter 2007 eq. 27 as 1 / G1 - 1; Heitz 2014 sec. 5.3): with a = 1 / (alpha(phi) tan theta),
  //   Lambda = (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)) = (exp(-a^2) / (a sqrt(pi)) - erfc(a)) / 2.
  // For a >= 3 the two terms cancel; there erfc comes from the continued fraction, which gives
  //   Lambda = exp(-a^2) c(a) / (2 sqrt(pi) a (a + c(a))) without cancellation. +inf on the horizon.
  T Lambda(const Vec3<T>& w) const {
    if (!w.allFinite()) return T(0);
    const T sigma = slope_scale(w), z = std::abs(w.z());
    if (sigma == T(0)) return T(0);
    if (z == T(0)) return std::numeric_limits<T>::infinity();
    return masked_area(w) / z;
  }

  // |wz| Lambda(w): the area of back-facing microfacets seen from w per unit macro area (finite on the
  // horizon, where it is sigma / (2 sqrt(pi))). With sigma = |wz| / a:
  //   |wz| Lambda = (sigma exp(-a^2) / sqrt(pi) - |wz| erfc(a)) / 2.
  T masked_area(const Vec3<T>& w) const {
    if (!w.allFinite()) return T(0);
    const T sigma = slope_scale(w), z = std::abs(w.z());
    if (sigma == T(0)) return T(0);
    const T a = z / sigma;
    const T sqrt_pi = T(detail::kSqrtPi);
    if (a >= T(3)) {
      const T c = detail::erfc_fraction_tail(a);
      return sigma * std::exp(-a * a) * c / (T(2) * sqrt_pi * (a + c));
    }
    return (sigma * std::exp(-a * a) / sqrt_pi - z * std::erfc(a)) / T(2);
  }

  // Smith masking G1 = 1 / (1 + Lambda) (Walter 2007 eq. 27), written as |wz| / projected_area: 0 on the
  // horizon, 1 for views along the normal.
  T G1(const Vec3<T>& w) const {
    if (!w.allFinite()) return T(0);
    const T area = projected_area(w);
    return area > T(0) ? std::abs(w.z()) / area : T(0);
  }

  // Height-correlated masking-shadowing (Heitz 2014 eq. 99): 1 / (1 + Lambda(wi) + Lambda(wo)), evaluated
  // as G1i G1o / (G1i + G1o - G1i G1o) (finite when a Lambda is infinite).
  T G2(const Vec3<T>& wi, const Vec3<T>& wo) const {
    const T gi = G1(wi), go = G1(wo);
    const T denom = gi + go - gi * go;
    return denom > T(0) ? gi * go / denom : T(0);
  }

  T G2_separable(const Vec3<T>& wi, const Vec3<T>& wo) const { return G1(wi) * G1(wo); }

  // Projected area of the microsurface seen from w per unit macro area: integral of D(m) <w, m>+ =
  // |wz| (1 + Lambda(w)) = |wz| + masked_area(w) (Heitz 2014 eq. 7 with the Smith G1). Finite on the horizon.
  T projected_area(const Vec3<T>& w) const {
    if (!w.allFinite()) return T(0);
    return std::abs(w.z()) + masked_area(w);
  }

  // Distribution of visible normals D_v(m) = G1(w) <w, m>+ D(m) / |wz| = <w, m>+ D(m) / projected_area(w)
  // (Heitz 2014 eq. 16), finite on the horizon. Back-side views (w.z < 0) use D_v(-w, -m).
  T visible_normal_pdf(const Vec3<T>& w, const Vec3<T>& m) const {
    if (!w.allFinite() || !m.allFinite()) return T(0);
    if (w.z() < T(0)) return visible_normal_pdf(Vec3<T>(-w), Vec3<T>(-m));
    const T wm = w.dot(m);
    if (!(wm > T(0))) return T(0);
    const T area = projected_area(w);
    return area > T(0) ? D(m) * wm / area : T(0);
  }

  bool effectively_smooth() const { return std::max(ax_, ay_) < T(1e-3); }

private:
  T ax_, ay_;
};

// ---- the exact visible-normal sampler --------------------------------------------------------------------

namespace detail {
// The visible slope x along the view azimuth of the standard (alpha = 1) Beckmann configuration seen from
// the unit direction (sin t, 0, cos t), t in [0, pi] (views below the horizon see the upper microfacets
// from underneath: the Smith walk's case). Its density is proportional to (cos t - x sin t)+ exp(-x^2)
// (Heitz & d'Eon 2014 appendix for Beckmann); u in [0, 1) is inverted exactly through that CDF
// (beckmann.cpp). nullopt when nothing is visible (t = pi).
std::optional<double> beckmann_visible_slope_x(double cos_t, double sin_t, double u);
// The slope y, a Gaussian of variance 1/2 whatever x: y = erf^-1(2u - 1), tails through erfc^-1.
double beckmann_slope_y(double u);
// The upper microfacet normal (m.z >= 0) drawn from D(m) <v, m>+ for a view v on either side of the
// horizon: stretch v, draw the standard visible slopes, rotate them to v's azimuth, unstretch. Zero when
// no upper microfacet faces v (v straight down) or u is not finite.
Vec3<double> beckmann_upper_visible_normal(double ax, double ay, const Vec3<double>& v, Vec2<double> u);
}  // namespace detail

// Samples D_v(wi, m) of Beckmann (the zoo's conventions, samplers.h: back-side views sample for -wi and
// negate). The pdf returned is the analytic D_v at the sample.
template <class T> SampleResult<T> sample_beckmann_vndf(const Beckmann<T>& b, const Vec3<T>& wi, Vec2<T> u) {
  return detail::with_conventions<T>(wi, u, [&](const Vec3<T>& w, Vec2<T> uc) -> SampleResult<T> {
    const Vec3<double> m = detail::beckmann_upper_visible_normal(double(b.alpha_x()), double(b.alpha_y()),
                                                                 w.template cast<double>(), uc.template cast<double>());
    if (m.isZero()) return std::nullopt;
    const Vec3<T> mt = m.cast<T>();
    return DirectionSample<T>{mt, b.visible_normal_pdf(w, mt)};
  });
}

// A visible normal of wi by the reference VNDF sampler of either NDF (GGX: Heitz 2018; Beckmann:
// sample_beckmann_vndf), for code written once for both.
inline SampleResult<double> sample_visible_normal(const GGX<double>& ggx, const Vec3<double>& wi, Vec2<double> u) {
  return sample_heitz2018(ggx, wi, u);
}
inline SampleResult<double> sample_visible_normal(const Beckmann<double>& b, const Vec3<double>& wi, Vec2<double> u) {
  return sample_beckmann_vndf(b, wi, u);
}

}  // namespace microsim
