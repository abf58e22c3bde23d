// Analytic tests of Smith-GGX (src/microfacet/ggx.h):
// - the normalisation identities by numerical integration (to 1e-6; the measured errors are printed and
//   recorded as test properties),
// - G1 / Lambda / G2 relations, slope-space P22, symmetries and the back-side convention,
// - float against double: worst ULP error of every function over a dense grid.
#include "microfacet/ggx.h"

#include "lune_quadrature.h"
#include "worst_error.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_ggx {

using namespace microsim;
using microsim::test::integrate_2d;
using microsim::test::integrate_lune;
using microsim::test::make_lune;
using microsim::test::StretchMap;

namespace {

struct AlphaPair {
  double ax, ay;
};

// Isotropic and anisotropic roughness, from the clamp (1e-4) to very rough, both orientations.
const std::vector<AlphaPair> kAlphas = {
    {1e-4, 1e-4}, {1e-3, 1e-3}, {0.01, 0.01}, {0.05, 0.05}, {0.3, 0.3}, {1, 1},     {2, 2},
    {0.1, 0.8},   {0.8, 0.1},   {0.05, 0.5},  {1e-3, 0.5},  {2, 0.01},  {1e-4, 1}, {1e-3, 1e-4}};
const std::vector<double> kThetas = {0, 30, 60, 80, 89};
const std::vector<double> kPhis = {17, 133};  // not axis-aligned

constexpr double kIdentityTolerance = 1e-6;

std::string label(const AlphaPair& a, double theta = -1, double phi = -1) {
  char buf[128];
  if (theta < 0)
    std::snprintf(buf, sizeof buf, "alpha=(%g,%g)", a.ax, a.ay);
  else
    std::snprintf(buf, sizeof buf, "alpha=(%g,%g) theta=%g phi=%g", a.ax, a.ay, theta, phi);
  return buf;
}

using microsim::test::WorstError;

}  // namespace

// ---- the normalisation identities ------------------------------------------------------------------------

// integral of D(m) m.z dm = 1 (the projected microfacet area equals the macro area).
TEST(GgxIdentities, ProjectedNdfIntegratesToOne) {
  WorstError worst{"int D(m) mz dm = 1"};
  for (const AlphaPair& a : kAlphas) {
    const GGX<double> ggx(a.ax, a.ay);
    const StretchMap map{ggx.alpha_x(), ggx.alpha_y()};
    const double integral = integrate_lune(make_lune({0, 0, 1}), [&](const Vec3<double>& h) {
      const Vec3<double> m = map.normal(h);
      return ggx.D(m) * m.z() * map.jacobian(h);
    });
    worst.add(std::abs(integral - 1), label(a));
    EXPECT_NEAR(integral, 1.0, kIdentityTolerance) << label(a);
  }
}

// The same identity integrated directly over m (no stretch map), where the lobe is wide enough for plain
// adaptive quadrature: guards against a compensating mistake in the test's own change of variables.
TEST(GgxIdentities, ProjectedNdfIntegratesToOneDirectlyInM) {
  WorstError worst{"int D(m) mz dm = 1 (direct in m)"};
  for (const AlphaPair& a : {AlphaPair{0.05, 0.05}, AlphaPair{0.3, 0.3}, AlphaPair{1, 1}, AlphaPair{2, 2},
                             AlphaPair{0.1, 0.8}, AlphaPair{0.05, 0.5}}) {
    const GGX<double> ggx(a.ax, a.ay);
    const double integral =
        integrate_lune(make_lune({0, 0, 1}), [&](const Vec3<double>& m) { return ggx.D(m) * m.z(); }, 1e-11, 18);
    worst.add(std::abs(integral - 1), label(a));
    EXPECT_NEAR(integral, 1.0, kIdentityTolerance) << label(a);
  }
}

