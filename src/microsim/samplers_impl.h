// microsim: implementations of the samplers declared in samplers.h (templates, header-only so that the
// float and double versions inline into benchmarks). Written from the papers' mathematics; the step
// comments follow the papers.
#pragma once

#include "microsim/samplers.h"

namespace microsim {
namespace detail {

// Applies the shared conventions: non-finite view -> nullopt; back-side view -> sample for -wi and
// negate; u clamped to [0, 1).
template <class T, class F> SampleResult<T> with_conventions(const Vec3<T>& wi, Vec2<T> u, F&& sample_upper) {
  if (!wi.allFinite()) return std::nullopt;
  u = Vec2<T>(clamp_unit(u.x()), clamp_unit(u.y()));
  if (wi.z() < T(0)) {
    SampleResult<T> s = sample_upper(Vec3<T>(-wi), u);
    if (s) s->direction = -s->direction;
    return s;
  }
  return sample_upper(wi, u);
}

// The view in the hemisphere configuration: Vh = normalize(ax wi.x, ay wi.y, wi.z) (Heitz 2018 sec. 3).
template <class T> Vec3<T> to_hemisphere_config(const GGX<T>& ggx, const Vec3<T>& wi) {
  return normalized_or_zero(Vec3<T>(ggx.alpha_x() * wi.x(), ggx.alpha_y() * wi.y(), wi.z()));
}

// Hemisphere-configuration normal Nh back to the ellipsoid: m = normalize(ax Nh.x, ay Nh.y, Nh.z), and
// the pdf of m given the pdf of Nh. The Jacobian of the direction map w -> normalize(A w) is
// det(A) / |A w|^3, so p(m) = p(Nh) |A Nh|^3 / (ax ay) (Heitz 2018 sec. 2, written for the pdf).
template <class T> DirectionSample<T> from_hemisphere_config(const GGX<T>& ggx, const Vec3<T>& nh, T pdf_nh) {
  // Nh.z can be a rounding error below 0: clamp so that the normal stays on the upper side.
  const Vec3<T> stretched(ggx.alpha_x() * nh.x(), ggx.alpha_y() * nh.y(), std::max(nh.z(), T(0)));
  const T len = stretched.norm();
  const T pdf = pdf_nh * len * len * len / (ggx.alpha_x() * ggx.alpha_y());
  return {stretched / len, pdf};
}

// Pdf of a visible normal Nh in the hemisphere configuration seen from Vh: the projected area
// <Vh, Nh>+ over the projected area of the half sphere, pi (1 + Vh.z) / 2 (Heitz 2018 eq. 2 for
// alpha = 1, with the truncated-sphere footprint).
template <class T> T hemisphere_visible_pdf(const Vec3<T>& vh, const Vec3<T>& nh) {
  return T(2) * std::max(vh.dot(nh), T(0)) / (kPi<T> * (T(1) + vh.z()));
}

// Solves b + sin(b) cos(b) = c for b in [-pi/2, pi/2] (c in [-pi/2, pi/2]); the left side is increasing
// with derivative 2 cos^2(b). Newton's method safeguarded by bisection.
template <class T> T solve_beta_plus_sincos(T c) {
  T lo = -kPi<T> / 2, hi = kPi<T> / 2;
  T b = c / T(2);  // exact near 0, inside the bracket everywhere
  for (int i = 0; i < 64; ++i) {
    const T g = b + std::sin(b) * std::cos(b) - c;
    if (g > T(0)) hi = b; else lo = b;
    const T dg = T(2) * sqr(std::cos(b));
    T next = b - g / dg;
    if (!(next > lo && next < hi)) next = (lo + hi) / T(2);  // Newton left the bracket: bisect
    if (std::abs(next - b) <= std::numeric_limits<T>::epsilon() * T(2)) return next;
    b = next;
  }
  return b;
}

}  // namespace detail

template <class T> SampleResult<T> sample_ndf(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u) {
  return detail::with_conventions<T>(wi, u, [&](const Vec3<T>&, Vec2<T> uc) -> SampleResult<T> {
    // Slope radius r = sqrt(u / (1 - u)) inverts the CDF of the alpha = 1 slope radius, 1 - 1/(1 + r^2);
    // stretched by (ax, ay) it is P22 (Walter 2007 eq. 35-36). m ~ (-sx, -sy, 1) is rescaled by
    // sqrt(1 - u) so that u -> 1 gives a horizontal normal rather than inf / inf.
    const T phi = T(2) * kPi<T> * uc.y();
    const T su = std::sqrt(uc.x()), cu = std::sqrt(T(1) - uc.x());
    const Vec3<T> n(ggx.alpha_x() * su * std::cos(phi), ggx.alpha_y() * su * std::sin(phi), cu);
    const T len = n.norm();
    // D(m) m.z = P22(slope) / m.z^3, with P22 = (1 - u)^2 / (pi ax ay) and m.z = sqrt(1 - u) / |n|.
    const T pdf = cu * len * len * len / (kPi<T> * ggx.alpha_x() * ggx.alpha_y());
    return DirectionSample<T>{n / len, pdf};
  });
}

template <class T> SampleResult<T> sample_heitz2014(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u) {
  return detail::with_conventions<T>(wi, u, [&](const Vec3<T>& w, Vec2<T> uc) -> SampleResult<T> {
    // 1. Stretch the view into the alpha = 1 configuration.
    const Vec3<T> ws = detail::to_hemisphere_config(ggx, w);
    const T cos_t = ws.z(), sin_t = sin_theta(ws);
    // 2. Visible slope x (along the view azimuth) of the alpha = 1 configuration. Its marginal density
    //    is proportional to (cos - x sin)+ / (1 + x^2)^(3/2) (Heitz & d'Eon 2014, appendix), whose CDF
    //    F(x) = U becomes sin(atan(x) + theta) = U (1 + cos) - cos: x = tan(asin(.) - theta).
    //    Exact at every theta, including theta = 90 deg.
    const T theta = std::atan2(sin_t, cos_t);
    const T x = std::tan(safe_asin(uc.x() * (T(1) + cos_t) - cos_t) - theta);
    // 3. Visible slope y given x: density proportional to P22, i.e. y = sqrt(1 + x^2) tan(b) with
    //    b + sin(b) cos(b) = pi (U - 1/2) (the CDF of (1 + s^2)^-2).
    const T b = detail::solve_beta_plus_sincos(kPi<T> * (uc.y() - T(0.5)));
    const T y = std::sqrt(T(1) + x * x) * std::tan(b);
    // Pdf of the standard visible slopes: G1 (1 - x tan)+ P22 = 2 (cos - x sin)+ / ((1 + cos) pi (1 + x^2 + y^2)^2).
    const T pdf_std = T(2) * std::max(cos_t - x * sin_t, T(0)) / ((T(1) + cos_t) * kPi<T> * sqr(T(1) + x * x + y * y));
    // 4. Rotate by the view azimuth and 5. unstretch.
    const T cp = cos_phi(ws), sp = sin_phi(ws);
    const T sx = ggx.alpha_x() * (cp * x - sp * y);
    const T sy = ggx.alpha_y() * (sp * x + cp * y);
    // 6. Normal from slopes; per-solid-angle pdf = slope pdf / m.z^3 = slope pdf (1 + s^2)^(3/2).
    const T q = T(1) + sx * sx + sy * sy;
    const Vec3<T> m = normalized_or_zero(Vec3<T>(-sx, -sy, T(1)));
    if (m.isZero()) return std::nullopt;
    const T pdf = pdf_std / (ggx.alpha_x() * ggx.alpha_y()) * q * std::sqrt(q);
    return DirectionSample<T>{m, pdf};
  });
}

template <class T> SampleResult<T> sample_heitz2018(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u) {
  return detail::with_conventions<T>(wi, u, [&](const Vec3<T>& w, Vec2<T> uc) -> SampleResult<T> {
    // Section 3: the view in the hemisphere configuration.
    const Vec3<T> vh = detail::to_hemisphere_config(ggx, w);
    // Section 4.1: orthonormal basis (T1, T2, Vh); T1 is horizontal, and (1, 0, 0) at the pole.
    const T lensq = sqr(vh.x()) + sqr(vh.y());
    const Vec3<T> t1 = lensq > T(0) ? Vec3<T>(Vec3<T>(-vh.y(), vh.x(), T(0)) / std::sqrt(lensq)) : Vec3<T>(1, 0, 0);
    const Vec3<T> t2 = vh.cross(t1);
    // Section 4.2: uniform point on the unit disk (polar map).
    const T r = std::sqrt(uc.x()), phi = T(2) * kPi<T> * uc.y();
    const T p1 = r * std::cos(phi);
    T p2 = r * std::sin(phi);
    // Warp the disk onto the projection of the truncated hemisphere: the half disk behind the view
    // shrinks by s = (1 + Vh.z) / 2.
    const T s = T(0.5) * (T(1) + vh.z());
    p2 = (T(1) - s) * std::sqrt(std::max(T(1) - p1 * p1, T(0))) + s * p2;
    // Section 4.3: reproject onto the hemisphere.
    const Vec3<T> nh = p1 * t1 + p2 * t2 + safe_sqrt(T(1) - p1 * p1 - p2 * p2) * vh;
    // Section 3: back to the ellipsoid configuration.
    return detail::from_hemisphere_config(ggx, nh, detail::hemisphere_visible_pdf(vh, nh));
  });
}

template <class T> SampleResult<T> sample_heitz2018_talk(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u) {
  return detail::with_conventions<T>(wi, u, [&](const Vec3<T>& w, Vec2<T> uc) -> SampleResult<T> {
    const Vec3<T> vh = detail::to_hemisphere_config(ggx, w);
    const T lensq = sqr(vh.x()) + sqr(vh.y());
    // Slide: fallback T1 = (0, 0, 1) -- not orthogonal to Vh at the pole.
    const Vec3<T> t1 = lensq > T(0) ? Vec3<T>(Vec3<T>(-vh.y(), vh.x(), T(0)) / std::sqrt(lensq)) : Vec3<T>(0, 0, 1);
    const Vec3<T> t2 = vh.cross(t1);
    const T r = std::sqrt(uc.x()), phi = T(2) * kPi<T> * uc.y();
    const T p1 = r * std::sin(phi);
    T p2 = r * std::cos(phi);
    const T s = T(0.5) + (T(1) + vh.z());  // slide's typo for 0.5 * (1 + Vh.z)
    p2 = (T(1) - s) * std::sqrt(std::max(T(1) - p1 * p1, T(0))) + s * p2;
    const Vec3<T> n_hat(0, 0, 1);  // N_hat read as the surface normal instead of Vh
    const Vec3<T> nh = normalized_or_zero(Vec3<T>(p1 * t1 + p2 * t2 + safe_sqrt(T(1) - p1 * p1 - p2 * p2) * n_hat));
    if (nh.isZero()) return std::nullopt;
    return detail::from_hemisphere_config(ggx, nh, detail::hemisphere_visible_pdf(vh, nh));
  });
}

template <class T> SampleResult<T> sample_dupuy2023(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u) {
  return detail::with_conventions<T>(wi, u, [&](const Vec3<T>& w, Vec2<T> uc) -> SampleResult<T> {
    const Vec3<T> vh = detail::to_hemisphere_config(ggx, w);
    // Sec. 3: a direction c uniform on the spherical cap z >= -Vh.z (z uniform in [-Vh.z, 1]).
    const T phi = T(2) * kPi<T> * uc.x();
    const T z = (T(1) - uc.y()) * (T(1) + vh.z()) - vh.z();
    const T sin_t = safe_sqrt(T(1) - z * z);
    const Vec3<T> c(sin_t * std::cos(phi), sin_t * std::sin(phi), z);
    // The visible normal is the half vector of Vh and c.
    const Vec3<T> nh = normalized_or_zero(Vec3<T>(vh + c));
    if (nh.isZero()) return std::nullopt;  // c == -Vh: a set of measure zero
    return detail::from_hemisphere_config(ggx, nh, detail::hemisphere_visible_pdf(vh, nh));
  });
}

template <class T> T bounded2023_k(const GGX<T>& ggx, const Vec3<T>& wi) {
  // Eq. 4 with a = min(ax, ay) saturated to [0, 1] and s = 1 + |wi.xy|.
  const T a = std::min(std::min(ggx.alpha_x(), ggx.alpha_y()), T(1));
  const T s = T(1) + std::sqrt(sqr(wi.x()) + sqr(wi.y()));
  const T a2 = a * a, s2 = s * s;
  return (T(1) - a2) * s2 / (s2 + a2 * sqr(wi.z()));
}

template <class T> SampleResult<T> sample_bounded2023(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u) {
  return detail::with_conventions<T>(wi, u, [&](const Vec3<T>& w, Vec2<T> uc) -> SampleResult<T> {
    const Vec3<T> vh = detail::to_hemisphere_config(ggx, w);
    // The cap's lower bound: -k Vh.z instead of -Vh.z (eq. 4-5).
    const T b = w.z() > T(0) ? bounded2023_k(ggx, w) * vh.z() : vh.z();
    const T phi = T(2) * kPi<T> * uc.x();
    const T z = (T(1) - uc.y()) * (T(1) + b) - b;
    const T sin_t = safe_sqrt(T(1) - z * z);
    const Vec3<T> c(sin_t * std::cos(phi), sin_t * std::sin(phi), z);
    const Vec3<T> mh = vh + c;
    const Vec3<T> m = normalized_or_zero(Vec3<T>(ggx.alpha_x() * mh.x(), ggx.alpha_y() * mh.y(), mh.z()));
    if (m.isZero()) return std::nullopt;
    const Vec3<T> wo = reflect(w, m);
    // Uniform on a cap of area 2 pi (1 + b); the VNDF's cap has 2 pi (1 + Vh.z) and gives the reflection
    // pdf D / (2 (wi.z + t)) = D / (2 t (1 + Vh.z)); hence D / (2 t (1 + b)).
    const T t = ggx.stretched_length(w);
    const T pdf = ggx.D(m) / (T(2) * t * (T(1) + b));
    return DirectionSample<T>{normalized_or_zero(wo), pdf};
  });
}

template <class T> T bounded2023_reflection_pdf(const GGX<T>& ggx, const Vec3<T>& wi_in, const Vec3<T>& wo_in) {
  // Back-side convention: evaluate with both directions flipped.
  const bool flip = wi_in.z() < T(0);
  const Vec3<T> wi = flip ? Vec3<T>(-wi_in) : wi_in;
  const Vec3<T> wo = flip ? Vec3<T>(-wo_in) : wo_in;
  Vec3<T> m = normalized_or_zero(Vec3<T>(wi + wo));
  if (m.isZero()) return T(0);
  if (m.z() < T(0)) m = -m;
  if (!(wi.dot(m) > T(0))) return T(0);
  // Membership of the cap: the cap direction of m is the reflection of Vh about Nh.
  const Vec3<T> vh = detail::to_hemisphere_config(ggx, wi);
  const Vec3<T> nh = normalized_or_zero(Vec3<T>(m.x() / ggx.alpha_x(), m.y() / ggx.alpha_y(), m.z()));
  const Vec3<T> c = reflect(vh, nh);
  const T k = wi.z() > T(0) ? bounded2023_k(ggx, wi) : T(1);
  if (c.z() < -k * vh.z()) return T(0);
  return ggx.D(m) / (T(2) * (k * wi.z() + ggx.stretched_length(wi)));
}

}  // namespace microsim
