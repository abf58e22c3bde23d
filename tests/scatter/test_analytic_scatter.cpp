// The analytic single-scattering reference (scatter/analytic_scatter.h): its order-1 total is the published
// single-scattering albedo of a GGX mirror and an independent quadrature (Boost.Math Gauss-Kronrod in
// theta and phi) of the directional albedo; its bins are independent quadratures over the bins' bounds;
// dielectrics lose energy to multiple scattering but not much at small roughness; a synthetic measurement
// whose expectation it is passes the weighted chi-square, and one of another roughness is rejected.
#include "scatter/analytic_scatter.h"

#include "scatter/smith_walk.h"
#include "scatter_samples.h"
#include "stats/scatter_compare.h"

#include <boost/math/quadrature/gauss_kronrod.hpp>
#include <gtest/gtest.h>

#include <cmath>

namespace microsim {
namespace {

using boost::math::quadrature::gauss_kronrod;

Vec3<double> direction(double theta, double phi) {
  return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
}

Vec3<double> view_of_mu(double mu) { return {std::sqrt(1 - mu * mu), 0, mu}; }

// The integral of f |cos o| over theta in [t0, t1], phi in [p0, p1] (radians), by nested adaptive
// Gauss-Kronrod (61 points, to a relative `tolerance`): independent of the binning and its cubature.
double quadrature(const std::function<double(const Vec3<double>&)>& flux, double t0, double t1, double p0, double p1,
                  double tolerance = 1e-11) {
  const auto inner = [&](double theta) {
    const auto g = [&](double phi) { return flux(direction(theta, phi)) * std::sin(theta); };
    return gauss_kronrod<double, 61>::integrate(g, p0, p1, 10, tolerance);
  };
  return gauss_kronrod<double, 61>::integrate(inner, t0, t1, 10, tolerance);
}

double sum(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return s;
}

// The single-scattering albedo E(mu) of the GGX mirror: the order-1 total of the binned expectation.
double binned_albedo(double alpha, double mu, int rows = 8) {
  return sum(analytic_single_scattering(GGX<double>(alpha), view_of_mu(mu), Material::mirror(), rows).order1[0]);
}

// Published values, given to three decimals.
TEST(AnalyticScatter, MirrorOrderOneIsThePublishedSingleScatteringAlbedo) {
  EXPECT_NEAR(binned_albedo(1.0, 1.0), 0.307, 6e-4);
  EXPECT_NEAR(binned_albedo(1.0, 0.5), 0.451, 6e-4);
  EXPECT_NEAR(binned_albedo(0.5, 1.0), 0.688, 6e-4);
  EXPECT_NEAR(binned_albedo(0.5, 0.5), 0.698, 6e-4);
}

TEST(AnalyticScatter, MirrorOrderOneIsTheDirectionalAlbedoByIndependentQuadrature) {
  for (double alpha : {0.2, 0.5, 1.0})
    for (double mu : {1.0, 0.7, 0.3, 0.1}) {
      const GGX<double> ggx(alpha);
      const Vec3<double> wi = view_of_mu(mu);
      const auto flux = [&](const Vec3<double>& wo) { return single_scattering_flux(ggx, Material::mirror(), 0, wi, wo); };
      // The lobe peaks at the reflection; split theta there so that each piece is smooth.
      const double peak = std::acos(mu);
      const double e = quadrature(flux, 0, peak, 0, 2 * kPi<double>) + quadrature(flux, peak, kPi<double> / 2, 0, 2 * kPi<double>);
      EXPECT_NEAR(binned_albedo(alpha, mu), e, 2e-6 * e) << "alpha " << alpha << " mu " << mu;
    }
}

// A few bins of each side against the quadrature over their own bounds.
void expect_bins_match_quadrature(const GGX<double>& ggx, const Vec3<double>& wi, const Material& m, int channel) {
  const int rows = 4;
  const ScatterExpectation e = analytic_single_scattering(ggx, wi, m, rows);
  const DirectionBinning b = DirectionBinning::hemispheres(rows);
  const auto flux = [&](const Vec3<double>& wo) { return single_scattering_flux(ggx, m, channel, wi, wo); };
  for (int bin : {0, 17, 26, 40, 63, 64 + 1, 64 + 20, 64 + 40, 127}) {
    const BinBounds bb = b.bounds(bin);
    const double d = kPi<double> / 180;
    const double q =
        quadrature(flux, bb.theta_min_deg * d, bb.theta_max_deg * d, bb.phi_min_deg * d, bb.phi_max_deg * d, 1e-8);
    EXPECT_NEAR(e.order1[std::size_t(channel)][std::size_t(bin)], q, 1e-7 + 1e-5 * q)
        << m.describe() << " channel " << channel << " bin " << b.describe_bin(bin);
  }
}

TEST(AnalyticScatter, BeckmannMirrorOrderOneIsTheDirectionalAlbedoByIndependentQuadrature) {
  for (double alpha : {0.3, 1.0})
    for (double mu : {1.0, 0.4}) {
      const Beckmann<double> b(alpha);
      const Vec3<double> wi = view_of_mu(mu);
      const auto flux = [&](const Vec3<double>& wo) { return single_scattering_flux(b, Material::mirror(), 0, wi, wo); };
      const double peak = std::acos(mu);
      const double e = quadrature(flux, 0, peak, 0, 2 * kPi<double>) + quadrature(flux, peak, kPi<double> / 2, 0, 2 * kPi<double>);
      const double binned = sum(analytic_single_scattering(b, wi, Material::mirror(), 8).order1[0]);
      EXPECT_NEAR(binned, e, 2e-6 * e) << "alpha " << alpha << " mu " << mu;
      EXPECT_NE(binned, binned_albedo(alpha, mu)) << "Beckmann is not GGX";
    }
}

TEST(AnalyticScatter, BinsAreIndependentQuadraturesOverTheirBounds) {
  const Vec3<double> wi = direction(0.7, 0.4);
  expect_bins_match_quadrature(GGX<double>(0.6, 0.3), wi, Material::conductor({{0.2, 3.9}, {1.1, 0.3}}), 1);
  expect_bins_match_quadrature(GGX<double>(0.5), wi, Material::dielectric(1.5), 0);
  expect_bins_match_quadrature(GGX<double>(0.5), -direction(0.4, 1.0), Material::dielectric(1.5), 0);  // from inside
}

TEST(AnalyticScatter, DielectricsLoseEnergyToMultipleScatteringOnlyWhenRough) {
  for (const double theta : {0.0, 0.6, 1.2})
    for (const bool inside : {false, true}) {
      const Vec3<double> wi = inside ? Vec3<double>(-direction(theta, 0)) : direction(theta, 0);
      const double smooth = sum(analytic_single_scattering(GGX<double>(0.05), wi, Material::dielectric(1.5), 2).order1[0]);
      const double rough = sum(analytic_single_scattering(GGX<double>(1.0), wi, Material::dielectric(1.5), 2).order1[0]);
      EXPECT_LT(smooth, 1.0 + 1e-6);
      EXPECT_GT(smooth, 0.97) << "theta " << theta << (inside ? " inside" : " outside");
      EXPECT_LT(rough, smooth - 0.02) << "theta " << theta << (inside ? " inside" : " outside");
    }
}

TEST(AnalyticScatter, RefusesWhatItCannotModel) {
  const GGX<double> ggx(0.5);
  EXPECT_THROW(analytic_single_scattering(ggx, Vec3<double>::UnitZ(), Material::lambertian(), 4), std::invalid_argument);
  EXPECT_THROW(analytic_single_scattering(ggx, -Vec3<double>::UnitZ(), Material::mirror(), 4), std::invalid_argument);
  EXPECT_THROW(analytic_single_scattering(ggx, Vec3<double>(1, 0, 0), Material::mirror(), 4), std::invalid_argument);
  EXPECT_THROW(analytic_single_scattering(ggx, Vec3<double>::UnitZ(), Material::mirror(), 0), std::invalid_argument);
}

// The synthetic measurement (tests/scatter_samples.h) samples exactly the analytic order 1.
TEST(AnalyticScatter, ASampledMeasurementPassesAndAnotherRoughnessIsRejected) {
  ScatterOptions o;
  o.wi = direction(0.9, 0.0);
  o.material = Material::conductor({{0.2, 3.9}, {1.4, 1.8}});
  o.paths = 200000;
  o.rows = 6;
  o.seed = 4;
  const ScatterExpectation e = analytic_single_scattering(GGX<double>(0.5), o.wi, o.material, o.rows);
  ScatterFile expected;
  expected.kind = ScatterFileKind::expectation;
  expected.expectation = e;
  for (const double alpha : {0.5, 0.45}) {
    ScatterFile measured;
    measured.histogram = test::synthetic_scatter(o, alpha);
    ScatterComparisonOptions options;
    for (const LobeComparison& c : compare_scatter_files(measured, "measured", expected, "analytic", options)) {
      EXPECT_EQ(c.order_bin, 0);
      ASSERT_TRUE(c.chi2) << c.insufficient;
      if (alpha == 0.5) {
        EXPECT_GT(c.chi2->p_value, 1e-3) << "channel " << c.channel;
        EXPECT_LT(std::abs(c.difference.value), 4 * c.difference.standard_error);
      } else {
        EXPECT_LT(c.chi2->p_value, 1e-6) << "channel " << c.channel;  // the negative control
      }
    }
  }
}

// Order 1 of the Smith random walk (scatter/smith_walk.h) is the analytic expectation, through the whole
// comparison (weighted chi-square and albedo), for a GGX mirror, a Beckmann conductor and a GGX dielectric
// from outside and from inside (its refraction lobe with the Smith microsurface's own transmission_G2).
TEST(AnalyticScatter, TheSmithWalksOrderOneIsTheAnalyticExpectation) {
  struct Case {
    NdfKind ndf;
    double alpha, theta;
    Material material;
  };
  const std::vector<Case> cases{{NdfKind::ggx, 0.6, 0.8, Material::mirror()},
                                {NdfKind::beckmann, 0.4, 1.0, Material::conductor({{0.2, 3.9}})},
                                {NdfKind::ggx, 0.5, 1.2, Material::dielectric(1.5)},
                                {NdfKind::ggx, 0.5, kPi<double> - 0.7, Material::dielectric(1.5)}};
  for (const Case& c : cases) {
    ScatterOptions o;
    o.wi = direction(c.theta, 0.4);
    o.material = c.material;
    o.paths = 200000;
    o.rows = 5;
    o.seed = 21;
    ScatterFile walk, expected;
    walk.histogram = smith_walk_scatter({c.ndf, c.alpha, c.alpha, HeightDistribution::uniform}, o);
    expected.kind = ScatterFileKind::expectation;
    expected.expectation = c.ndf == NdfKind::ggx ? analytic_single_scattering(GGX<double>(c.alpha), o.wi, o.material, o.rows)
                                                 : analytic_single_scattering(Beckmann<double>(c.alpha), o.wi, o.material, o.rows);
    const std::vector<LobeComparison> r = compare_scatter_files(walk, "walk", expected, "analytic", {});
    ASSERT_EQ(r.size(), 1u);
    ASSERT_TRUE(r[0].chi2) << r[0].insufficient;
    EXPECT_GT(r[0].chi2->p_value, 1e-3) << c.material.describe() << " theta " << c.theta;
    EXPECT_GT(r[0].difference_p, 1e-3) << c.material.describe() << " theta " << c.theta << ": " << r[0].difference.value;
  }
}

// The level at the scale of whole scattering results: over 60 seeds, a measurement against the analytic
// expectation (order 1) and against a second measurement (orders 1, 2 and the total) rejects at 0.01 as
// often as the level says (60 x 4 tests expect 2.4 rejections; 9 or more have probability 2e-4), with
// uniform p-values.
TEST(AnalyticScatter, SampledMeasurementsPassAtTheStatedLevel) {
  ScatterOptions o;
  o.wi = direction(1.1, 0.3);
  o.material = Material::conductor({{0.5, 2.4}});
  o.paths = 40000;
  o.rows = 4;
  ScatterFile expected;
  expected.kind = ScatterFileKind::expectation;
  expected.expectation = analytic_single_scattering(GGX<double>(0.3), o.wi, o.material, o.rows);
  std::vector<double> p_values;
  int rejected = 0;
  ScatterComparisonOptions options;
  options.order_bins = {0, 1, kTotalOrder};
  for (std::uint64_t seed = 100; seed < 160; ++seed) {
    ScatterFile a, b;
    o.seed = seed;
    a.histogram = test::synthetic_scatter(o, 0.3);
    o.seed = seed + 1000;
    b.histogram = test::synthetic_scatter(o, 0.3);
    std::vector<LobeComparison> all = compare_scatter_files(a, "a", b, "b", options);
    for (const LobeComparison& c : compare_scatter_files(a, "a", expected, "analytic", options)) all.push_back(c);
    for (const LobeComparison& c : all) {
      ASSERT_TRUE(c.chi2) << c.insufficient;
      p_values.push_back(c.chi2->p_value);
      rejected += c.chi2->p_value < 0.01;
    }
  }
  EXPECT_EQ(p_values.size(), 240u);
  EXPECT_LE(rejected, 8);
  EXPECT_GT(ks_test_uniform(p_values).p_value, 1e-3);
}

}  // namespace
}  // namespace microsim
