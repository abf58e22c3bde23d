// Tests of the surface statistics (microgeom/surface_stats.h): reference laws, the tolerance, and the
// measured quantities on surfaces whose answer is known.
#include "microgeom/assembly.h"
#include "microgeom/surface_stats.h"

#include "microfacet/ggx.h"

#include <gtest/gtest.h>

#include <cmath>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_surface_stats {

using namespace microgeom;

TEST(SurfaceStats, ReferenceRadiusLawsAreConsistent) {
  for (NdfKind ref : {NdfKind::ggx, NdfKind::beckmann})
    for (double q : {1e-4, 0.01, 0.25, 0.5, 0.9, 0.999, 0.999999})
      EXPECT_NEAR(reference_radius_cdf(ref, reference_radius_quantile(ref, q)), q, 1e-12);
  EXPECT_DOUBLE_EQ(reference_radius_quantile(NdfKind::ggx, 0.5), 1.0);  // median slope = alpha
  EXPECT_NEAR(reference_radius_quantile(NdfKind::beckmann, 1 - std::exp(-1.0)), 1.0, 1e-12);
  EXPECT_EQ(reference_radius_cdf(NdfKind::ggx, 0.0), 0.0);
  EXPECT_EQ(reference_radius_cdf(NdfKind::ggx, -1.0), 0.0);
  EXPECT_EQ(reference_radius_quantile(NdfKind::ggx, 0.0), 0.0);
  EXPECT_TRUE(std::isinf(reference_radius_quantile(NdfKind::ggx, 1.0)));
  // The GGX radius law is that of P22 (microsim::GGX::slope_pdf): d/dR of the CDF = 2 pi R P22(R).
  const microsim::GGX<double> ggx(1.0);
  for (double r : {0.1, 0.7, 1.0, 3.0, 20.0}) {
    const double h = 1e-6 * r;
    const double pdf = (reference_radius_cdf(NdfKind::ggx, r + h) - reference_radius_cdf(NdfKind::ggx, r - h)) / (2 * h);
    EXPECT_NEAR(pdf, 2 * M_PI * r * ggx.slope_pdf(r, 0.0), 1e-6 * pdf);
  }
}

TEST(SurfaceStats, ToleranceWidensWithFewerPatchesOnlyWhereStated) {
  const NdfTolerance fixed;
  const NdfTolerance big = tolerance_for(NdfKind::ggx, 4096, 16);
  EXPECT_EQ(big.quantile, fixed.quantile);
  EXPECT_EQ(big.radius_bin, fixed.radius_bin);
  EXPECT_NEAR(big.angular_bin, std::max(fixed.angular_bin, kAngularNoiseFactor * std::sqrt(kAngularBins / 65536.0)), 1e-15);
  const NdfTolerance small = tolerance_for(NdfKind::ggx, 256, 16);
  EXPECT_GT(small.angular_bin, big.angular_bin);
  const NdfTolerance beck = tolerance_for(NdfKind::beckmann, 1024, 16);
  EXPECT_NEAR(beck.quantile, kBeckmannQuantileNoiseFactor / 64.0, 1e-15);
  EXPECT_GT(beck.radius_bin, fixed.radius_bin);
}

TEST(SurfaceStats, FlatSurfaceGivesFiniteNumbersNotNaN) {
  const Heightfield flat(16, 1.0, std::vector<float>(256, 0.25f));
  const SurfaceStats st = measure_surface(flat, {});
  EXPECT_EQ(st.fitted_alpha_x, 0.0);
  EXPECT_FALSE(st.ndf_within_tolerance);  // a flat plane is not GGX
  for (double v : {st.max_quantile_error, st.max_radius_bin_error, st.max_angular_bin_error, st.height_sd,
                   st.height_skewness, st.height_excess_kurtosis, st.spearman_height_slope,
                   st.spearman_extremity_slope, st.steepest_1pct_height_z})
    EXPECT_TRUE(std::isfinite(v));
  EXPECT_EQ(st.height_mean, 0.25);
}

TEST(SurfaceStats, KnownSurfaceQuantities) {
  // A periodic ramp-and-cliff in x only: heights i (mod N) * c. Every triangle slope is (c/h, 0) except the
  // wrap column, where it is -(N-1) c / h; the y slopes are 0. The upper triangles of row j share edges.
  const int n = 32;
  std::vector<float> h(n * n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) h[j * n + i] = float(i) * 0.01f;
  const Heightfield f(n, 1.0, h);
  StatsOptions o;
  o.alpha_x = o.alpha_y = 1.0;
  const SurfaceStats st = measure_surface(f, o);
  const double cell = 1.0 / n, s = 0.01 / cell;
  EXPECT_NEAR(st.mean_slope_x, 0.0, 1e-6);  // periodic: slopes sum to zero
  EXPECT_NEAR(st.rms_slope_x, std::sqrt(((n - 1) * s * s + std::pow((n - 1) * s, 2)) / n), 1e-4);
  EXPECT_EQ(st.rms_slope_y, 0.0);
  EXPECT_NEAR(st.fitted_alpha_x, std::sqrt(3.0) * s, 1e-5);  // the median |slope| is s
  EXPECT_NEAR(st.height_mean, 0.01 * (n - 1) / 2.0, 1e-6);
  EXPECT_NEAR(st.height_min, 0.0, 0.0);
  EXPECT_NEAR(st.height_max, 0.31, 1e-6);
  // The steepest facets are the wrap cliff, at the mean height; the rest have equal radius (ties by index).
  EXPECT_NEAR(st.max_normalised_radius, (n - 1) * s, 1e-4);
}

TEST(SurfaceStats, HeightSlopeCorrelationDetectsSteepLowFacets) {
  // Heights: a periodic landscape whose slope grows as height falls (|sin| pits): z = -|sin(pi x / L)|^(1/2)
  // gives the steepest facets at the lowest points.
  const int n = 64;
  std::vector<float> h(n * n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i)
      h[j * n + i] = float(std::sqrt(std::fabs(std::sin(M_PI * (i + 0.5) / n))) +
                           std::sqrt(std::fabs(std::sin(M_PI * (j + 0.5) / n))));
  const SurfaceStats st = measure_surface(Heightfield(n, 1.0, h), {});
  EXPECT_LT(st.spearman_height_slope, -0.5);
  EXPECT_LT(st.steepest_1pct_height_z, -1.0);
}

}  // namespace test_surface_stats