// integral of D_v(v, m) dm = 1 for every view, including exactly grazing (theta = 90).
TEST(GgxIdentities, VisibleNormalPdfIntegratesToOne) {
  WorstError worst{"int D_v(v, m) dm = 1"};
  std::vector<double> thetas = kThetas;
  thetas.push_back(90);
  for (const AlphaPair& a : kAlphas) {
    const GGX<double> ggx(a.ax, a.ay);
    const StretchMap map{ggx.alpha_x(), ggx.alpha_y()};
    for (double theta : thetas) {
      for (double phi : kPhis) {
        const Vec3<double> v = direction_from_degrees(theta, phi);
        // <v, m> > 0  <=>  <A v, h> > 0
        const double integral = integrate_lune(make_lune({0, 0, 1}, map.stretch(v)), [&](const Vec3<double>& h) {
          return ggx.visible_normal_pdf(v, map.normal(h)) * map.jacobian(h);
        });
        worst.add(std::abs(integral - 1), label(a, theta, phi));
        EXPECT_NEAR(integral, 1.0, kIdentityTolerance) << label(a, theta, phi);
      }
    }
  }
}

TEST(GgxIdentities, VisibleNormalPdfIntegratesToOneDirectlyInM) {
  WorstError worst{"int D_v(v, m) dm = 1 (direct in m)"};
  for (const AlphaPair& a : {AlphaPair{0.05, 0.05}, AlphaPair{0.3, 0.3}, AlphaPair{1, 1}, AlphaPair{2, 2},
                             AlphaPair{0.1, 0.8}}) {
    const GGX<double> ggx(a.ax, a.ay);
    for (double theta : kThetas) {
      const Vec3<double> v = direction_from_degrees(theta, 17.0);
      const double integral = integrate_lune(
          make_lune({0, 0, 1}, v), [&](const Vec3<double>& m) { return ggx.visible_normal_pdf(v, m); }, 1e-11, 18);
      worst.add(std::abs(integral - 1), label(a, theta, 17));
      EXPECT_NEAR(integral, 1.0, kIdentityTolerance) << label(a, theta, 17);
    }
  }
}

// integral of D(m) <v, m>+ dm = v.z / G1(v) = projected_area(v).
TEST(GgxIdentities, ProjectedAreaMatchesG1) {
  WorstError worst{"int D(m) <v,m>+ dm = vz / G1(v)"};
  for (const AlphaPair& a : kAlphas) {
    const GGX<double> ggx(a.ax, a.ay);
    const StretchMap map{ggx.alpha_x(), ggx.alpha_y()};
    for (double theta : kThetas) {
      for (double phi : kPhis) {
        const Vec3<double> v = direction_from_degrees(theta, phi);
        const double integral = integrate_lune(make_lune({0, 0, 1}, map.stretch(v)), [&](const Vec3<double>& h) {
          const Vec3<double> m = map.normal(h);
          return ggx.D(m) * std::max(0.0, v.dot(m)) * map.jacobian(h);
        });
        const double expected = v.z() / ggx.G1(v);
        const double rel = std::abs(integral / expected - 1);
        worst.add(rel, label(a, theta, phi));
        EXPECT_NEAR(integral / expected, 1.0, kIdentityTolerance) << label(a, theta, phi);
        EXPECT_NEAR(ggx.projected_area(v) / expected, 1.0, 1e-14) << label(a, theta, phi);
      }
    }
  }
}

