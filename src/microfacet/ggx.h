// microsim: the analytic anisotropic Smith-GGX microfacet model, templated on float and double.
//
// References (formulas written from these):
// - Walter, Marschner, Li, Torrance 2007, "Microfacet Models for Refraction through Rough Surfaces",
//   EGSR: GGX D(m) (eq. 33), Smith G1 (eq. 34).
// - Heitz 2014, "Understanding the Masking-Shadowing Function in Microfacet-Based BRDFs", JCGT 3(2):
//   anisotropic Lambda (eq. 86), height-correlated G2 (eq. 99), visible normal distribution (eq. 16).
// - Heitz 2018, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4): ellipsoid picture.
//
// Conventions: z-up frame, directions point away from the surface. The roughness is clamped from below
// at kMinAlpha = 1e-4 (a documented convention: below it the lobe is narrower than float resolves near
// the pole; treat such surfaces as this roughness, or as a perfect mirror in the caller). Views below the
// horizon see the microsurface from its back side: every function of (w, m) with w.z < 0 is evaluated
// as the same function of (-w, -m). Degenerate inputs return 0, never NaN.
#pragma once

#include "core/math.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace microsim {

inline constexpr double kMinAlpha = 1e-4;
// The supported roughness of every command and of the traced quadric (docs/reference/conventions.md): each axis in
// [kMinAlpha, kMaxSupportedAlpha] and max/min <= kMaxSupportedAnisotropy. The stability sweep covers
// exactly this box, and the quadric was measured exact at its corners (quadric.h).
inline constexpr double kMaxSupportedAlpha = 10;
inline constexpr double kMaxSupportedAnisotropy = 1000;

