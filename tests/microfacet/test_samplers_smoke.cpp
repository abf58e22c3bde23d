// Smoke checks of every registered sampler: returned pdf equals the claimed analytic pdf at a few
// views (the full statistical validation lives in the validator tests).
#include "microfacet/samplers.h"

#include <gtest/gtest.h>

#include <random>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_samplers_smoke {

using namespace microsim;

TEST(SamplerRegistry, ReturnedPdfMatchesClaimedPdf) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (const SamplerInfo& s : sampler_registry()) {
    if (s.negative_control) continue;
    for (double alpha : {0.05, 0.3, 1.0, 2.0}) {
      for (double theta : {0.0, 30.0, 60.0, 89.0}) {
        const GGX<double> ggx(alpha, alpha * 0.7);
        const Vec3<double> wi = direction_from_degrees(theta, 20.0);
        for (int i = 0; i < 200; ++i) {
          const auto r = s.sample_double(ggx, wi, Vec2<double>(uni(rng), uni(rng)));
          ASSERT_TRUE(r.has_value()) << s.name;
          const double claimed = s.claimed_pdf(ggx, wi, r->direction);
          EXPECT_NEAR(r->pdf, claimed, 1e-7 * std::max(1.0, claimed))
              << s.name << " alpha=" << alpha << " theta=" << theta;
          EXPECT_NEAR(r->direction.norm(), 1.0, 1e-12);
        }
      }
    }
  }
}

}  // namespace test_samplers_smoke