// Back side: a view below the horizon sees the lower hemisphere of normals, D_v(v, m) = D_v(-v, -m),
// and that pdf also integrates to 1 (over m.z < 0).
TEST(GgxIdentities, BackSideVisibleNormalPdf) {
  WorstError worst{"int D_v(v, m) dm = 1 (v below horizon)"};
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g;
  for (const AlphaPair& a : {AlphaPair{0.05, 0.05}, AlphaPair{0.3, 0.3}, AlphaPair{1e-3, 0.5}, AlphaPair{2, 2}}) {
    const GGX<double> ggx(a.ax, a.ay);
    const StretchMap map{ggx.alpha_x(), ggx.alpha_y()};
    for (double theta : {100.0, 150.0, 180.0}) {
      const Vec3<double> v = direction_from_degrees(theta, 133.0);
      const double integral = integrate_lune(make_lune({0, 0, -1}, map.stretch(v)), [&](const Vec3<double>& h) {
        return ggx.visible_normal_pdf(v, map.normal(h)) * map.jacobian(h);
      });
      worst.add(std::abs(integral - 1), label(a, theta, 133));
      EXPECT_NEAR(integral, 1.0, kIdentityTolerance) << label(a, theta, 133);
      for (int i = 0; i < 200; ++i) {
        Vec3<double> m = Vec3<double>(g(rng), g(rng), g(rng)).normalized();
        EXPECT_EQ(ggx.visible_normal_pdf(v, m), ggx.visible_normal_pdf(Vec3<double>(-v), Vec3<double>(-m)));
        if (m.z() > 0) {
          EXPECT_EQ(ggx.visible_normal_pdf(v, m), 0.0);  // front normals are not seen from below
        }
      }
    }
  }
}

// Slope space: P22 integrates to 1 over the slope plane (stretched polar coordinates s = (ax r cos phi,
// ay r sin phi), r = tan(u): ds = ax ay r dr dphi, dr = du / cos^2 u).
TEST(GgxIdentities, SlopePdfIntegratesToOne) {
  WorstError worst{"int P22(s) ds = 1"};
  for (const AlphaPair& a : kAlphas) {
    const GGX<double> ggx(a.ax, a.ay);
    const double ax = ggx.alpha_x(), ay = ggx.alpha_y();
    const double integral = integrate_2d(
        [&](double u, double phi) {
          const double r = std::tan(u), c = std::cos(u);
          return ggx.slope_pdf(ax * r * std::cos(phi), ay * r * std::sin(phi)) * ax * ay * r / (c * c);
        },
        0.0, kPi<double> / 2, 0.0, 2 * kPi<double>);
    worst.add(std::abs(integral - 1), label(a));
    EXPECT_NEAR(integral, 1.0, kIdentityTolerance) << label(a);
  }
}

// Negative controls: the same integrations reject plausible mistakes by far more than the tolerance,
// so the identity tests have power. (1) An NDF with its anisotropy axes swapped still satisfies
// int D mz = 1 (by symmetry) but not int D_v = 1 for a view off the axes; (2) a G1 whose a(phi) swaps
// cos and sin breaks int D <v, m>+ = vz / G1.
TEST(GgxIdentities, NegativeControlsAreDetected) {
  const GGX<double> ggx(0.1, 0.8), swapped(0.8, 0.1);
  const StretchMap map{0.1, 0.8};
  const Vec3<double> v = direction_from_degrees(60.0, 17.0);
  const auto wrong_dv = [&](const Vec3<double>& m) {
    return 2 * swapped.D(m) * std::max(0.0, v.dot(m)) / (v.z() + ggx.stretched_length(v));
  };
  const double i1 = integrate_lune(make_lune({0, 0, 1}, map.stretch(v)), [&](const Vec3<double>& h) {
    return wrong_dv(map.normal(h)) * map.jacobian(h);
  });
  const double i1_direct = integrate_lune(make_lune({0, 0, 1}, v), wrong_dv, 1e-11, 18);
  std::printf("[ negative ] int D_v with swapped anisotropy axes = %.6f (stretch map), %.6f (direct)\n", i1, i1_direct);
  EXPECT_GT(std::abs(i1 - 1), 1e-2);
  EXPECT_NEAR(i1, i1_direct, 1e-9);  // the two parameterisations agree on the wrong answer too
  const double area = integrate_lune(make_lune({0, 0, 1}, map.stretch(v)), [&](const Vec3<double>& h) {
    const Vec3<double> m = map.normal(h);
    return ggx.D(m) * std::max(0.0, v.dot(m)) * map.jacobian(h);
  });
  const double wrong_g1 = swapped.G1(v);
  std::printf("[ negative ] int D <v,m>+ / (vz / G1 with swapped a(phi)) = %.6f\n", area / (v.z() / wrong_g1));
  EXPECT_GT(std::abs(area / (v.z() / wrong_g1) - 1), 1e-2);
}

