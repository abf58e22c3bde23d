// "Ellipsoid facets": normals over uniform footprint points of the GGX ellipsoid (Heitz 2018, sec. 2)
// have the GGX distribution D(m) m.z exactly. Chi-square goodness of fit in sphere and lobe bins (fixed
// seed, level 0.01, Sidak over the two binnings), a negative control (the same normals against D_v at
// 60 degrees are rejected), and the median slope magnitude equal to alpha (isotropic).
#include "microgeom/ellipsoid.h"
#include "stats/chi2.h"
#include "core/random.h"
#include "validate/validate.h"

#include <gtest/gtest.h>

#include <algorithm>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_ellipsoid_facets {

using namespace microsim;

namespace {

std::vector<Vec3<double>> facet_normals(double ax, double ay, int n, std::uint64_t seed) {
  const microgeom::Ellipsoid e{ax, ay};
  std::vector<Vec3<double>> normals;
  for (int i = 0; i < n; ++i) {
    CounterRng rng(seed, std::uint64_t(i));
    const double u1 = rng.uniform(), u2 = rng.uniform();
    // Both routes to a facet: the closed-form normal, and the gradient at the surface point above a
    // uniform footprint point (same u): they must agree.
    const Vec3<double> m = e.sample_facet_normal(u1, u2);
    const Eigen::Vector2d p = e.footprint_point(u1, u2);
    const Vec3<double> g = e.normal_at(e.point_over(p.x(), p.y()));
    EXPECT_NEAR((m - g).norm(), 0.0, 1e-9) << i;
    normals.push_back(m);
  }
  return normals;
}

double chi2_p(const std::vector<Vec3<double>>& normals, const ReferenceDistribution& ref) {
  double p_min = 1;
  for (const auto* pair : {&ref.sphere, &ref.lobe}) {
    const DirectionBinning& b = *pair;
    const BinIntegrals& bi = pair == &ref.sphere ? ref.sphere_probability : ref.lobe_probability;
    std::vector<double> observed(std::size_t(b.size()) + 1, 0.0);
    for (const auto& m : normals) {
      const auto bin = b.bin_of(m);
      observed[bin ? std::size_t(*bin) : observed.size() - 1] += 1;
    }
    std::vector<double> expected = bi.probability;
    expected.push_back(std::max(0.0, 1.0 - bi.total));
    p_min = std::min(p_min, goodness_of_fit(observed, expected, double(normals.size())).p_value);
  }
  return sidak_adjusted_p(p_min, 2);
}

}  // namespace

TEST(EllipsoidFacets, NormalsFollowGgxNdf) {
  for (const auto& [ax, ay] : {std::pair{0.05, 0.05}, std::pair{0.5, 0.5}, std::pair{0.1, 0.8}}) {
    const GGX<double> ggx(ax, ay);
    const Vec3<double> up(0, 0, 1);
    const auto normals = facet_normals(ax, ay, 200'000, 31);
    // D(m) m.z is the VNDF seen from the zenith: D_v(z, m) = 2 D(m) m.z / (1 + 1) = D(m) m.z.
    const auto ndf = prepare_reference([&](const Vec3<double>& m) { return ggx.D(m) * std::max(m.z(), 0.0); },
                                       SampleDomain::microfacet_normal, ggx, up, 15);
    const double p = chi2_p(normals, *ndf);
    EXPECT_GT(p, 0.01) << ax << "," << ay;
    // Negative control: the same normals are not the VNDF of a 60-degree view.
    const auto vndf60 = vndf_reference(SampleDomain::microfacet_normal, ggx, direction_from_degrees(60.0, 0.0), 15);
    EXPECT_LT(chi2_p(normals, *vndf60), 1e-6) << ax << "," << ay;
  }
}

TEST(EllipsoidFacets, MedianSlopeIsAlpha) {
  // Isotropic GGX slopes: |s| has CDF r^2 / (alpha^2 + r^2), median alpha. With 200k samples the
  // sample median's standard error is about alpha * 0.0045: test within 2%.
  for (double alpha : {0.01, 0.3, 2.0}) {
    auto normals = facet_normals(alpha, alpha, 200'000, 5);
    std::vector<double> slopes;
    for (const auto& m : normals) slopes.push_back(std::hypot(m.x(), m.y()) / m.z());
    std::nth_element(slopes.begin(), slopes.begin() + slopes.size() / 2, slopes.end());
    EXPECT_NEAR(slopes[slopes.size() / 2] / alpha, 1.0, 0.02) << alpha;
  }
}

}  // namespace test_ellipsoid_facets
