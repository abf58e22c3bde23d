// Tests of the equal-area direction bins and of the adaptive cubature of pdfs over them.
#include "stats/binning.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <random>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_binning {

using namespace microsim;

namespace {

Vec3<double> random_direction(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const double z = 2 * uni(rng) - 1, phi = 2 * kPi<double> * uni(rng);
  const double s = std::sqrt(1 - z * z);
  return {s * std::cos(phi), s * std::sin(phi), z};
}

// The options the validator uses for sphere bins: focus on the lobe, jumps of the pdf on cell edges
// (lobe bins need neither).
IntegrationOptions lobe_focus(const GGX<double>& ggx, const Vec3<double>& wi, SampleDomain domain, bool sphere) {
  IntegrationOptions o;
  if (sphere) {
    o.focus = DirectionBinning::lobe(ggx, wi, domain, 31).lattice_directions(4096);
    o.z_breaks = {0.0};
    if (domain == SampleDomain::reflected_direction) o.z_breaks.push_back(-wi.z());
  }
  return o;
}

}  // namespace

TEST(DirectionBinning, SphereShapeAndValidation) {
  const auto b = DirectionBinning::sphere(31);
  EXPECT_EQ(b.rows(), 31);
  EXPECT_EQ(b.cols(), 62);
  EXPECT_EQ(b.size(), 31 * 62);
  EXPECT_EQ(b.kind(), BinningKind::sphere);
  EXPECT_THROW(DirectionBinning::sphere(30), std::invalid_argument);
  EXPECT_THROW(DirectionBinning::sphere(0), std::invalid_argument);
  EXPECT_THROW(DirectionBinning::sphere(-3), std::invalid_argument);
  EXPECT_THROW(DirectionBinning::lobe(GGX<double>(0.3), Vec3<double>(0, 0, 1), SampleDomain::microfacet_normal, 0),
               std::invalid_argument);
}

TEST(DirectionBinning, BinOfAgreesWithBounds) {
  std::mt19937_64 rng(11);
  const auto sphere = DirectionBinning::sphere(21);
  const auto lobe = DirectionBinning::lobe(GGX<double>(0.2, 0.6), direction_from_degrees(50.0, 30.0),
                                           SampleDomain::microfacet_normal, 15);
  for (const DirectionBinning* b : {&sphere, &lobe}) {
    for (int i = 0; i < 20000; ++i) {
      const Vec3<double> w = random_direction(rng);
      const auto u = b->to_param(w);
      const auto bin = b->bin_of(w);
      ASSERT_EQ(u.has_value(), bin.has_value());
      if (!bin) {
        EXPECT_EQ(b->kind(), BinningKind::lobe);
        continue;
      }
      ASSERT_GE(*bin, 0);
      ASSERT_LT(*bin, b->size());
      const BinBounds bb = b->bounds(*bin);
      const double theta = std::acos(u->z()) * 180 / kPi<double>;
      double phi = std::atan2(u->y(), u->x()) * 180 / kPi<double>;
      if (phi < 0) phi += 360;
      EXPECT_GE(theta, bb.theta_min_deg - 1e-9);
      EXPECT_LE(theta, bb.theta_max_deg + 1e-9);
      EXPECT_GE(phi, bb.phi_min_deg - 1e-9);
      EXPECT_LE(phi, bb.phi_max_deg + 1e-9);
      EXPECT_GE(b->center_theta_deg(*bin), bb.theta_min_deg);
      EXPECT_LE(b->center_theta_deg(*bin), bb.theta_max_deg);
    }
  }
  // The pole has phi = 0 by convention; non-finite and zero directions have no bin.
  EXPECT_EQ(sphere.bin_of(Vec3<double>(0, 0, 1)), 0);
  EXPECT_EQ(sphere.bin_of(Vec3<double>(0, 0, -1)), (sphere.rows() - 1) * sphere.cols());
  EXPECT_FALSE(sphere.bin_of(Vec3<double>(0, 0, 0)).has_value());
  EXPECT_FALSE(sphere.bin_of(Vec3<double>(std::nan(""), 0, 1)).has_value());
  // Lobe bins of a front view have no bin for normals on the lower side.
  EXPECT_FALSE(lobe.bin_of(Vec3<double>(0, 0.6, -0.8)).has_value());
}