// ---- pointwise relations ------------------------------------------------------------------------------

namespace {
std::vector<Vec3<double>> random_directions(int n, unsigned seed, bool upper_only) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  std::vector<Vec3<double>> out;
  for (int i = 0; i < n; ++i) {
    Vec3<double> w(g(rng), g(rng), g(rng));
    if (i % 3 == 0) w.z() *= 1e-3;   // near the horizon
    if (i % 3 == 1) w.z() *= 300.0;  // near the pole
    w.normalize();
    if (upper_only) w.z() = std::abs(w.z());
    out.push_back(w);
  }
  return out;
}
}  // namespace

// D(m) = P22(-mx/mz, -my/mz) / mz^4 (Heitz 2014 eq. 37): the slope density and the NDF agree.
TEST(GgxRelations, NdfEqualsSlopePdfOverCos4) {
  for (const AlphaPair& a : kAlphas) {
    const GGX<double> ggx(a.ax, a.ay);
    for (const Vec3<double>& m : random_directions(500, 21, true)) {
      if (m.z() < 1e-6) continue;
      const double d = ggx.D(m);
      const double from_slopes = ggx.slope_pdf(-m.x() / m.z(), -m.y() / m.z()) / std::pow(m.z(), 4);
      EXPECT_NEAR(from_slopes / d, 1.0, 1e-13) << label(a) << " m=" << m.transpose();
    }
  }
}

// G1 = 1 / (1 + Lambda) = 2 vz / (vz + t), and Lambda against an independent evaluation from the
// angles: Lambda = (-1 + sqrt(1 + a^2 tan^2 theta)) / 2 with a^2 = cos^2 phi ax^2 + sin^2 phi ay^2
// (Heitz 2014 eq. 86), written as x / (2 (1 + sqrt(1 + x))) with x = a^2 tan^2 theta (same value,
// no cancellation).
TEST(GgxRelations, G1AndLambdaAgreeWithTheTextbookForms) {
  for (const AlphaPair& a : kAlphas) {
    const GGX<double> ggx(a.ax, a.ay);
    const double ax = ggx.alpha_x(), ay = ggx.alpha_y();
    for (double theta : {0.0, 1e-3, 10.0, 30.0, 45.0, 60.0, 80.0, 89.0, 89.9, 89.999}) {
      for (double phi : {0.0, 17.0, 90.0, 133.0, 260.0}) {
        const double th = theta * kPi<double> / 180, ph = phi * kPi<double> / 180;
        const Vec3<double> v = spherical_direction(th, ph);
        const double x = (sqr(std::cos(ph) * ax) + sqr(std::sin(ph) * ay)) * sqr(std::tan(th));
        const double lambda_ref = x / (2 * (1 + std::sqrt(1 + x)));
        const double lambda = ggx.Lambda(v);
        EXPECT_NEAR(lambda, lambda_ref, 1e-12 * lambda_ref + 1e-300) << label(a, theta, phi);
        const double g1 = ggx.G1(v);
        EXPECT_NEAR(g1, 1 / (1 + lambda), 1e-15) << label(a, theta, phi);
        const double t = std::sqrt(sqr(ax * v.x()) + sqr(ay * v.y()) + sqr(v.z()));
        EXPECT_NEAR(g1, 2 * v.z() / (v.z() + t), 1e-15) << label(a, theta, phi);
        EXPECT_GE(g1, 0.0);
        EXPECT_LE(g1, 1.0);
      }
    }
    // Horizon: Lambda = +inf, G1 = 0; pole: Lambda = 0, G1 = 1.
    EXPECT_EQ(ggx.Lambda(Vec3<double>(0.6, 0.8, 0)), std::numeric_limits<double>::infinity());
    EXPECT_EQ(ggx.G1(Vec3<double>(0.6, 0.8, 0)), 0.0);
    EXPECT_EQ(ggx.Lambda(Vec3<double>(0, 0, 1)), 0.0);
    EXPECT_EQ(ggx.G1(Vec3<double>(0, 0, 1)), 1.0);
  }
}

