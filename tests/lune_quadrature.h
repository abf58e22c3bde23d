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

#include "core/math.h"

#include <boost/math/quadrature/gauss_kronrod.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

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

// Adaptive Gauss-Kronrod (31 points) with an ABSOLUTE error target: bisect until the Gauss-Kronrod
// error estimate of each piece is below its share of abs_tol. Boost's integrate() only knows relative
// tolerances, which never terminate early on pieces whose value is ~0 (rounding noise stays relatively
// large); the albedo integrals here are O(1), so an absolute target is the meaningful one.
template <class F> double gk_absolute(F f, double a, double b, double abs_tol, unsigned depth) {
  using boost::math::quadrature::gauss_kronrod;
  double err = 0, l1 = 0;
  const double value = gauss_kronrod<double, 31>::integrate(f, a, b, 0, 0.0, &err, &l1);
  err *= (b - a) / 2;  // Boost 1.74 reports this error for the rule on [-1, 1], unscaled (its L1 is scaled)
  // abs_tol halves with every bisection; a piece is also done when its error is below 1e-12 of its own
  // L1 norm (as in Boost's rule), which stops the bisection on peaks and on rounding noise.
  if (err <= std::max(abs_tol, 1e-12 * l1) || depth == 0) return value;
  const double mid = (a + b) / 2;
  return gk_absolute(f, a, mid, abs_tol / 2, depth - 1) + gk_absolute(f, mid, b, abs_tol / 2, depth - 1);
}

// Integral of f over a piece [a, b] whose ends may be kinks (|x - a|) or square-root points (the
// Fresnel factor at the critical angle behaves as sqrt(x - a)): substitute x = a + (b - a) S(t) with
// the smoothstep S(t) = 3t^2 - 2t^3 (S' = 6t(1 - t) vanishes at both ends), which makes both kinds of
// end point smooth in t, so Gauss-Kronrod converges fast instead of bisecting towards the ends.
template <class F> double integrate_piece(F f, double a, double b, double abs_tol, unsigned depth) {
  const double w = b - a;
  return gk_absolute([&](double t) { return f(a + w * t * t * (3 - 2 * t)) * w * 6 * t * (1 - t); }, 0.0, 1.0,
                     abs_tol, depth);
}

// Sign changes of split(x) on [a, b]: scanned in `scan` equal steps, each refined by bisection to
// machine precision. (Two changes closer than a step are missed; the callers' splits are smooth.)
template <class S> std::vector<double> sign_changes(S split, double a, double b, int scan = 64) {
  std::vector<double> roots;
  double x0 = a, s0 = split(a);
  for (int k = 1; k <= scan; ++k) {
    const double x1 = a + (b - a) * k / scan, s1 = split(x1);
    if ((s0 < 0 && s1 > 0) || (s0 > 0 && s1 < 0)) {
      double l = x0, r = x1;
      for (int it = 0; it < 200 && r - l > 4 * std::numeric_limits<double>::epsilon() * std::abs(r); ++it) {
        const double mid = (l + r) / 2, sm = split(mid);
        if ((sm < 0) == (s0 < 0) && sm != 0) l = mid; else r = mid;
      }
      roots.push_back((l + r) / 2);
    }
    if (s1 != 0) {
      x0 = x1;
      s0 = s1;
    }
  }
  return roots;
}

// Adaptive Gauss-Kronrod (31 points, absolute tolerance tol) of f over [a, b], split at every sign
// change of `split`. Gauss
// rules converge spectrally only on smooth integrands: a kink or jump of f must sit on a piece
// boundary, which the caller arranges by passing a function that changes sign exactly there.
template <class F, class S>
double integrate_split(F f, S split, double a, double b, double tol, unsigned depth, int scan = 64) {
  using boost::math::quadrature::gauss_kronrod;
  double total = 0, lo = a;
  for (double root : sign_changes(split, a, b, scan)) {
    total += integrate_piece(f, lo, root, tol, depth);
    lo = root;
  }
  return total + integrate_piece(f, lo, b, tol, depth);
}

// Nested integration over the lune of f(w) dw where f has kinks inside the lune along curves whose
// crossings with each beta line the caller computes: roots(psi) returns the beta values in (0, pi) at
// which f is not smooth on the line of that psi (in the direct lune parameterisation these are often
// closed-form; see test_bsdf.cpp). The inner (beta) integrations are split there (adaptive
// Gauss-Kronrod, absolute tolerance `tol`). The inner integral as a function of psi is then smooth
// except where a kink curve is tangent to a beta line, i.e. where the number of roots changes: there it
// has an algebraic endpoint singularity. The outer integration is split at those psi (found by
// bisection on the root count) and each piece integrated by integrate_piece (absolute tolerance
// outer_tol), whose smoothstep substitution flattens such end points.
template <class F, class R>
double integrate_lune_kinked(const Lune& l, F f, R roots, double tol = 1e-12, unsigned depth = 12,
                             double outer_tol = 1e-11) {
  using boost::math::quadrature::gauss_kronrod;
  if (!(l.psi_hi > l.psi_lo)) return 0.0;
  const auto inner = [&](double psi) {
    std::vector<double> r = roots(psi);
    std::sort(r.begin(), r.end());
    const auto g = [&](double beta) { return f(l.direction(beta, psi)) * std::sin(beta); };
    double total = 0, lo = 0;
    for (double x : r) {
      if (!(x > lo && x < kPi<double>)) continue;
      total += integrate_piece(g, lo, x, tol, depth);
      lo = x;
    }
    return total + integrate_piece(g, lo, kPi<double>, tol, depth);
  };
  const auto count = [&](double psi) { return roots(psi).size(); };
  std::vector<double> breaks = {l.psi_lo};
  constexpr int kScan = 256;
  double p0 = l.psi_lo;
  std::size_t c0 = count(p0);
  for (int k = 1; k <= kScan; ++k) {
    const double p1 = l.psi_lo + (l.psi_hi - l.psi_lo) * k / kScan;
    const std::size_t c1 = count(p1);
    if (c1 != c0) {
      double a = p0, b = p1;
      for (int it = 0; it < 200 && b - a > 4 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(b));
           ++it) {
        const double mid = (a + b) / 2;
        if (count(mid) == c0) a = mid; else b = mid;
      }
      breaks.push_back((a + b) / 2);
    }
    p0 = p1;
    c0 = c1;
  }
  breaks.push_back(l.psi_hi);
  double total = 0;
  for (std::size_t k = 0; k + 1 < breaks.size(); ++k) {
    if (breaks[k + 1] > breaks[k]) total += integrate_piece(inner, breaks[k], breaks[k + 1], outer_tol, 20);
  }
  return total;
}

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