TEST(DirectionBinning, BinsHaveEqualArea) {
  // A constant density over the parameter space gives every bin the same probability.
  const auto sphere = DirectionBinning::sphere(15);
  const auto p = sphere.integrate([](const Vec3<double>&) { return 1 / (4 * kPi<double>); });
  for (double x : p) EXPECT_NEAR(x, 1.0 / sphere.size(), 1e-12);
  // Lobe bins are equal-area in parameter space: the pdf 1 / (2 pi |dw/du|) is uniform there.
  const auto lobe = DirectionBinning::lobe(GGX<double>(0.1, 0.4), direction_from_degrees(40.0, 10.0),
                                           SampleDomain::microfacet_normal, 9);
  const auto q = lobe.integrate([&](const Vec3<double>& m) {
    const auto u = lobe.to_param(m);
    return u ? 1 / (2 * kPi<double> * lobe.jacobian(*u)) : 0.0;
  });
  for (double x : q) EXPECT_NEAR(x, 1.0 / lobe.size(), 1e-9);
}

TEST(DirectionBinning, LobeMapRoundTripsAndJacobianMatchesFiniteDifferences) {
  std::mt19937_64 rng(5);
  const GGX<double> ggx(0.05, 0.3);
  for (SampleDomain domain : {SampleDomain::microfacet_normal, SampleDomain::reflected_direction}) {
    for (double theta : {0.0, 45.0, 85.0, 120.0}) {  // 120: a back-side view (lower parameter space)
      const Vec3<double> wi = direction_from_degrees(theta, 25.0);
      const auto lobe = DirectionBinning::lobe(ggx, wi, domain, 11);
      EXPECT_EQ(lobe.z_max(), theta > 90 ? 0.0 : 1.0);
      for (int i = 0; i < 200; ++i) {
        Vec3<double> u = random_direction(rng);
        if ((u.z() > 0) != (theta < 90)) u.z() = -u.z();
        if (std::abs(u.z()) < 0.05) continue;
        if (domain == SampleDomain::reflected_direction) {
          // Only u whose m faces wi are images of reflected directions; the others have measure 0.
          const Vec3<double> mm = Vec3<double>(ggx.alpha_x() * u.x(), ggx.alpha_y() * u.y(), u.z()).normalized();
          if (wi.dot(mm) <= 0) {
            EXPECT_EQ(lobe.jacobian(u), 0.0);
          }
          if (wi.dot(mm) <= 0.05) continue;
        }
        const Vec3<double> w = lobe.from_param(u);
        const auto back = lobe.to_param(w);
        ASSERT_TRUE(back.has_value());
        EXPECT_LT((*back - u).norm(), 1e-9);
        // Solid-angle ratio of a small triangle around u and its image.
        Vec3<double> t1, t2;
        orthonormal_basis(u, t1, t2);
        const double h = 1e-5;
        const Vec3<double> a = (u + h * t1).normalized(), b = (u + h * t2).normalized();
        const double area_u = (a - u).cross(b - u).norm();
        const Vec3<double> wa = lobe.from_param(a), wb = lobe.from_param(b);
        const double area_w = (wa - w).cross(wb - w).norm();
        EXPECT_NEAR(area_w / area_u, lobe.jacobian(u), 1e-3 * lobe.jacobian(u));
      }
    }
  }
}

// The sum of the bin probabilities of the VNDF (and of the VNDF reflection pdf) is 1 to 1e-6 in both
// parameterizations over alpha 1e-3..2 (and anisotropic pairs) and theta 0..89 degrees. The azimuth
// 20 degrees puts the reflected peaks inside bins rather than on their edges. One test per roughness.
class VndfBinSums : public ::testing::TestWithParam<std::pair<double, double>> {};