// Lambda(-w) = Lambda(w), G1(-w) = G1(w): the surface statistics are symmetric.
TEST(GgxRelations, LambdaIsEven) {
  for (const AlphaPair& a : kAlphas) {
    const GGX<double> ggx(a.ax, a.ay);
    for (const Vec3<double>& w : random_directions(300, 3, false)) {
      EXPECT_EQ(ggx.Lambda(w), ggx.Lambda(Vec3<double>(-w)));
      EXPECT_EQ(ggx.G1(w), ggx.G1(Vec3<double>(-w)));
    }
  }
}

// Height-correlated G2 = 1 / (1 + Lambda_i + Lambda_o), and G1i G1o <= G2 <= min(G1i, G1o).
TEST(GgxRelations, G2BetweenSeparableAndMinG1) {
  for (const AlphaPair& a : kAlphas) {
    const GGX<double> ggx(a.ax, a.ay);
    const auto dirs = random_directions(400, 9, true);
    for (std::size_t k = 0; k + 1 < dirs.size(); k += 2) {
      const Vec3<double>&wi = dirs[k], &wo = dirs[k + 1];
      const double g2 = ggx.G2(wi, wo), sep = ggx.G2_separable(wi, wo);
      const double gi = ggx.G1(wi), go = ggx.G1(wo);
      EXPECT_LE(sep, g2 * (1 + 1e-15)) << label(a);
      EXPECT_LE(g2, std::min(gi, go) * (1 + 1e-15)) << label(a);
      EXPECT_NEAR(sep, gi * go, 1e-16);
      const double li = ggx.Lambda(wi), lo = ggx.Lambda(wo);
      if (std::isfinite(li) && std::isfinite(lo)) {
        EXPECT_NEAR(g2 * (1 + li + lo), 1.0, 1e-13) << label(a);
      }
    }
    // One direction on the horizon: everything is 0, not NaN.
    EXPECT_EQ(ggx.G2(Vec3<double>(1, 0, 0), Vec3<double>(0, 0, 1)), 0.0);
    EXPECT_EQ(ggx.G2(Vec3<double>(1, 0, 0), Vec3<double>(0, 1, 0)), 0.0);
  }
}

// ---- float against double ------------------------------------------------------------------------------

namespace {

// |f - d| in units of the float ULP at the correctly rounded value of d. Infinities and zeros must
// match exactly (otherwise the error is infinite).
constexpr double kUnitRoundoff = 0x1p-24;  // u for float

double ulp_error(float f, double d) {
  if (std::isnan(f) || std::isnan(d)) return std::numeric_limits<double>::infinity();
  if (std::isinf(d) || std::isinf(f) || d == 0 || f == 0)
    return static_cast<double>(f) == d ? 0.0 : std::numeric_limits<double>::infinity();
  const float r = std::abs(static_cast<float>(d));
  const double ulp = static_cast<double>(std::nextafter(r, std::numeric_limits<float>::infinity()) - r);
  return std::abs(static_cast<double>(f) - d) / ulp;
}

struct UlpStat {
  const char* name;
  double bound;
  double worst = 0;
  std::string where{};
  long count = 0;
  void add(float f, double d, const std::string& at) {
    ++count;
    const double e = ulp_error(f, d);
    if (!(e <= worst)) {
      worst = e;
      where = at;
    }
  }
};

}  // namespace