template <class T> class GGX {
public:
  GGX(T alpha_x, T alpha_y)
      : ax_(std::max(alpha_x, T(kMinAlpha))), ay_(std::max(alpha_y, T(kMinAlpha))) {}
  explicit GGX(T alpha) : GGX(alpha, alpha) {}

  T alpha_x() const { return ax_; }
  T alpha_y() const { return ay_; }

  // GGX normal distribution D(m), per unit solid angle of m and unit projected macro area
  // (Walter 2007 eq. 33, anisotropic form). Evaluated from (mx, my) rather than via
  // ((a^2 - 1) cos^2 + 1), which cancels catastrophically at small alpha. m need not be normalised.
  T D(const Vec3<T>& m) const {
    if (!(m.z() > T(0))) return T(0);
    const T len2 = m.squaredNorm();
    if (!(len2 < std::numeric_limits<T>::infinity())) return T(0);  // non-finite m: inf / inf
    const T e = sqr(m.x() / ax_) + sqr(m.y() / ay_) + sqr(m.z());  // for unit m; rescaled below
    return sqr(len2) / (kPi<T> * ax_ * ay_ * sqr(e));
  }

  // How much a renderer's D(m) computed from cos theta_m loses: the factor a unit roundoff of sin^2 theta_m
  // is amplified by, d ln D / d sin^2 = 2 / (alpha_phi^2 cos^2 + sin^2) (Walter et al. 2007 eq. 33;
  // alpha_phi the roughness along m's azimuth). pbrt-v4's Tan2Theta = (1 - cos^2) / cos^2 and Karis 2013's
  // 1 + (alpha^2 - 1) cos^2 cancel near the peak, where this is about 2 / alpha^2.
  double cancellation_of_D(const Vec3<double>& m) const {
    const double s2 = sqr(m.x()) + sqr(m.y()), c2 = sqr(m.z());
    const double ax2 = sqr(double(ax_)), ay2 = sqr(double(ay_));
    const double a2 = s2 > 0 ? s2 / (sqr(m.x()) / ax2 + sqr(m.y()) / ay2) : std::min(ax2, ay2);
    return 2 / (a2 * c2 + s2);
  }

  // Density of microfacet slopes (sx, sy) = (-mx/mz, -my/mz) per unit slope area: a bivariate Student-t
  // with nu = 2 (Heitz 2014 eq. 39 for GGX): P22 = 1 / (pi ax ay (1 + sx^2/ax^2 + sy^2/ay^2)^2).
  T slope_pdf(T sx, T sy) const {
    const T q = sqr(sx / ax_) + sqr(sy / ay_);
    if (std::isnan(q)) return T(0);  // NaN slope (infinite slopes give 0 below)
    // Squared last: (1 + q)^2 alone overflows float for slopes past ~1e19 alpha, long before the
    // density leaves float's range.
    const T r = T(1) / (std::sqrt(kPi<T> * ax_ * ay_) * (T(1) + q));
    return r * r;
  }

  // t = |(ax wx, ay wy, wz)|: the length of w in the hemisphere (stretched) configuration.
  T stretched_length(const Vec3<T>& w) const {
    return std::sqrt(sqr(ax_ * w.x()) + sqr(ay_ * w.y()) + sqr(w.z()));
  }

  // Smith Lambda (Heitz 2014 eq. 86): (-1 + sqrt(1 + a(phi)^2 tan^2 theta)) / 2, written as
  // (t - |wz|) / (2 |wz|) = (ax^2 wx^2 + ay^2 wy^2) / (2 |wz| (t + |wz|)) to avoid cancellation at
  // small alpha. +inf on the horizon.
  T Lambda(const Vec3<T>& w) const {
    if (!w.allFinite()) return T(0);  // degenerate input: 0 by convention
    const T z = std::abs(w.z());
    const T num = sqr(ax_ * w.x()) + sqr(ay_ * w.y());
    if (num == T(0)) return T(0);
    if (z == T(0)) return std::numeric_limits<T>::infinity();
    return num / (T(2) * z * (stretched_length(w) + z));
  }

  // Smith masking G1 = 1 / (1 + Lambda) = 2 |wz| / (|wz| + t): finite everywhere, 0 on the horizon.
  T G1(const Vec3<T>& w) const {
    if (!w.allFinite()) return T(0);  // degenerate input: 0 by convention (inf / inf otherwise)
    const T z = std::abs(w.z());
    const T denom = z + stretched_length(w);
    return denom > T(0) ? T(2) * z / denom : T(0);
  }

  // Height-correlated masking-shadowing (Heitz 2014 eq. 99): 1 / (1 + Lambda(wi) + Lambda(wo)),
  // evaluated as G1i G1o / (G1i + G1o - G1i G1o) which stays finite when either Lambda is infinite.
  T G2(const Vec3<T>& wi, const Vec3<T>& wo) const {
    const T gi = G1(wi), go = G1(wo);
    const T denom = gi + go - gi * go;
    return denom > T(0) ? gi * go / denom : T(0);
  }

  // Separable (uncorrelated) masking-shadowing G1(wi) G1(wo).
  T G2_separable(const Vec3<T>& wi, const Vec3<T>& wo) const { return G1(wi) * G1(wo); }

  // Projected area of the microsurface seen from w per unit macro area: integral of D(m) <w, m>+
  // = |wz| / G1(w) = (|wz| + t) / 2 (Heitz 2014 eq. 7 with the Smith G1).
  T projected_area(const Vec3<T>& w) const { return (std::abs(w.z()) + stretched_length(w)) / T(2); }

  // Distribution of visible normals D_v(m) = G1(w) <w, m>+ D(m) / wz (Heitz 2014 eq. 16), in the form
  // 2 D(m) <w, m>+ / (wz + t) that stays finite at wz = 0. Per unit solid angle of m. Back-side views
  // (w.z < 0) use D_v(-w, -m).
  T visible_normal_pdf(const Vec3<T>& w, const Vec3<T>& m) const {
    if (!w.allFinite() || !m.allFinite()) return T(0);  // degenerate input: 0 by convention
    if (w.z() < T(0)) return visible_normal_pdf(Vec3<T>(-w), Vec3<T>(-m));
    const T wm = w.dot(m);
    if (!(wm > T(0))) return T(0);
    const T denom = w.z() + stretched_length(w);
    return denom > T(0) ? T(2) * D(m) * wm / denom : T(0);
  }

  // Pdf of the reflected direction wo = reflect(wi, m) when m is drawn from D_v(wi): D_v / (4 <wi, m>)
  // (Walter 2007 eq. 14 Jacobian), which simplifies to D(m) / (2 (wi.z + t)). Zero where the half
  // vector is not visible from wi.
  T visible_reflection_pdf(const Vec3<T>& wi, const Vec3<T>& wo) const {
    const Vec3<T> h = wi + wo;
    const T len = h.norm();
    if (!(len > T(0))) return T(0);
    Vec3<T> m = h / len;
    if (m.z() < T(0)) m = -m;
    const T im = wi.dot(m);
    if (!(std::abs(im) > T(0))) return T(0);
    return visible_normal_pdf(wi, m) / (T(4) * std::abs(im));
  }

  // Whether the lobe is so narrow that callers may prefer to treat the surface as a mirror.
  bool effectively_smooth() const { return std::max(ax_, ay_) < T(1e-3); }

private:
  T ax_, ay_;
};

}  // namespace microsim
