// microsim: implementations of the samplers declared in samplers.h (templates, header-only so that the
// float and double versions inline into benchmarks). Written from the papers' mathematics; the step
// comments follow the papers.
//
// Numerical care (docs/reference/stability.md, docs/reference/conventions.md): each sampler computes the quantities that
// vanish at the edges of its domain (1 - u, 1 - Vh.z, the distance to the edge of the disk or cap, the
// horizontal part of Vh + c) from factored forms that do not cancel, so that float stays close to
// double at grazing views, at alpha down to 1e-4 and for u at the ends of [0, 1). Angles 2 pi u are
// reduced exactly to a quadrant (cos_sin_2pi) so that u = 1/2 gives (cos, sin) = (-1, 0) exactly.
#pragma once

#include "microfacet/samplers.h"

#include <boost/math/tools/roots.hpp>

#include <cstdint>
#include <tuple>

namespace microsim {
namespace detail {

// Applies the shared conventions: a non-finite or zero view, or a non-finite u -> nullopt; back-side
// view -> sample for -wi and negate; u clamped to [0, 1).
template <class T, class F> SampleResult<T> with_conventions(const Vec3<T>& wi, Vec2<T> u, F&& sample_upper) {
  if (!wi.allFinite() || !u.allFinite()) return std::nullopt;
  if (!(wi.squaredNorm() > T(0))) return std::nullopt;  // not a direction
  u = Vec2<T>(clamp_unit(u.x()), clamp_unit(u.y()));
  if (wi.z() < T(0)) {
    SampleResult<T> s = sample_upper(Vec3<T>(-wi), u);
    if (s) s->direction = -s->direction;
    return s;
  }
  return sample_upper(wi, u);
}

// (cos 2 pi u, sin 2 pi u) with the argument reduced exactly: 2 pi u = (pi / 2) (q + r) with q the
// integer nearest to 4u and |r| <= 1/2 (4u and 4u - q are exact in floating point). Exact at multiples
// of a quarter turn, where cos/sin of a rounded 2 pi u would leave an error of about ulp(2 pi).
template <class T> Vec2<T> cos_sin_2pi(T u) {
  const T t = T(4) * u;
  const T q = std::round(t);
  const T a = (t - q) * (kPi<T> / T(2));
  const T c = std::cos(a), s = std::sin(a);
  switch (static_cast<long long>(q) & 3) {
    case 0: return {c, s};
    case 1: return {-s, c};
    case 2: return {-c, -s};
    default: return {s, -c};
  }
}

// The view in the hemisphere configuration: Vh = normalize(ax wi.x, ay wi.y, wi.z) (Heitz 2018 sec. 3).
template <class T> Vec3<T> to_hemisphere_config(const GGX<T>& ggx, const Vec3<T>& wi) {
  return normalized_or_zero(Vec3<T>(ggx.alpha_x() * wi.x(), ggx.alpha_y() * wi.y(), wi.z()));
}

// 1 - Vh.z for a unit Vh with Vh.z >= 0, as (Vh.x^2 + Vh.y^2) / (1 + Vh.z): keeps its relative precision
// near the pole, where 1 - Vh.z would cancel (alpha -> 0 or wi -> z).
template <class T> T one_minus_z(const Vec3<T>& vh) { return (sqr(vh.x()) + sqr(vh.y())) / (T(1) + vh.z()); }

// Hemisphere-configuration normal Nh back to the ellipsoid: m = normalize(ax Nh.x, ay Nh.y, Nh.z), and
// the pdf of m given the pdf of Nh. The Jacobian of the direction map w -> normalize(A w) is
// det(A) / |A w|^3, so p(m) = p(Nh) |A Nh|^3 / (ax ay) (Heitz 2018 sec. 2, written for the pdf).
// Normals on the horizon (Nh.z <= 0) get pdf 0, the value of D and D_v there (GGX::D is zero on the
// closed lower hemisphere); nullopt when the stretched normal vanishes (Nh = -z, only reachable from a
// wrong sampler such as the negative control).
template <class T> SampleResult<T> from_hemisphere_config(const GGX<T>& ggx, const Vec3<T>& nh, T pdf_nh) {
  // Nh.z can be a rounding error below 0: clamp so that the normal stays on the upper side.
  const Vec3<T> stretched(ggx.alpha_x() * nh.x(), ggx.alpha_y() * nh.y(), std::max(nh.z(), T(0)));
  const T len = stretched.norm();
  if (!(len > T(0))) return std::nullopt;
  const T pdf = stretched.z() > T(0) ? pdf_nh * len * len * len / (ggx.alpha_x() * ggx.alpha_y()) : T(0);
  return DirectionSample<T>{stretched / len, pdf};
}

// Pdf of a visible normal Nh in the hemisphere configuration seen from Vh, given <Vh, Nh>: the projected
// area <Vh, Nh>+ over the projected area of the half sphere, pi (1 + Vh.z) / 2 (Heitz 2018 eq. 2 for
// alpha = 1, with the truncated-sphere footprint).
template <class T> T hemisphere_visible_pdf(const Vec3<T>& vh, T vh_dot_nh) {
  return T(2) * std::max(vh_dot_nh, T(0)) / (kPi<T> * (T(1) + vh.z()));
}

// g(d) = d - sin(d) cos(d) = (2d - sin 2d) / 2: increasing, g'(d) = 2 sin^2(d). For small d the
// difference cancels (g ~ 2 d^3 / 3), so there it is summed as the series of (x - sin x) / 2, x = 2d.
// s, c = sin(d), cos(d), which the callers have at hand.
template <class T> T d_minus_sin_cos(T d, T s, T c) {
  if (d < T(0.5)) {
    const T x = T(2) * d, x2 = x * x;
    T term = x * x2 / T(6), sum = term;
    for (int j = 4; j < 40; j += 2) {  // terms (-1)^k x^(2k+1) / (2k+1)!, converge fast for x < 1
      term *= -x2 / T(j * (j + 1));
      sum += term;
      if (std::abs(term) <= std::numeric_limits<T>::epsilon() * sum) break;
    }
    return sum / T(2);
  }
  return d - s * c;
}

// Halley's method (cubic convergence) for an increasing g on [lo, hi] from `guess`: Boost.Math's
// halley_iterate, which keeps the iterate bracketed. g returns (g - target, g', g''). A Halley step leaves
// an error of the order of the cube of the one before, so once a step is below 2^(1 - 2 digits / 5) of the
// iterate the error left is below 2^(3 - 6 digits / 5), under an ulp: the iteration stops there (Boost's
// rule tests the last step). Measured (tests/test_root_solvers.cpp): within 2 ulps over the whole range.
template <class T, class G> T halley_root(G&& g, T guess, T lo, T hi) {
  std::uintmax_t iterations = 40;
  return boost::math::tools::halley_iterate(g, guess, lo, hi, std::numeric_limits<T>::digits * 2 / 5, iterations);
}

// Solves d - sin(d) cos(d) = q for d in [0, pi/4] (q in [0, pi/4 - 1/2]; larger q give pi/4). Start:
// inverting g = (2/3) d^3 (1 - d^2/5 + ...) gives d ~ d0 (1 + d0^2 / 15) with d0 = (3q/2)^(1/3), within
// 0.5% on the whole range.
template <class T> T solve_d_minus_sin_cos(T q) {
  if (!(q > T(0))) return T(0);
  const T hi = kPi<T> / T(4);
  if (!(q < hi - T(0.5))) return hi;
  const T d0 = std::cbrt(T(1.5) * q);
  auto g = [q](T d) {
    const T s = std::sin(d), c = std::cos(d);
    return std::make_tuple(d_minus_sin_cos(d, s, c) - q, T(2) * s * s, T(4) * s * c);
  };
  return halley_root(g, std::min(d0 * (T(1) + d0 * d0 / T(15)), hi), T(0), hi);
}

// Solves b + sin(b) cos(b) = c for b in [0, pi/4] (c in [0, pi/4 + 1/2]; larger c give pi/4); the left side
// has derivative 2 cos^2(b) >= 1 there. Start: with x = 2b, 2c = x + sin x, whose series inversion
// x ~ c + c^3 / 12 is within 7% on the range.
template <class T> T solve_b_plus_sin_cos(T c) {
  if (!(c > T(0))) return T(0);
  const T hi = kPi<T> / T(4);
  if (!(c < hi + T(0.5))) return hi;
  auto g = [c](T b) {
    const T s = std::sin(b), co = std::cos(b);
    return std::make_tuple(b + s * co - c, T(2) * co * co, T(-4) * s * co);
  };
  return halley_root(g, std::min(T(0.5) * (c + c * c * c / T(12)), hi), T(0), hi);
}

// (cos b, sin b) for the b in [-pi/2, pi/2] with b + sin(b) cos(b) = pi (u - 1/2): the inverse CDF of a
// density proportional to cos^2(b), i.e. of (1 + y^2)^-2 for y = tan(b) (Heitz & d'Eon 2014 appendix).
// Near u = 1/2 solved for b; near the ends for d = pi/2 - |b| from d - sin d cos d = pi min(u, 1 - u),
// so that cos b = sin d keeps its relative precision (cos b -> 0 as u -> 0 or 1; the u -> b map is
// flat there, b ~ pi/2 - (3 pi min(u, 1 - u) / 2)^(1/3)). Both unknowns stay in [0, pi/4].
template <class T> Vec2<T> cos_sin_of_cos2_inverse_cdf(T u) {
  const T c = kPi<T> * std::abs(u - T(0.5));  // |b| + sin|b| cos|b|
  const T sign = u < T(0.5) ? T(-1) : T(1);
  if (c <= kPi<T> / T(4) + T(0.5)) {  // |b| <= pi/4
    const T b = solve_b_plus_sin_cos(c);
    return {std::cos(b), sign * std::sin(b)};
  }
  const T d = solve_d_minus_sin_cos(kPi<T> * std::min(u, T(1) - u));
  return {std::sin(d), sign * std::cos(d)};
}

// Vh + c, where c is uniform on the spherical cap z >= -b of the unit sphere (Dupuy & Benyoub 2023
// sec. 3 with b = Vh.z; Eto & Tokuyoshi 2023 eq. 5 with b = k Vh.z): z = (1 - u.y)(1 + b) - b, azimuth
// psi = 2 pi u.x measured from the view azimuth (the cap is symmetric about z, so this is the same
// distribution). Vh + c is the (unnormalised) visible normal; it vanishes at c = -Vh, on the rim of
// the cap when b = Vh.z. Every part is computed with an absolute error of a few ulps of |Vh + c|:
//   vertical part   Vh.z + z = (Vh.z - b) + (1 - u.y)(1 + b)              (two non-negative terms);
//   across the view azimuth: s_c sin psi, with s_c = sin(theta_c) = sqrt(u.y (1 + b)((1 - b) + (1 - u.y)(1 + b)));
//   along the view azimuth:  s_v + s_c cos psi, with s_v = |Vh.xy|. When cos psi < 0 this cancels near
//   c = -Vh; there it is (s_v - s_c) + 2 s_c cos^2(psi / 2), where |s_v - s_c| <= |Vh + c| (triangle
//   inequality on the horizontal parts), so s_v - s_c needs only its own relative precision: it is
//   (z - Vh.z)(z + Vh.z) / (s_v + s_c) with z - Vh.z = (1 - u.y)(1 + b) - (b + Vh.z), except where that
//   difference cancels (z near +Vh.z) on a view closer to the pole than to the horizon, where the direct
//   s_v - s_c is accurate enough (its error eps s_v is small against |Vh + c| >= z + Vh.z ~ 2 Vh.z).
// z_minus_b = Vh.z - b and one_minus_b = 1 - b are passed in factored form by the caller.
template <class T> Vec3<T> cap_half_vector(const Vec3<T>& vh, T b, T z_minus_b, T one_minus_b, Vec2<T> u) {
  const T w = T(1) - u.y();  // exact for u.y >= 1/2, where it matters
  const T c = vh.z();
  const T sv = std::sqrt(sqr(vh.x()) + sqr(vh.y()));
  const T sc = safe_sqrt(u.y() * (T(1) + b) * (one_minus_b + w * (T(1) + b)));
  const T vertical = z_minus_b + w * (T(1) + b);  // Vh.z + z
  const Vec2<T> half = cos_sin_2pi(u.x() / T(2));  // (cos psi/2, sin psi/2)
  T along;
  if (half.x() * half.x() >= T(0.5)) {
    along = sv + sc * (sqr(half.x()) - sqr(half.y()));  // cos psi >= 0: no cancellation
  } else {
    const T z = w * (T(1) + b) - b;
    T sv_minus_sc;
    if (z > T(0) && c > sv) {
      sv_minus_sc = sv - sc;
    } else {
      const T sum = sv + sc;
      sv_minus_sc = sum > T(0) ? (w * (T(1) + b) - (b + c)) * vertical / sum : T(0);
    }
    along = sv_minus_sc + T(2) * sc * sqr(half.x());
  }
  const T across = T(2) * sc * half.x() * half.y();
  // Rotate from the view-azimuth frame to the local frame (phi_v = 0 at the pole).
  const T cv = sv > T(0) ? vh.x() / sv : T(1), sn = sv > T(0) ? vh.y() / sv : T(0);
  return {cv * along - sn * across, sn * along + cv * across, vertical};
}

}  // namespace detail

template <class T> SampleResult<T> sample_ndf(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u) {
  return detail::with_conventions<T>(wi, u, [&](const Vec3<T>&, Vec2<T> uc) -> SampleResult<T> {
    // Slope radius r = sqrt(u / (1 - u)) inverts the CDF of the alpha = 1 slope radius, 1 - 1/(1 + r^2);
    // stretched by (ax, ay) it is P22 (Walter 2007 eq. 35-36). m ~ (-sx, -sy, 1) is rescaled by
    // sqrt(1 - u) so that u -> 1 gives a horizontal normal rather than inf / inf.
    const Vec2<T> cs = detail::cos_sin_2pi(uc.y());
    const T su = std::sqrt(uc.x()), cu = std::sqrt(T(1) - uc.x());
    const Vec3<T> n(ggx.alpha_x() * su * cs.x(), ggx.alpha_y() * su * cs.y(), cu);
    const T len = n.norm();
    // D(m) m.z = P22(slope) / m.z^3, with P22 = (1 - u)^2 / (pi ax ay) and m.z = sqrt(1 - u) / |n|.
    const T pdf = cu * len * len * len / (kPi<T> * ggx.alpha_x() * ggx.alpha_y());
    return DirectionSample<T>{n / len, pdf};
  });
}

template <class T> SampleResult<T> sample_heitz2014(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u) {
  return detail::with_conventions<T>(wi, u, [&](const Vec3<T>& w, Vec2<T> uc) -> SampleResult<T> {
    // 1. Stretch the view into the alpha = 1 configuration: direction (sin t, 0, cos t) in its azimuth frame.
    const Vec3<T> ws = detail::to_hemisphere_config(ggx, w);
    const T c = ws.z(), s = sin_theta(ws), one_minus_c = detail::one_minus_z(ws);
    // 2. Visible slope x (along the view azimuth) of the alpha = 1 configuration. Its marginal density
    //    is proportional to (cos t - x sin t)+ / (1 + x^2)^(3/2) (Heitz & d'Eon 2014, appendix); the CDF
    //    F(x) = U is sin(g) = v with g = atan(x) + t, v = U (1 + cos t) - cos t. We keep x = N / Dn with
    //    N = sin(g - t), Dn = cos(g - t) >= 0 (x = -inf is Dn = 0, a horizontal normal), and
    //    cos g = sqrt((1 - v)(1 + v)) with 1 - v = (1 - U)(1 + c), 1 + v = (1 - c) + U (1 + c).
    const T ux = uc.x();
    const T v = ux * (T(1) + c) - c;
    const T cos_g = safe_sqrt((T(1) - ux) * (T(1) + c) * (one_minus_c + ux * (T(1) + c)));
    const T N = v * c - cos_g * s;
    T Dn;
    if (v >= T(0)) {
      Dn = cos_g * c + v * s;  // two non-negative terms
    } else {
      // cos g c + v s cancels as U -> 0: use (c^2 - v^2) / (c cos g - v s), with c + v = U (1 + c).
      const T den = c * cos_g - v * s;
      Dn = den > T(0) ? (c - v) * (ux * (T(1) + c)) / den : T(0);
    }
    // 3. Visible slope y given x: density proportional to (1 + x^2 + y^2)^-2, i.e. y = sqrt(1 + x^2) tan b
    //    with b + sin b cos b = pi (U - 1/2) (see detail::cos_sin_of_cos2_inverse_cdf).
    const Vec2<T> cs_b = detail::cos_sin_of_cos2_inverse_cdf(uc.y());
    const T cos_b = cs_b.x(), sin_b = cs_b.y();
    // Homogeneous slopes: (x, y) = (N cos b, sin b) / (Dn cos b), using N^2 + Dn^2 = 1.
    const T p1 = N * cos_b, p2 = sin_b, q = Dn * cos_b;
    // 4. Rotate by the view azimuth and 5. unstretch; 6. the normal is (-sx, -sy, 1) ~ (-P_x, -P_y, Q).
    const T cp = cos_phi(ws), sp = sin_phi(ws);
    const Vec3<T> h(-ggx.alpha_x() * (cp * p1 - sp * p2), -ggx.alpha_y() * (sp * p1 + cp * p2), q);
    const T len = h.norm();
    if (!(len > T(0))) return std::nullopt;
    // Pdf of the standard visible slopes: 2 (cos t - x sin t)+ / ((1 + cos t) pi (1 + x^2 + y^2)^2), with
    // cos t - x sin t = cos g / Dn and 1 + x^2 + y^2 = 1 / Q^2; per unit stretched slope area divide by
    // ax ay; per solid angle multiply by (1 + sx^2 + sy^2)^(3/2) = (len / Q)^3. Altogether
    // 2 cos g cos b len^3 / ((1 + c) pi ax ay), which never divides by a vanishing quantity.
    // A normal exactly on the horizon (Q == 0, u at a closed end) gets pdf 0, the value of D_v there.
    const T pdf = q > T(0) ? T(2) * cos_g * cos_b * len * len * len /
                                 ((T(1) + c) * kPi<T> * ggx.alpha_x() * ggx.alpha_y())
                           : T(0);
    return DirectionSample<T>{h / len, pdf};
  });
}

template <class T> SampleResult<T> sample_heitz2018(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u) {
  return detail::with_conventions<T>(wi, u, [&](const Vec3<T>& w, Vec2<T> uc) -> SampleResult<T> {
    // Section 3: the view in the hemisphere configuration.
    const Vec3<T> vh = detail::to_hemisphere_config(ggx, w);
    // Section 4.1: orthonormal basis (T1, T2, Vh); T1 is horizontal, and (1, 0, 0) at the pole.
    const T lensq = sqr(vh.x()) + sqr(vh.y());
    const T sv = std::sqrt(lensq);  // = T2.z
    const Vec3<T> t1 = lensq > T(0) ? Vec3<T>(Vec3<T>(-vh.y(), vh.x(), T(0)) / sv) : Vec3<T>(1, 0, 0);
    const Vec3<T> t2 = vh.cross(t1);
    // Section 4.2: uniform point on the unit disk (polar map), then the half disk behind the view
    // shrinks by s = (1 + Vh.z) / 2: p2 = (1 - s) sqrt(1 - p1^2) + s r sin(phi).
    const T ux = uc.x(), r = std::sqrt(ux);
    const Vec2<T> cs = detail::cos_sin_2pi(uc.y());
    const T p1 = r * cs.x(), rs = r * cs.y();
    const T one_minus_r2 = T(1) - ux;
    const T a = std::sqrt(one_minus_r2 + ux * sqr(cs.y()));  // sqrt(1 - p1^2), without cancellation
    const T s = T(0.5) * (T(1) + vh.z());
    const T one_minus_s = T(0.5) * detail::one_minus_z(vh);
    // a -+ r sin(phi), one of which cancels near the rim: (a - rs)(a + rs) = 1 - r^2.
    const T a_minus_rs = rs > T(0) ? one_minus_r2 / (a + rs) : a - rs;
    const T a_plus_rs = rs < T(0) ? one_minus_r2 / (a - rs) : a + rs;
    // p2 = a - s (a - rs), written as s (a + rs) - Vh.z a (the two are equal since 2s - 1 = Vh.z): at grazing
    // views (Vh.z -> 0) this form loses nothing, where a - s (a - rs) leaves an error of eps a in a p2 that
    // then sets Nh.z ~ p2 alone.
    const T p2 = s * a_plus_rs - vh.z() * a;
    // Section 4.3: reproject onto the hemisphere. The height above the disk is <Vh, Nh> =
    // sqrt(1 - p1^2 - p2^2) = sqrt((a - p2)(a + p2)), with a - p2 = s (a - rs) and
    // a + p2 = 2 (1 - s) a + s (a + rs): both sums of non-negative terms.
    const T height = std::sqrt(s * a_minus_rs * (T(2) * one_minus_s * a + s * a_plus_rs));
    Vec3<T> nh = p1 * t1 + p2 * t2 + height * vh;
    // Nh.z = p2 sv + height Vh.z cancels when p2 < 0 (normals near the horizon); there use
    // (height^2 Vh.z^2 - p2^2 sv^2) / (height Vh.z - p2 sv) = (a Vh.z - p2) s (a + rs) / (height Vh.z - p2 sv).
    if (p2 < T(0) && sv > T(0)) nh.z() = (a * vh.z() - p2) * s * a_plus_rs / (height * vh.z() - p2 * sv);
    // Section 3: back to the ellipsoid configuration.
    return detail::from_hemisphere_config(ggx, nh, detail::hemisphere_visible_pdf(vh, height));
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
    // Guard (not in the listing): the listing's Nh can be zero or point straight down, where the
    // transform back to the ellipsoid would divide 0 by 0. The control must be wrong, not NaN.
    if (nh.isZero()) return std::nullopt;
    return detail::from_hemisphere_config(ggx, nh, detail::hemisphere_visible_pdf(vh, vh.dot(nh)));
  });
}

template <class T> SampleResult<T> sample_dupuy2023(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u) {
  return detail::with_conventions<T>(wi, u, [&](const Vec3<T>& w, Vec2<T> uc) -> SampleResult<T> {
    const Vec3<T> vh = detail::to_hemisphere_config(ggx, w);
    // Sec. 3: the visible normal is the half vector of Vh and a direction c uniform on the spherical cap
    // z >= -Vh.z; Vh + c computed without cancellation (detail::cap_half_vector with b = Vh.z).
    const Vec3<T> h = detail::cap_half_vector(vh, vh.z(), T(0), detail::one_minus_z(vh), uc);
    const T len = h.norm();
    if (!(len > T(0))) return std::nullopt;  // c == -Vh: a set of measure zero
    // <Vh, Nh> = <Vh, Vh + c> / |Vh + c| = (1 + <Vh, c>) / |h| = |h| / 2 for unit Vh and c.
    return detail::from_hemisphere_config(ggx, Vec3<T>(h / len), detail::hemisphere_visible_pdf(vh, len / T(2)));
  });
}

namespace detail {
// k of Eto & Tokuyoshi 2023 eq. 4 and 1 - k = a^2 (wi.z^2 + s^2) / (s^2 + a^2 wi.z^2), the latter without
// the cancellation of 1 - k at small alpha (a = min(ax, ay) saturated to [0, 1], s = 1 + |wi.xy|).
template <class T> Vec2<T> bounded2023_k_and_complement(const GGX<T>& ggx, const Vec3<T>& wi) {
  const T a = std::min(std::min(ggx.alpha_x(), ggx.alpha_y()), T(1));
  const T s = T(1) + std::sqrt(sqr(wi.x()) + sqr(wi.y()));
  const T a2 = a * a, s2 = s * s, z2 = sqr(wi.z());
  const T den = s2 + a2 * z2;
  return {(T(1) - a2) * s2 / den, a2 * (z2 + s2) / den};
}
}  // namespace detail

template <class T> T bounded2023_k(const GGX<T>& ggx, const Vec3<T>& wi) {
  return detail::bounded2023_k_and_complement(ggx, wi).x();
}

template <class T> SampleResult<T> sample_bounded2023(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u) {
  return detail::with_conventions<T>(wi, u, [&](const Vec3<T>& w, Vec2<T> uc) -> SampleResult<T> {
    const Vec3<T> vh = detail::to_hemisphere_config(ggx, w);
    // The cap's lower bound: -k Vh.z instead of -Vh.z (eq. 4-5); b = k Vh.z, Vh.z - b = (1 - k) Vh.z,
    // 1 - b = (1 - k) + k (1 - Vh.z).
    const Vec2<T> k = detail::bounded2023_k_and_complement(ggx, w);
    const T b = k.x() * vh.z();
    const Vec3<T> mh = detail::cap_half_vector(vh, b, k.y() * vh.z(), k.y() + k.x() * detail::one_minus_z(vh), uc);
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
  const Vec3<T> h = wi + wo;
  const T h_len = h.norm();
  if (!(h_len > T(0)) || !std::isfinite(h_len)) return T(0);
  Vec3<T> m = h / h_len;
  if (m.z() < T(0)) m = -m;
  if (!(wi.dot(m) > T(0))) return T(0);
  // Membership of the cap: the cap direction of m is the reflection of Vh about Nh. The sampler's own
  // samples on the rim (u.y -> 1) land within rounding of the boundary, and m recovered from wi + wo
  // carries a relative error of about eps / |wi + wo| (wi + wo cancels as wo -> -wi). A slack of
  // 8 eps / min(|wi + wo|, 1) keeps them inside; it moves the boundary by a set of probability O(slack).
  const Vec3<T> vh = detail::to_hemisphere_config(ggx, wi);
  const Vec3<T> nh = normalized_or_zero(Vec3<T>(m.x() / ggx.alpha_x(), m.y() / ggx.alpha_y(), m.z()));
  const Vec3<T> c = reflect(vh, nh);
  const T k = bounded2023_k(ggx, wi);
  const T slack = T(8) * std::numeric_limits<T>::epsilon() / std::min(h_len, T(1));
  if (c.z() < -k * vh.z() - slack) return T(0);
  return ggx.D(m) / (T(2) * (k * wi.z() + ggx.stretched_length(wi)));
}

}  // namespace microsim
