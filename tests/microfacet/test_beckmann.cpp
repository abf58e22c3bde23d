// Smith-Beckmann (microfacet/beckmann.h) and the visible normals of the upper microsurface seen from any
// direction (microfacet/upper_vndf.h), for the Smith random walk:
// - the identities by numerical integration: D normalised (integral of D(m) m.z = 1), D_v normalised, the
//   projected area |vz| (1 + Lambda), Lambda against its definition as an integral over slopes, the upper
//   visible area A(v) below the horizon (GGX and Beckmann);
// - the exact visible-slope inversion: the CDF of the returned slope, integrated independently, is u again
//   (to 1e-9 relative in both tails), for views from the normal to far below the horizon;
// - the samplers' histograms against the analytic pdf by chi-square at fixed seeds (family-wise level 1%,
//   Sidak over the configurations of a test), each with negative controls that must be rejected.
#include "microfacet/beckmann.h"
#include "microfacet/bsdf.h"
#include "microfacet/upper_vndf.h"

#include "core/random.h"
#include "lune_quadrature.h"
#include "stats/binning.h"
#include "stats/chi2.h"

#include <boost/math/quadrature/gauss_kronrod.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

namespace microsim {
namespace {

using test::integrate_lune;
using test::make_lune;
using test::StretchMap;

struct AlphaPair {
  double ax, ay;
};

const std::vector<AlphaPair> kAlphas = {{0.05, 0.05}, {0.3, 0.3}, {1, 1}, {2, 2}, {0.1, 0.8}, {1e-3, 0.5}};
const std::vector<double> kThetas = {0, 30, 60, 80, 89, 90};

std::string label(const AlphaPair& a, double theta = -1) {
  return "alpha=(" + std::to_string(a.ax) + "," + std::to_string(a.ay) + ") theta=" + std::to_string(theta);
}

// integral over the upper hemisphere of f(m) dm, through the stretched map (the lobe fills the hemisphere),
// restricted to <v, m> > 0 when v is given.
template <class F> double integrate_upper(const AlphaPair& a, F f, const Vec3<double>& v = Vec3<double>::Zero()) {
  const StretchMap map{a.ax, a.ay};
  const Vec3<double> u = v.isZero() ? v : Vec3<double>(map.stretch(v));
  return integrate_lune(make_lune({0, 0, 1}, u), [&](const Vec3<double>& h) {
    const Vec3<double> m = map.normal(h);
    return f(m) * map.jacobian(h);
  });
}

TEST(BeckmannIdentities, ProjectedNdfIntegratesToOne) {
  for (const AlphaPair& a : kAlphas) {
    const Beckmann<double> b(a.ax, a.ay);
    EXPECT_NEAR(integrate_upper(a, [&](const Vec3<double>& m) { return b.D(m) * m.z(); }), 1.0, 1e-7) << label(a);
  }
  // Directly in m where the lobe is wide (guards against a compensating error of the stretch map).
  const Beckmann<double> b(0.6, 0.9);
  const double direct = integrate_lune(make_lune({0, 0, 1}), [&](const Vec3<double>& m) { return b.D(m) * m.z(); });
  EXPECT_NEAR(direct, 1.0, 1e-7);
}

TEST(BeckmannIdentities, ProjectedAreaAndVisibleNormalsIntegrate) {
  for (const AlphaPair& a : kAlphas) {
    const Beckmann<double> b(a.ax, a.ay);
    for (double theta : kThetas) {
      const Vec3<double> v = direction_from_degrees(theta, 37.0);
      const double area = integrate_upper(a, [&](const Vec3<double>& m) { return b.D(m) * std::max(0.0, v.dot(m)); }, v);
      EXPECT_NEAR(area / b.projected_area(v), 1.0, 1e-7) << label(a, theta);
      if (theta < 90) {
        EXPECT_NEAR(b.projected_area(v), v.z() / b.G1(v), 1e-14 * b.projected_area(v)) << label(a, theta);
      }
      const double dv = integrate_upper(a, [&](const Vec3<double>& m) { return b.visible_normal_pdf(v, m); }, v);
      EXPECT_NEAR(dv, 1.0, 1e-7) << label(a, theta);
    }
  }
}

// Lambda(w) = (1/a) int_a^inf (q - a) exp(-q^2) / sqrt(pi) dq for a = 1 / (alpha tan theta) (Heitz 2014 sec. 5):
// the definition of Smith's Lambda for a Gaussian slope marginal, against the erf closed form and its
// continued-fraction branch (a >= 3).
TEST(BeckmannIdentities, LambdaMatchesItsSlopeIntegral) {
  using boost::math::quadrature::gauss_kronrod;
  const Beckmann<double> b(1.0);
  for (double a : {0.01, 0.3, 1.0, 2.0, 2.999, 3.0, 3.5, 5.0, 8.0, 20.0}) {
    const double tan_t = 1 / a, theta = std::atan(tan_t);
    const Vec3<double> w = spherical_direction(theta, 0.3);
    const double integral = gauss_kronrod<double, 61>::integrate(
        [&](double q) { return (q - a) * std::exp(-q * q) / std::sqrt(kPi<double>); }, a,
        std::numeric_limits<double>::infinity(), 15, 1e-14);
    EXPECT_NEAR(b.Lambda(w) / (integral / a), 1.0, 1e-11) << "a=" << a;
  }
  EXPECT_EQ(b.Lambda(Vec3<double>(0, 0, 1)), 0.0);
  EXPECT_EQ(b.Lambda(Vec3<double>(1, 0, 0)), std::numeric_limits<double>::infinity());
  EXPECT_NEAR(b.projected_area(Vec3<double>(1, 0, 0)), 1 / (2 * std::sqrt(kPi<double>)), 1e-15);
  EXPECT_EQ(b.G1(Vec3<double>(1, 0, 0)), 0.0);
}

// A(v) = integral over the upper hemisphere of <v, m>+ D(m) for views below the horizon (upper_vndf.h).
TEST(UpperVisibleNormals, AreaBelowTheHorizonIntegrates) {
  for (const AlphaPair& a : {AlphaPair{0.3, 0.3}, AlphaPair{1, 1}, AlphaPair{0.2, 0.7}}) {
    const GGX<double> g(a.ax, a.ay);
    const Beckmann<double> b(a.ax, a.ay);
    for (double theta : {91.0, 100.0, 135.0, 170.0}) {
      const Vec3<double> v = direction_from_degrees(theta, 37.0);
      const double ig = integrate_upper(a, [&](const Vec3<double>& m) { return g.D(m) * std::max(0.0, v.dot(m)); }, v);
      const double ib = integrate_upper(a, [&](const Vec3<double>& m) { return b.D(m) * std::max(0.0, v.dot(m)); }, v);
      EXPECT_NEAR(ig / upper_visible_area(g, v), 1.0, 1e-7) << "GGX " << label(a, theta);
      EXPECT_NEAR(ib / upper_visible_area(b, v), 1.0, 1e-7) << "Beckmann " << label(a, theta);
    }
  }
}

// The marginal CDF of the standard visible slope x seen from theta, integrated independently (adaptive
// Gauss-Kronrod): the density (a - t) e^(-t^2), t < a = cot theta; below the horizon (a < 0) in the
// variable sigma = a - t with the factor e^(-a^2) taken out, sigma e^(sigma (2a - sigma)), so that nothing
// underflows far below it. Returns the lower tail (t < x), the upper tail, both over
// the total, and the logarithmic derivative of the tail that the test compares (for its rounding slack).
struct SlopeTails {
  double lower, upper, log_derivative_lower, log_derivative_upper;
};
SlopeTails slope_cdf_by_quadrature(double theta, double x) {
  using boost::math::quadrature::gauss_kronrod;
  const double inf = std::numeric_limits<double>::infinity();
  if (std::sin(theta) == 0) return {0.5 * std::erfc(-x), 0.5 * std::erfc(x), 0, 0};
  const double a = std::cos(theta) / std::sin(theta), s = a - x;
  if (a >= 0) {  // in t, split where the density peaks (near 0) so that no piece hides it
    const auto p = [&](double t) { return (a - t) * std::exp(-t * t); };
    double upper = 0, lo = x;
    for (double cut : {-8.0, 0.0, 8.0, a}) {
      if (cut <= lo || cut > a) continue;
      upper += gauss_kronrod<double, 61>::integrate(p, lo, cut, 12, 1e-13);
      lo = cut;
    }
    const double lower = gauss_kronrod<double, 61>::integrate(p, -inf, x, 12, 1e-13), total = lower + upper;
    return {lower / total, upper / total, p(x) / lower, p(x) / upper};
  }
  const auto f = [&](double sigma) { return sigma * std::exp(sigma * (2 * a - sigma)); };
  const double lower = gauss_kronrod<double, 61>::integrate(f, s, inf, 12, 1e-13);
  const double upper = gauss_kronrod<double, 61>::integrate(f, 0.0, s, 12, 1e-13);
  return {lower / (lower + upper), upper / (lower + upper), f(s) / lower, f(s) / upper};
}

// x = a - s is returned as a slope: near the edge of a view far below the horizon, the distance s to it is
// below the resolution of x. The comparison allows that rounding (4 ulps of x, through the tail's slope).
TEST(BeckmannSlopeInversion, ReturnedSlopeHasTheRequestedCdfInBothTails) {
  const double us[] = {1e-15, 1e-9, 1e-4, 0.02, 0.3, 0.5, 0.7, 0.98, 1 - 1e-4, 1 - 1e-9, 1 - 1e-14};
  for (double theta_deg : {0.0, 0.5, 10.0, 45.0, 75.0, 80.0, 89.99, 90.0, 90.01, 100.0, 135.0, 170.0, 179.0, 179.9}) {
    const double theta = theta_deg * kPi<double> / 180;
    for (double u : us) {
      const std::optional<double> x = microsim::detail::beckmann_visible_slope_x(std::cos(theta), std::sin(theta), u);
      ASSERT_TRUE(x.has_value()) << theta_deg;
      ASSERT_TRUE(std::isfinite(*x)) << theta_deg << " u=" << u;
      const SlopeTails t = slope_cdf_by_quadrature(theta, *x);
      const double rounding = 4 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(*x));
      // Each tail against its own target, relative: the inversion keeps the precision of the small tail.
      if (u <= 0.5) {
        EXPECT_NEAR(t.lower / u, 1.0, 1e-9 + rounding * t.log_derivative_lower)
            << "theta=" << theta_deg << " u=" << u << " x=" << *x;
      } else {
        EXPECT_NEAR(t.upper / (1 - u), 1.0, 1e-9 + rounding * t.log_derivative_upper)
            << "theta=" << theta_deg << " u=" << u << " x=" << *x;
      }
    }
  }
  EXPECT_FALSE(microsim::detail::beckmann_visible_slope_x(-1.0, 0.0, 0.5).has_value());  // straight up from below
}

// ---- the samplers' histograms ----------------------------------------------------------------------------

struct View {
  AlphaPair alpha;
  double theta, phi;
};

using NormalSampler = std::function<std::optional<Vec3<double>>(const Vec3<double>&, Vec2<double>)>;
using NormalPdf = std::function<double(const Vec3<double>&)>;

// Chi-square of n normals from `sample` seen from v against `pdf` (upper hemisphere), lobe bins of `rows`.
ChiSquareResult normals_against_pdf(const AlphaPair& a, const Vec3<double>& v, const NormalSampler& sample,
                                    const NormalPdf& pdf, std::uint64_t n, std::uint64_t seed, double level) {
  // The lobe binning follows the alpha stretch; its hemisphere is the upper one (a view with |v.z|).
  const Vec3<double> binning_view(v.x(), v.y(), std::abs(v.z()));
  const DirectionBinning bins = DirectionBinning::lobe(GGX<double>(a.ax, a.ay), binning_view,
                                                       SampleDomain::microfacet_normal, 10);
  IntegrationOptions io;
  io.breaks = {[v](const Vec3<double>& m) { return v.dot(m); }};  // the visibility edge (a kink)
  io.focus = bins.lattice_directions(2000);
  const BinIntegrals expected = bins.integrate(pdf, io);
  std::vector<double> observed(std::size_t(bins.size()), 0.0);
  double outside = 0;
  CounterRng rng(seed, 0);
  for (std::uint64_t i = 0; i < n; ++i) {
    const double u1 = rng.uniform(), u2 = rng.uniform();
    const std::optional<Vec3<double>> m = sample(v, {u1, u2});
    const std::optional<int> bin = m ? bins.bin_of(*m) : std::nullopt;
    if (bin) observed[std::size_t(*bin)] += 1; else outside += 1;
  }
  ChiSquareOptions co;
  co.significance = level;
  return goodness_of_fit(observed, expected.probability, double(n), co, outside);
}

const std::vector<View> kSamplerViews = {
    {{0.5, 0.5}, 0, 0},    {{0.5, 0.5}, 30, 20}, {{0.5, 0.5}, 60, 200}, {{0.5, 0.5}, 80, 45}, {{0.5, 0.5}, 89.5, 10},
    {{1, 1}, 75, 0},       {{0.05, 0.05}, 70, 30}, {{0.2, 0.7}, 60, 35}, {{0.2, 0.7}, 85, 120}, {{2, 2}, 89.9, 300}};

TEST(BeckmannVndfSampler, HistogramsMatchTheVisibleNormalPdf) {
  const double level = sidak_significance(0.01, int(kSamplerViews.size()));
  for (const View& view : kSamplerViews) {
    const Beckmann<double> b(view.alpha.ax, view.alpha.ay);
    const Vec3<double> v = direction_from_degrees(view.theta, view.phi);
    const NormalSampler sample = [&](const Vec3<double>& w, Vec2<double> u) -> std::optional<Vec3<double>> {
      const SampleResult<double> s = sample_beckmann_vndf(b, w, u);
      if (!s) return std::nullopt;
      EXPECT_NEAR(s->pdf, b.visible_normal_pdf(w, s->direction), 1e-12 * s->pdf);
      return s->direction;
    };
    const ChiSquareResult r = normals_against_pdf(
        view.alpha, v, sample, [&](const Vec3<double>& m) { return b.visible_normal_pdf(v, m); }, 100000, 11, level);
    EXPECT_FALSE(r.rejected) << label(view.alpha, view.theta) << " p=" << r.p_value << " " << r.reason;
  }
}

// Negative controls: GGX's visible normals of the same alpha, and Beckmann's seen from a view 3 degrees
// off, must both be rejected by the same test.
TEST(BeckmannVndfSampler, NegativeControlsAreRejected) {
  const AlphaPair a{0.5, 0.5};
  const Beckmann<double> b(0.5);
  const GGX<double> g(0.5);
  const Vec3<double> v = direction_from_degrees(70.0, 20.0);
  const NormalPdf pdf = [&](const Vec3<double>& m) { return b.visible_normal_pdf(v, m); };
  const NormalSampler ggx = [&](const Vec3<double>& w, Vec2<double> u) -> std::optional<Vec3<double>> {
    return sample_upper_visible_normal(g, w, u);
  };
  const NormalSampler tilted = [&](const Vec3<double>&, Vec2<double> u) -> std::optional<Vec3<double>> {
    return sample_upper_visible_normal(b, direction_from_degrees(73.0, 20.0), u);
  };
  EXPECT_TRUE(normals_against_pdf(a, v, ggx, pdf, 100000, 11, 0.01).rejected);
  EXPECT_TRUE(normals_against_pdf(a, v, tilted, pdf, 100000, 11, 0.01).rejected);
}

// The walk's sampler of upper normals from any view, GGX and Beckmann, above and below the horizon.
TEST(UpperVisibleNormals, HistogramsMatchThePdfOnBothSidesOfTheHorizon) {
  const std::vector<View> views = {{{0.5, 0.5}, 45, 30},  {{0.5, 0.5}, 95, 10},  {{0.5, 0.5}, 120, 250},
                                   {{1, 1}, 150, 0},      {{0.2, 0.7}, 110, 35}, {{1.5, 1.5}, 170, 60}};
  const double level = sidak_significance(0.01, int(2 * views.size()));
  for (const View& view : views) {
    const Vec3<double> v = direction_from_degrees(view.theta, view.phi);
    const GGX<double> g(view.alpha.ax, view.alpha.ay);
    const Beckmann<double> b(view.alpha.ax, view.alpha.ay);
    const ChiSquareResult rg = normals_against_pdf(
        view.alpha, v, [&](const Vec3<double>& w, Vec2<double> u) { return sample_upper_visible_normal(g, w, u); },
        [&](const Vec3<double>& m) { return upper_visible_normal_pdf(g, v, m); }, 100000, 5, level);
    const ChiSquareResult rb = normals_against_pdf(
        view.alpha, v, [&](const Vec3<double>& w, Vec2<double> u) { return sample_upper_visible_normal(b, w, u); },
        [&](const Vec3<double>& m) { return upper_visible_normal_pdf(b, v, m); }, 100000, 5, level);
    EXPECT_FALSE(rg.rejected) << "GGX " << label(view.alpha, view.theta) << " p=" << rg.p_value << " " << rg.reason;
    EXPECT_FALSE(rb.rejected) << "Beckmann " << label(view.alpha, view.theta) << " p=" << rb.p_value << " "
                              << rb.reason;
  }
}

// Negative control: the zoo's back-side convention (normals of -v, negated, then flipped up) is not the
// upper-normal distribution below the horizon, and the test sees it.
TEST(UpperVisibleNormals, BackSideConventionIsRejectedBelowTheHorizon) {
  const AlphaPair a{0.5, 0.5};
  const GGX<double> g(0.5);
  const Vec3<double> v = direction_from_degrees(120.0, 250.0);
  const NormalSampler back_side = [&](const Vec3<double>& w, Vec2<double> u) -> std::optional<Vec3<double>> {
    const SampleResult<double> s = sample_heitz2018(g, w, u);
    if (!s) return std::nullopt;
    return Vec3<double>(-s->direction);
  };
  EXPECT_TRUE(normals_against_pdf(a, v, back_side, [&](const Vec3<double>& m) { return upper_visible_normal_pdf(g, v, m); },
                                  100000, 5, 0.01)
                  .rejected);
}

TEST(BeckmannVndfSampler, ExtremeVariatesAndViewsGiveUnitVisibleNormals) {
  const double ends[] = {0.0, 1e-300, 0.5, 1 - 1e-16, kOneMinusEpsilon<double>};
  for (const AlphaPair& a : {AlphaPair{1e-4, 1e-4}, AlphaPair{0.5, 0.5}, AlphaPair{10, 10}, AlphaPair{1e-3, 1}}) {
    const Beckmann<double> b(a.ax, a.ay);
    for (double theta : {0.0, 1e-6, 45.0, 89.999999, 90.0, 90.000001, 135.0, 179.999}) {
      const Vec3<double> v = direction_from_degrees(theta, 33.0);
      for (double u1 : ends) {
        for (double u2 : ends) {
          const std::optional<Vec3<double>> m = sample_upper_visible_normal(b, v, {u1, u2});
          ASSERT_TRUE(m.has_value()) << label(a, theta) << " u=" << u1 << "," << u2;
          EXPECT_TRUE(m->allFinite());
          EXPECT_NEAR(m->norm(), 1.0, 1e-12);
          EXPECT_GE(m->z(), 0.0);
          EXPECT_GE(v.dot(*m), -1e-12) << label(a, theta) << " u=" << u1 << "," << u2;
        }
      }
    }
  }
}

// The single-scattering BSDFs of bsdf.h take Beckmann as well (the Beckmann analytic reference of the
// walk's order 1): reciprocal, and the dielectric's BTDF with the eta^2 factor.
TEST(BeckmannBsdf, MirrorBrdfIsReciprocal) {
  const Beckmann<double> b(0.4, 0.7);
  for (double ti : {10.0, 50.0, 80.0}) {
    for (double to : {0.0, 35.0, 70.0}) {
      const Vec3<double> i = direction_from_degrees(ti, 20.0), o = direction_from_degrees(to, 150.0);
      EXPECT_NEAR(mirror_brdf(b, i, o), mirror_brdf(b, o, i), 1e-13 * mirror_brdf(b, i, o));
      EXPECT_NEAR(dielectric_bsdf(b, 1.5, i, Vec3<double>(-o)) / (1.5 * 1.5), dielectric_bsdf(b, 1.5, Vec3<double>(-o), i),
                  1e-12 * dielectric_bsdf(b, 1.5, i, Vec3<double>(-o)));
    }
  }
}

}  // namespace
}  // namespace microsim
