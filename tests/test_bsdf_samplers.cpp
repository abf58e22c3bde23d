// The BSDF samplers of the zoo (microfacet/bsdf_samplers.h) and their validation (validate/bsdf_validation.h):
// the correct samplers pass the whole battery from both sides, each negative control is rejected by the
// weight test wherever its bug has an effect, and the weight test alone passes a bug that has none.
// Fixed seeds, 1e6 samples, each validation at the family-wise level 0.01; a rejection must reach
// p < 1e-6 in a weight test (the --all threshold of negative controls).
#include "microfacet/bsdf.h"
#include "validate/bsdf_validation.h"

#include <gtest/gtest.h>

namespace microsim {
namespace {

struct View {
  double alpha, theta;
  bool inside;
};

ValidationReport validate(std::string_view name, const View& v) {
  const BsdfSamplerInfo& s = *find_bsdf_sampler(name);
  ValidationOptions o;
  o.seed = 11;
  return validate_bsdf_sampler(s, zoo_bsdf_material(s, v.inside), GGX<double>(v.alpha, v.alpha),
                               direction_from_degrees(v.theta, 0.0), o);
}

double weight_p(const ValidationReport& r) {
  return std::min(r.check("bsdf_albedo").p_value, r.check("bsdf_bins").p_value);
}

TEST(BsdfSamplers, CorrectSamplersPassTheWholeBatteryFromBothSides) {
  const View views[] = {{0.3, 60, false}, {0.05, 89, false}, {0.3, 30, true}};
  for (const View& v : views)
    for (std::string_view name : {"conductor_vndf", "dielectric_vndf"}) {
      if (v.inside && name == "conductor_vndf") continue;
      const ValidationReport r = validate(name, v);
      EXPECT_TRUE(r.passed) << name << " alpha " << v.alpha << " theta " << v.theta << " inside " << v.inside << ": "
                            << (r.failures.empty() ? "" : r.failures.front());
      EXPECT_TRUE(r.check("bsdf_albedo").applicable && r.check("bsdf_bins").applicable);
    }
}

TEST(BsdfSamplers, EachNegativeControlIsRejectedByTheWeightTest) {
  const struct {
    std::string_view name;
    View view;
  } cases[] = {{"cond_no_g1_wo", {0.05, 60, false}}, {"cond_alpha_sq", {2.0, 60, false}},
               {"diel_wrong_jac", {0.3, 30, true}},  {"diel_no_eta2", {0.05, 0, false}},
               {"diel_no_eta2", {0.3, 60, true}}};
  for (const auto& c : cases) {
    const BsdfSamplerInfo& s = *find_bsdf_sampler(c.name);
    ASSERT_TRUE(s.negative_control);
    const Material m = zoo_bsdf_material(s, c.view.inside);
    const GGX<double> g(c.view.alpha, c.view.alpha);
    const Vec3<double> wi = direction_from_degrees(c.view.theta, 0.0);
    const std::complex<double> eta = sampler_index(m);
    ASSERT_TRUE(!s.bug_has_effect || s.bug_has_effect(g, eta, wi, 1'000'000)) << c.name;
    const ValidationReport r = validate(c.name, c.view);
    EXPECT_FALSE(r.passed) << c.name;
    EXPECT_LT(weight_p(r), 1e-6) << c.name << " alpha " << c.view.alpha << " theta " << c.view.theta;
  }
}

// Where a bug changes nothing, nothing rejects it: the roughness squared at alpha = 1, and the refraction
// weight seen from inside beyond the critical angle at alpha 1e-3 (every visible normal reflects totally).
TEST(BsdfSamplers, ABugWithoutEffectPassesAndIsSaidToHaveNone) {
  const struct {
    std::string_view name;
    View view;
  } cases[] = {{"cond_alpha_sq", {1.0, 60, false}}, {"diel_no_eta2", {1e-3, 60, true}}};
  for (const auto& c : cases) {
    const BsdfSamplerInfo& s = *find_bsdf_sampler(c.name);
    const Material m = zoo_bsdf_material(s, c.view.inside);
    const std::complex<double> eta = sampler_index(m);
    EXPECT_FALSE(s.bug_has_effect(GGX<double>(c.view.alpha, c.view.alpha), eta, direction_from_degrees(c.view.theta, 0.0), 1'000'000));
    EXPECT_TRUE(validate(c.name, c.view).passed) << c.name;
  }
}

// The claimed pdfs integrate to what the samplers keep: 1 less the lost samples (cubature of the reference
// against the sampled fraction), and the effect predicate of a weight bug is the shift of the mean weight.
TEST(BsdfSamplers, ClaimedDensityHoldsTheSamplesThatAreKept) {
  const GGX<double> g(0.3, 0.3);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  const BsdfSamplerInfo& s = *find_bsdf_sampler("dielectric_vndf");
  std::uint64_t kept = 0, refracted = 0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const Vec3<double> u((i + 0.5) / n, std::fmod(i * 0.6180339887498949, 1.0), std::fmod(i * 0.7548776662466927, 1.0));
    if (const auto r = s.sample(g, kZooDielectricEta, wi, u)) {
      ++kept;
      refracted += r->wo.z() < 0;
    }
  }
  const auto ref = density_reference(bsdf_sampling_density(Material::dielectric(kZooDielectricEta), g, wi), g, wi, 31);
  EXPECT_NEAR(ref->sphere_probability.total, double(kept) / n, 3e-3);
  EXPECT_GT(refracted, n / 2);
  const BsdfSamplerInfo& bug = *find_bsdf_sampler("diel_no_eta2");
  // From outside, the refraction weights are off by 1 / eta^2: seen at 1e6 samples, not by one.
  EXPECT_GT(mean_weight_shift_z(bug.sample, s.sample, g, kZooDielectricEta, wi, 1'000'000), 100);
  EXPECT_LT(mean_weight_shift_z(bug.sample, s.sample, g, kZooDielectricEta, wi, 1), 6);
  // From inside beyond the critical angle at alpha 1e-3 nothing refracts: no shift at all.
  EXPECT_EQ(mean_weight_shift_z(bug.sample, s.sample, GGX<double>(1e-3, 1e-3), 1 / kZooDielectricEta, wi, 1'000'000), 0);
}

}  // namespace
}  // namespace microsim
