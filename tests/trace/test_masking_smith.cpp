// Tests of the Smith predictions for heightfields: analytic GGX/Beckmann (normalisation, Lambda against
// its slope-space definition) and the empirical-NDF Smith model (identities that hold exactly on a
// periodic tile, tabulated Lambda against the exact pass, VNDF bin probabilities).
#include "microgeom/assembly.h"
#include "core/random.h"
#include "trace/smith_prediction.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace microsim {
namespace {

// Simpson's rule on [a, b] with n (even) intervals.
template <class F> double simpson(F f, double a, double b, int n) {
  const double h = (b - a) / n;
  double s = f(a) + f(b);
  for (int i = 1; i < n; ++i) s += f(a + i * h) * (i % 2 ? 4.0 : 2.0);
  return s * h / 3.0;
}

// Integral over the upper hemisphere of f(w) d omega, in (theta, phi).
template <class F> double hemisphere(F f, int n = 400) {
  return simpson(
      [&](double theta) {
        return std::sin(theta) *
               simpson([&](double phi) { return f(spherical_direction(theta, phi)); }, 0.0, 2 * kPi<double>, n);
      },
      0.0, kPi<double> / 2, n);
}

TEST(AnalyticSmith, GgxMatchesTheGgxClass) {
  const AnalyticSmith s(NdfKind::ggx, 0.3, 0.7);
  const GGX<double> g(0.3, 0.7);
  for (double theta : {0.0, 20.0, 60.0, 85.0}) {
    const Vec3<double> w = direction_from_degrees(theta, 37.0), m = direction_from_degrees(theta / 3, 100.0);
    EXPECT_DOUBLE_EQ(s.Lambda(w), g.Lambda(w));
    EXPECT_DOUBLE_EQ(s.D(m), g.D(m));
    EXPECT_DOUBLE_EQ(s.vndf(w, m), g.visible_normal_pdf(w, m));
    EXPECT_NEAR(s.G2(w, m), g.G2(w, m), 1e-15);
  }
}

// Beckmann: D is normalised (integral of D mz = 1), D_v integrates to 1, and Lambda equals its slope-space
// definition (1/mu) E[(s_phi - mu)+] with s_phi ~ N(0, alpha(phi)^2 / 2) (Heitz 2014 eq. 72), computed by
// quadrature, for an anisotropic roughness.
TEST(AnalyticSmith, BeckmannNormalisationAndLambdaDefinition) {
  const double ax = 0.4, ay = 0.8;
  const AnalyticSmith s(NdfKind::beckmann, ax, ay);
  EXPECT_NEAR(hemisphere([&](const Vec3<double>& m) { return s.D(m) * m.z(); }), 1.0, 1e-5);
  for (double theta : {30.0, 70.0, 85.0}) {
    const double phi = 25.0;
    const Vec3<double> w = direction_from_degrees(theta, phi);
    EXPECT_NEAR(hemisphere([&](const Vec3<double>& m) { return s.vndf(w, m); }), 1.0, 1e-4) << theta;
    const double p = phi * kPi<double> / 180;
    const double sigma = std::sqrt(sqr(ax * std::cos(p)) + sqr(ay * std::sin(p))) / std::sqrt(2.0);
    const double mu = 1.0 / std::tan(theta * kPi<double> / 180);
    const double excess = simpson(
        [&](double x) { return (x - mu) * std::exp(-x * x / (2 * sigma * sigma)) / (sigma * std::sqrt(2 * kPi<double>)); },
        mu, mu + 12 * sigma, 4000);
    EXPECT_NEAR(s.Lambda(w), excess / mu, 1e-9 + 1e-7 * excess / mu) << theta;
  }
  EXPECT_EQ(s.Lambda(Vec3<double>(0, 0, 1)), 0.0);
  EXPECT_TRUE(std::isinf(s.Lambda(Vec3<double>(1, 0, 0))));
  EXPECT_EQ(s.G1(Vec3<double>(1, 0, 0)), 0.0);
  EXPECT_GE(s.Lambda(direction_from_degrees(1e-3, 0.0)), 0.0);  // no negative round-off near the pole
}

microgeom::Heightfield random_surface(int n, std::uint64_t seed, double amplitude) {
  CounterRng rng(seed, 0);
  std::vector<float> z(std::size_t(n) * n);
  for (auto& h : z) h = float(amplitude * (rng.uniform() - 0.5));
  return microgeom::Heightfield(n, 1.0, std::move(z));
}

// Identities of the empirical Smith model on any periodic tile: A(w) = w_z (1 + Lambda(w)) (the mean
// slope is 0), Lambda(pole) = 0, Lambda equals the direct mean over triangle slopes.
TEST(EmpiricalSmith, ExactIdentitiesOnAPeriodicTile) {
  const auto field = random_surface(64, 3, 0.05);
  const EmpiricalSmith e(field);
  for (double theta : {10.0, 45.0, 80.0, 89.0}) {
    const Vec3<double> w = direction_from_degrees(theta, 123.0);
    const double lambda = e.Lambda(w);
    EXPECT_NEAR(e.projected_area(w), w.z() * (1.0 + lambda), 1e-12 * (1.0 + lambda)) << theta;
    double direct = 0;
    for (std::uint32_t t = 0; t < field.triangle_count(); ++t) {
      const Eigen::Vector2d s = field.triangle_slope(t);
      direct += std::max(s.x() * w.x() + s.y() * w.y() - w.z(), 0.0);
    }
    direct /= double(field.triangle_count()) * w.z();
    EXPECT_NEAR(lambda, direct, 1e-12 * (1 + direct));
    EXPECT_NEAR(e.G1(w), w.z() / e.projected_area(w), 1e-12);
  }
  EXPECT_EQ(e.Lambda(Vec3<double>(0, 0, 1)), 0.0);
}

TEST(EmpiricalSmith, TabulatedLambdaMatchesExactPass) {
  microgeom::AssemblyParams p;
  p.assembly = "smith";
  p.alpha_x = p.alpha_y = 0.5;
  p.resolution = 128;
  const auto field = microgeom::build_assembly(p);
  const EmpiricalSmith e(field);
  for (double theta : {20.0, 50.0, 75.0, 85.0, 89.0}) {
    for (double phi : {0.0, 17.0, 200.0, 359.0}) {
      const Vec3<double> w = direction_from_degrees(theta, phi);
      const double exact = e.Lambda(w), tab = e.Lambda_tabulated(w);
      // Azimuthal interpolation between 64 tables dominates the error (5.6 degree steps).
      EXPECT_NEAR(tab, exact, 2e-3 * exact + 1e-6) << theta << " " << phi;
    }
  }
}

// The `smith` assembly's own NDF is GGX within its build tolerance, so the empirical G1 is close to the
// analytic one (the residual is the NDF error the two predictions are meant to separate). Lambda itself
// can differ by tens of percent at small theta: there it is a mean over the far tail of the slopes
// (s_phi > cot theta = 3.5 alpha at 30 deg), which a finite tile samples poorly (GGX slopes have infinite
// variance).
TEST(EmpiricalSmith, SmithAssemblyLambdaCloseToGgx) {
  microgeom::AssemblyParams p;
  p.assembly = "smith";
  p.alpha_x = p.alpha_y = 0.5;
  p.resolution = 256;
  const auto field = microgeom::build_assembly(p);
  const EmpiricalSmith e(field);
  std::string source;
  const AnalyticSmith a = analytic_reference(field, &source);
  EXPECT_EQ(source, "metadata");
  EXPECT_EQ(a.ndf(), NdfKind::ggx);
  for (double theta : {30.0, 60.0, 75.0, 85.0}) {
    const Vec3<double> w = direction_from_degrees(theta, 30.0);
    EXPECT_NEAR(e.G1(w) / a.G1(w), 1.0, 0.01) << theta;
  }
  // The fit from the median slope recovers alpha when the metadata is missing.
  microgeom::Heightfield bare(field.resolution(), field.tile_size(), field.heights());
  const AnalyticSmith fitted = analytic_reference(bare, &source);
  EXPECT_EQ(source, "fitted");
  EXPECT_NEAR(fitted.alpha_x(), 0.5, 0.02);
  EXPECT_NEAR(fitted.alpha_y(), 0.5, 0.02);
}

TEST(EmpiricalSmith, VndfBinProbabilitiesAndHeightCdf) {
  const auto field = random_surface(64, 5, 0.03);
  const EmpiricalSmith e(field);
  const Vec3<double> w = direction_from_degrees(60.0, 10.0);
  const auto binning = DirectionBinning::sphere(9);
  const auto p = e.vndf_bin_probabilities(binning, w);
  double total = 0;
  for (double x : p) {
    EXPECT_GE(x, 0.0);
    total += x;
  }
  EXPECT_NEAR(total, 1.0, 1e-12);
  // Bins entirely facing away from w get nothing.
  for (int b = 0; b < binning.size(); ++b) {
    const BinBounds bb = binning.bounds(b);
    if (bb.theta_min_deg >= 90.0) {
      EXPECT_EQ(p[std::size_t(b)], 0.0);
    }
  }
  EXPECT_EQ(e.height_cdf(field.min_height() - 1), 0.0);
  EXPECT_EQ(e.height_cdf(field.max_height()), 1.0);
  EXPECT_NEAR(e.height_cdf(double(e.sorted_heights()[2047])), 2048.0 / 4096.0, 1e-12);
  EXPECT_EQ(EmpiricalSmith::height_masking(0.0, 0.5), 0.0);
  EXPECT_NEAR(EmpiricalSmith::height_masking(0.25, 0.5), 0.5, 1e-15);
}

}  // namespace
}  // namespace microsim
