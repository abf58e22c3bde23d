// Test-only numerical integration over pieces of the unit sphere, accurate enough to check the
// analytic identities of Smith-GGX to 1e-6 and far below (used by test_ggx.cpp and test_bsdf.cpp).
//
// The integrands of the identities have kinks where a clamped cosine <u, w>+ or the hemisphere bound
// <n, w> > 0 switches off. Both bounds are great circles through the two points +-e, e = n x u / |n x u|.
// In spherical coordinates whose pole is e, w = cos(beta) e + sin(beta) (cos(psi) a + sin(psi) b) with
// a = n and b = e x a, the set {<n, w> > 0, <u, w> > 0} (a "lune") is the rectangle beta in [0, pi],
// psi in [psi_lo, psi_hi], and dw = sin(beta) dbeta dpsi: the kinks lie on the rectangle's edges, so a
// smooth integrand stays smooth and Gauss-Kronrod quadrature converges spectrally.
//
// For GGX the integrands are additionally mapped to the hemisphere configuration of Heitz 2018 (JCGT
// 7(4), sec. 3): m = A h / |A h| with A = diag(ax, ay, 1), dw_m = ax ay / |A h|^3 dw_h (the Jacobian of
// the projective map w -> M w / |M w| is |det M| / |M w|^3). In h the GGX lobe is as wide as the whole
// hemisphere whatever alpha, and the half-spaces <v, m> > 0 become <A v, h> > 0 (A is diagonal), so the
// lune construction applies in h with u = A v.
#pragma once

#include "microsim/math.h"

#include <boost/math/quadrature/gauss_kronrod.hpp>

#include <algorithm>
#include <cmath>

namespace microsim::test {

struct Lune {
  Vec3<double> e, a, b;  // pole of the (beta, psi) coordinates and the frame of its equator
  double psi_lo = 0, psi_hi = 0;

  Vec3<double> direction(double beta, double psi) const {
    return std::cos(beta) * e + std::sin(beta) * (std::cos(psi) * a + std::sin(psi) * b);
  }
};

// {w : <n, w> > 0 and <u, w> > 0}; u == 0 means the whole hemisphere around n. n must be unit.
inline Lune make_lune(const Vec3<double>& n, const Vec3<double>& u = Vec3<double>::Zero()) {
  Lune l;
  l.a = n;
  const Vec3<double> c = n.cross(u);
  double psi_u = 0;
  if (c.norm() > 1e-300 * std::max(1.0, u.norm())) {
    l.e = c.normalized();
    l.b = l.e.cross(l.a);
    psi_u = std::atan2(u.dot(l.b), u.dot(l.a));
  } else {
    Vec3<double> b1, b2;
    orthonormal_basis(n, b1, b2);
    l.e = b1;
    l.b = l.e.cross(l.a);
    psi_u = u.dot(n) < 0 ? kPi<double> : 0.0;  // u antiparallel to n: empty lune
  }
  const double half = kPi<double> / 2;
  l.psi_lo = (u.squaredNorm() == 0) ? -half : std::max(-half, psi_u - half);
  l.psi_hi = (u.squaredNorm() == 0) ? half : std::min(half, psi_u + half);
  return l;
}

// Nested adaptive Gauss-Kronrod (31 points) over the lune of f(w) dw. `tol` is the relative tolerance
// handed to each 1-D integration.
template <class F> double integrate_lune(const Lune& l, F f, double tol = 1e-12, unsigned depth = 12) {
  using boost::math::quadrature::gauss_kronrod;
  if (!(l.psi_hi > l.psi_lo)) return 0.0;
  const auto inner = [&](double psi) {
    return gauss_kronrod<double, 31>::integrate(
        [&](double beta) { return f(l.direction(beta, psi)) * std::sin(beta); }, 0.0, kPi<double>, depth, tol);
  };
  return gauss_kronrod<double, 31>::integrate(inner, l.psi_lo, l.psi_hi, depth, tol);
}

// Nested adaptive Gauss-Kronrod over the rectangle [x0, x1] x [y0, y1] of f(x, y).
template <class F>
double integrate_2d(F f, double x0, double x1, double y0, double y1, double tol = 1e-12, unsigned depth = 15) {
  using boost::math::quadrature::gauss_kronrod;
  const auto inner = [&](double x) {
    return gauss_kronrod<double, 31>::integrate([&](double y) { return f(x, y); }, y0, y1, depth, tol);
  };
  return gauss_kronrod<double, 31>::integrate(inner, x0, x1, depth, tol);
}

// The Heitz 2018 hemisphere configuration: m(h) and dw_m / dw_h.
struct StretchMap {
  double ax, ay;
  Vec3<double> stretch(const Vec3<double>& h) const { return {ax * h.x(), ay * h.y(), h.z()}; }
  Vec3<double> normal(const Vec3<double>& h) const { return stretch(h).normalized(); }
  double jacobian(const Vec3<double>& h) const {
    const double len = stretch(h).norm();
    return ax * ay / (len * len * len);
  }
};

}  // namespace microsim::test