TEST_P(VndfBinSums, SumToOne) {
  const auto [ax, ay] = GetParam();
  const GGX<double> ggx(ax, ay);
  for (double theta : {0.0, 30.0, 60.0, 80.0, 89.0}) {
    const Vec3<double> wi = direction_from_degrees(theta, 20.0);
    for (SampleDomain domain : {SampleDomain::microfacet_normal, SampleDomain::reflected_direction}) {
      auto pdf = [&](const Vec3<double>& w) {
        return domain == SampleDomain::microfacet_normal ? ggx.visible_normal_pdf(wi, w)
                                                         : ggx.visible_reflection_pdf(wi, w);
      };
      const auto sphere = DirectionBinning::sphere(31).integrate(pdf, lobe_focus(ggx, wi, domain, true));
      const auto lobe = DirectionBinning::lobe(ggx, wi, domain, 31).integrate(pdf, lobe_focus(ggx, wi, domain, false));
      const std::string where = "alpha=(" + std::to_string(ax) + "," + std::to_string(ay) +
                                ") theta=" + std::to_string(theta) + " domain=" + to_string(domain);
      EXPECT_NEAR(sphere.total, 1.0, 1e-6) << where;
      EXPECT_NEAR(lobe.total, 1.0, 1e-6) << where;
      for (double p : sphere.probability) ASSERT_GE(p, 0.0) << where;
      for (double p : lobe.probability) ASSERT_GE(p, 0.0) << where;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Roughness, VndfBinSums,
                         ::testing::Values(std::pair{1e-3, 1e-3}, std::pair{0.05, 0.05}, std::pair{0.3, 0.3},
                                           std::pair{1.0, 1.0}, std::pair{2.0, 2.0}, std::pair{1e-3, 0.3},
                                           std::pair{0.5, 0.05}));

// The NDF pdf D(m) m.z, whose whole mass sits inside the polar sphere bins at alpha = 1e-3, also sums to 1.
TEST(DirectionBinning, NarrowNdfSumsToOne) {
  for (double alpha : {1e-3, 1e-2}) {
    const GGX<double> ggx(alpha);
    const Vec3<double> wi(0, 0, 1);
    auto pdf = [&](const Vec3<double>& m) { return ggx.D(m) * std::max(m.z(), 0.0); };
    const auto r = DirectionBinning::sphere(31).integrate(pdf, lobe_focus(ggx, wi, SampleDomain::microfacet_normal, true));
    EXPECT_NEAR(r.total, 1.0, 1e-6);
  }
}

TEST(DirectionBinning, DescriptionRoundTrips) {
  std::mt19937_64 rng(3);
  const auto a = DirectionBinning::lobe(GGX<double>(0.02, 0.7), direction_from_degrees(70.0, 200.0),
                                        SampleDomain::reflected_direction, 13);
  const auto s = DirectionBinning::sphere(7);
  for (const DirectionBinning* b : {&a, &s}) {
    const nlohmann::json d = nlohmann::json::parse(b->describe().dump());
    const auto c = DirectionBinning::from_description(d);
    EXPECT_EQ(c.kind(), b->kind());
    EXPECT_EQ(c.size(), b->size());
    for (int i = 0; i < 5000; ++i) {
      const Vec3<double> w = random_direction(rng);
      EXPECT_EQ(c.bin_of(w), b->bin_of(w));
    }
  }
  EXPECT_THROW(DirectionBinning::from_description(nlohmann::json{{"kind", "cube"}, {"rows", 3}}), std::invalid_argument);
  EXPECT_THROW(DirectionBinning::from_description(nlohmann::json{{"kind", "sphere"}}), std::invalid_argument);
  EXPECT_THROW(DirectionBinning::from_description(nlohmann::json{{"kind", "sphere"}, {"rows", 3}, {"cols", 5}}),
               std::invalid_argument);
}

}  // namespace test_binning