// Every function is evaluated in float and in double on the SAME inputs (the float inputs widened
// exactly to double), so the difference is the float rounding inside the function, not the
// conditioning of the inputs. The error in float ULPs is at most the relative error in units of
// u = 2^-24, and each bound below is the first-order worst case of the function's chain of correctly
// rounded operations (each contributes u; a square doubles the relative error of its argument, a sqrt
// halves it; a sum of non-negative terms keeps the largest relative error; float pi adds u/2):
//   G1 = 2z / (z + t):                    t: 3u, z + t: 4u, quotient: 5.5u           -> bound 8
//   projected_area = (z + t) / 2:                                          5u           -> bound 8
//   Lambda = num / (2 z (t + z)):         num: 4u, 2 z (t + z): 5u, quotient: 10u    -> bound 12
//   G2_separable = G1 G1:                                                  12u          -> bound 12
//   G2 = gi go / (gi + go - gi go):       the denominator is >= max(gi, go), so its terms' errors
//                                         (<= 5.5u each, <= 3 max) give <= 17u; numerator 12u -> bound 32
//   slope_pdf = 1 / (pi ax ay (1 + sx^2/ax^2 + sy^2/ay^2)^2):  4u, squared 9u, pi ax ay 2.5u -> 13.5u -> 16
//   D = len2^2 / (pi ax ay e^2):          e: 4u -> e^2 9u, len2^2 7u, pi ax ay e^2 12.5u -> 20.5u -> bound 24
//   D_v = 2 D <v, m> / (z + t):           D 20.5u, the dot 3u ABSOLUTE (|v|, |m| ~ 1), denominator 4u.
// The dot's absolute error is a large relative error near <v, m> = 0, a cancellation in the INPUTS
// that no float evaluation avoids. So D_v is measured in ULP where |<v, m>| >= 1/2 (dot <= 6u
// relative: 32.5u -> bound 40), and everywhere as |f - d| / (u * 2 D / (z + t)), i.e. the error
// relative to D_v without its cosine factor (20.5u <v,m> + 3u + 5u <= 29u -> bound 32), which also
// covers the sign of <v, m> flipping between float and double.
TEST(GgxFloatVsDouble, WorstUlpErrorIsBounded) {
  std::vector<AlphaPair> alphas;
  for (double a : {1e-4, 1e-3, 0.01, 0.1, 0.5, 1.0, 2.0, 10.0})
    for (double ratio : {1.0, 0.1, 1e-3}) {
      alphas.push_back({a, a * ratio});
      if (ratio != 1) alphas.push_back({a * ratio, a});
    }
  std::vector<Vec3<double>> views;
  for (double theta : {0.0, 1e-3, 10.0, 30.0, 60.0, 80.0, 89.0, 89.9, 89.999})
    for (double phi : {0.0, 17.0, 45.0, 90.0, 133.0, 260.0}) views.push_back(direction_from_degrees(theta, phi));
  std::vector<Vec3<double>> normals = random_directions(400, 77, true);
  for (double theta : {0.0, 1e-2, 1.0, 20.0, 45.0, 70.0, 85.0, 89.99})
    for (double phi : {0.0, 30.0, 200.0}) normals.push_back(direction_from_degrees(theta, phi));

  UlpStat d{"D", 24}, lambda{"Lambda", 12}, g1{"G1", 8}, g2{"G2", 32}, g2s{"G2_separable", 12},
      dv{"D_v", 40}, p22{"slope_pdf", 16}, area{"projected_area", 8};
  std::string where;
  char buf[256];
  double dv_worst_scaled = 0;
  std::string dv_scaled_where;

  for (const AlphaPair& a : alphas) {
    const GGX<float> gf(static_cast<float>(a.ax), static_cast<float>(a.ay));
    const GGX<double> gd(gf.alpha_x(), gf.alpha_y());  // the same (float) alpha
    // Normals inside this lobe too: the stretch map of Heitz 2018 sends hemisphere directions there.
    std::vector<Vec3<double>> lobe = normals;
    for (const Vec3<double>& h : random_directions(60, 78, true)) {
      lobe.push_back(StretchMap{gd.alpha_x(), gd.alpha_y()}.normal(h));
    }
    for (const Vec3<double>& m0 : lobe) {
      const Vec3<float> mf = m0.cast<float>();
      const Vec3<double> m = mf.cast<double>();
      std::snprintf(buf, sizeof buf, "alpha=(%g,%g) m=(%.9g,%.9g,%.9g)", gd.alpha_x(), gd.alpha_y(), m.x(), m.y(), m.z());
      where = buf;
      d.add(gf.D(mf), gd.D(m), where);
      if (mf.z() > 0) {
        const float sxf = -mf.x() / mf.z(), syf = -mf.y() / mf.z();
        p22.add(gf.slope_pdf(sxf, syf), gd.slope_pdf(sxf, syf), where);
      }
    }
    for (const Vec3<double>& v0 : views) {
      const Vec3<float> vf = v0.cast<float>();
      const Vec3<double> v = vf.cast<double>();
      std::snprintf(buf, sizeof buf, "alpha=(%g,%g) v=(%.9g,%.9g,%.9g)", gd.alpha_x(), gd.alpha_y(), v.x(), v.y(), v.z());
      where = buf;
      lambda.add(gf.Lambda(vf), gd.Lambda(v), where);
      g1.add(gf.G1(vf), gd.G1(v), where);
      area.add(gf.projected_area(vf), gd.projected_area(v), where);
      for (const Vec3<double>& l0 : views) {
        const Vec3<float> lf = l0.cast<float>();
        const Vec3<double> l = lf.cast<double>();
        g2.add(gf.G2(vf, lf), gd.G2(v, l), where);
        g2s.add(gf.G2_separable(vf, lf), gd.G2_separable(v, l), where);
      }
      for (const Vec3<double>& m0 : lobe) {
        const Vec3<float> mf = m0.cast<float>();
        const Vec3<double> m = mf.cast<double>();
        std::snprintf(buf, sizeof buf, "alpha=(%g,%g) v=(%.9g,%.9g,%.9g) m=(%.9g,%.9g,%.9g)", gd.alpha_x(), gd.alpha_y(), v.x(),
                      v.y(), v.z(), m.x(), m.y(), m.z());
        where = buf;
        const float pf = gf.visible_normal_pdf(vf, mf);
        const double pd = gd.visible_normal_pdf(v, m);
        const double vm = v.dot(m);
        if (std::abs(vm) >= 0.5) dv.add(pf, pd, where);
        const double pd_without_cosine = 2 * gd.D(m) / (v.z() + gd.stretched_length(v));
        if (pd_without_cosine > 0) {
          const double scaled = std::abs(pf - pd) / pd_without_cosine / kUnitRoundoff;
          if (!(scaled <= dv_worst_scaled)) {
            dv_worst_scaled = scaled;
            dv_scaled_where = where;
          }
        }
      }
    }
  }
  for (UlpStat* s : {&d, &p22, &lambda, &g1, &g2, &g2s, &dv, &area}) {
    std::printf("[ float ULP ] %-15s worst %8.2f ULP over %7ld values (bound %g) at %s\n", s->name, s->worst,
                s->count, s->bound, s->where.c_str());
    char value[32];
    std::snprintf(value, sizeof value, "%.2f", s->worst);
    ::testing::Test::RecordProperty(std::string("worst_ulp_") + s->name, value);
    EXPECT_LE(s->worst, s->bound) << s->name << " at " << s->where;
  }
  std::printf("[ float ULP ] D_v error / (u 2 D / (z + t)), all m: worst %.2f (bound 32) at %s\n", dv_worst_scaled,
              dv_scaled_where.c_str());
  char value[32];
  std::snprintf(value, sizeof value, "%.2f", dv_worst_scaled);
  ::testing::Test::RecordProperty("worst_scaled_D_v", value);
  EXPECT_LE(dv_worst_scaled, 32.0) << dv_scaled_where;
}

}  // namespace test_ggx
