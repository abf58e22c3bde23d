// microsim: small math helpers and the one z-up local frame.
//
// Conventions (used everywhere in microsim):
// - The local shading frame is z-up: the macro-surface normal is (0, 0, 1); theta is measured from +z,
//   phi from +x towards +y.
// - Directions point AWAY from the surface (the view v, the light l, a microfacet normal m).
// - The trig helpers below are defined at the poles: there sin(theta) = 0 and we take phi = 0,
//   i.e. cos_phi = 1 and sin_phi = 0. No helper returns NaN for a unit input.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace microsim {

template <class T> using Vec3 = Eigen::Matrix<T, 3, 1>;
template <class T> using Vec2 = Eigen::Matrix<T, 2, 1>;

template <class T> inline constexpr T kPi = std::numbers::pi_v<T>;
template <class T> inline constexpr T kInvPi = std::numbers::inv_pi_v<T>;

// Largest value below 1 in T: uniform variates are clamped to [0, kOneMinusEpsilon] so that a
// sampler's inverse CDF never sees u == 1 (1 - 2^-53 rounds to 1.0f in float).
template <class T> inline constexpr T kOneMinusEpsilon = T(1) - std::numeric_limits<T>::epsilon() / 2;

template <class T> constexpr T sqr(T x) { return x * x; }

// sqrt that treats small negative round-off as 0 instead of returning NaN.
template <class T> inline T safe_sqrt(T x) { return std::sqrt(std::max(x, T(0))); }

// asin/acos with the argument clamped to [-1, 1] (round-off can push |x| slightly past 1).
template <class T> inline T safe_asin(T x) { return std::asin(std::clamp(x, T(-1), T(1))); }
template <class T> inline T safe_acos(T x) { return std::acos(std::clamp(x, T(-1), T(1))); }

// Clamps a uniform variate into [0, 1): see kOneMinusEpsilon.
template <class T> inline T clamp_unit(T u) { return std::clamp(u, T(0), kOneMinusEpsilon<T>); }

// ---- trig in the z-up frame (w is a unit vector) ------------------------------------------------------
template <class T> inline T cos_theta(const Vec3<T>& w) { return w.z(); }
template <class T> inline T cos2_theta(const Vec3<T>& w) { return w.z() * w.z(); }
// sin^2 from the x, y components (not 1 - z^2) so that it keeps full precision near the pole.
template <class T> inline T sin2_theta(const Vec3<T>& w) { return w.x() * w.x() + w.y() * w.y(); }
template <class T> inline T sin_theta(const Vec3<T>& w) { return std::sqrt(sin2_theta(w)); }
// tan^2 is +inf on the horizon (z == 0) and 0 at the poles.
template <class T> inline T tan2_theta(const Vec3<T>& w) {
  const T c2 = cos2_theta(w);
  return c2 > T(0) ? sin2_theta(w) / c2 : std::numeric_limits<T>::infinity();
}
// phi of the pole is defined as 0: cos_phi = 1, sin_phi = 0.
template <class T> inline T cos_phi(const Vec3<T>& w) {
  const T s = sin_theta(w);
  return s > T(0) ? std::clamp(w.x() / s, T(-1), T(1)) : T(1);
}
template <class T> inline T sin_phi(const Vec3<T>& w) {
  const T s = sin_theta(w);
  return s > T(0) ? std::clamp(w.y() / s, T(-1), T(1)) : T(0);
}

// Unit direction from spherical angles in radians (theta from +z, phi from +x).
template <class T> inline Vec3<T> spherical_direction(T theta, T phi) {
  const T s = std::sin(theta);
  return {s * std::cos(phi), s * std::sin(phi), std::cos(theta)};
}
// Unit direction from angles in degrees; used by the command line (--theta, --phi).
template <class T> inline Vec3<T> direction_from_degrees(T theta_deg, T phi_deg) {
  constexpr T to_rad = kPi<T> / T(180);
  return spherical_direction(theta_deg * to_rad, phi_deg * to_rad);
}

// Mirror reflection of w about the unit normal n (both pointing away from the surface).
template <class T> inline Vec3<T> reflect(const Vec3<T>& w, const Vec3<T>& n) { return T(2) * w.dot(n) * n - w; }

// Refraction of w (unit, pointing away from the interface, on the side n points to) through the interface
// with unit normal n, for eta = n_transmitted / n_incident (Snell's law in vector form; e.g. Walter et al.
// 2007, eq. 40 with the sign of n chosen on w's side). The refracted direction points away on the other
// side, unit. Returns false (total internal reflection, or w not on n's side) and leaves `out` unchanged.
template <class T> inline bool refract(const Vec3<T>& w, const Vec3<T>& n, T eta, Vec3<T>& out) {
  const T cos_i = w.dot(n);
  if (!(cos_i > T(0)) || !(eta > T(0))) return false;
  const T sin2_t = (T(1) - cos_i * cos_i) / (eta * eta);
  if (sin2_t >= T(1)) return false;
  const T cos_t = std::sqrt(T(1) - sin2_t);
  out = (-w / eta + (cos_i / eta - cos_t) * n).normalized();
  return true;
}

// Normalises v; returns nullopt-like zero vector for a zero or non-finite input (callers check norm).
template <class T> inline Vec3<T> normalized_or_zero(const Vec3<T>& v) {
  const T n = v.norm();
  return (n > T(0) && std::isfinite(n)) ? Vec3<T>(v / n) : Vec3<T>::Zero();
}

// Orthonormal basis around the unit vector n (Duff et al. 2017, "Building an Orthonormal Basis,
// Revisited", JCGT 6(1)): branchless except for the sign, continuous away from n.z = -0.
template <class T> inline void orthonormal_basis(const Vec3<T>& n, Vec3<T>& b1, Vec3<T>& b2) {
  const T sign = std::copysign(T(1), n.z());
  const T a = T(-1) / (sign + n.z());
  const T b = n.x() * n.y() * a;
  b1 = {T(1) + sign * n.x() * n.x() * a, sign * b, -sign * n.x()};
  b2 = {b, sign + n.y() * n.y() * a, -n.y()};
}

}  // namespace microsim
