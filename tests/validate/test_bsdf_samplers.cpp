// The BSDF samplers of the zoo (microfacet/bsdf_samplers.h) and their validation (validate/bsdf_validation.h):
// the correct samplers pass the whole battery from both sides, each negative control is rejected by the
// weight test wherever its bug has an effect, and the weight test alone passes a bug that has none.
// Fixed seeds, 1e6 samples, each validation at the family-wise level 0.01; a rejection must reach
// p < 1e-6 in a weight test (the --all threshold of negative controls).
#include "measure/validate_all.h"
#include "measure/validation.h"
#include "microfacet/bsdf.h"
#include "stats/chi2.h"
#include "validate/bsdf_validation.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <optional>
#include <utility>
#include <string>

namespace microsim {
namespace {

struct View {
  double alpha, theta;
  bool inside;
};

// The sampler's weights tested in `mode` (its own transport mode unless given).
ValidationReport validate(std::string_view name, const View& v, std::optional<TransportMode> mode = std::nullopt) {
  const BsdfSamplerInfo& s = *find_bsdf_sampler(name);
  ValidationOptions o;
  o.seed = 11;
  o.convention = s.convention;
  if (mode) o.convention.transport = *mode;
  return validate_bsdf_sampler(s, zoo_bsdf_material(s, v.inside), GGX<double>(v.alpha, v.alpha),
                               direction_from_degrees(v.theta, 0.0), o);
}

double weight_p(const ValidationReport& r) {
  return std::min(r.check("bsdf_albedo").p_value, r.check("bsdf_bins").p_value);
}

TEST(BsdfSamplers, CorrectSamplersPassTheWholeBatteryFromBothSides) {
  const View views[] = {{0.3, 60, false}, {0.05, 89, false}, {0.3, 30, true}};
  for (const View& v : views)
    for (std::string_view name : {"conductor_vndf", "dielectric_vndf", "dielectric_vndf_importance"}) {
      if (v.inside && name == "conductor_vndf") continue;
      const ValidationReport r = validate(name, v);
      EXPECT_TRUE(r.passed) << name << " alpha " << v.alpha << " theta " << v.theta << " inside " << v.inside << ": "
                            << (r.failures.empty() ? "" : r.failures.front());
      EXPECT_TRUE(r.check("bsdf_albedo").applicable && r.check("bsdf_bins").applicable);
    }
}

// Two views off the --all grid (the grid itself: EveryNegativeControlIsRejectedByTheWeightTestOnTheWholeAllGrid),
// at the stricter p < 1e-6 of --all's negative controls.
TEST(BsdfSamplers, EachNegativeControlIsRejectedByTheWeightTest) {
  const struct {
    std::string_view name;
    View view;
  } cases[] = {{"cond_alpha_sq", {2.0, 60, false}},  // off the --all grid
               {"diel_wrong_jac", {0.3, 30, true}},
               {"diel_eta2_twice", {0.3, 30, true}},
               {"diel_eta2_reflect", {0.3, 45, false}},
               {"diel_g1_for_g2", {0.6, 70, false}}};
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

// Every negative control at every view of the --all grid where its bug has an effect --all's default budget
// (200000 samples per validation) can see (bug_has_effect) is rejected by a weight test (albedo or flux per bin)
// with p below --all's threshold for negative controls (kNegativeControlP), whatever the directions.
TEST(BsdfSamplers, EveryNegativeControlIsRejectedByTheWeightTestOnTheWholeAllGrid) {
  constexpr std::uint64_t kSamples = 200'000;
  std::map<std::string, BsdfReference> references;  // by view and material, as --all shares them
  int rejected = 0;
  for (const BsdfValidationCase& c : bsdf_zoo_cases(1)) {
    if (!c.sampler->negative_control || !c.expects_rejection(kSamples)) continue;
    const std::string key =
        fmt::format("{} {} {} {}", c.alpha, c.theta_deg, c.material().describe(), describe(c.sampler->convention));
    if (!references.count(key)) references[key] = bsdf_reference(c.material(), c.sampler->convention, c.ggx(), c.wi(), 31);
    ValidationOptions o;
    o.samples = kSamples;
    o.seed = c.seed;
    o.convention = c.sampler->convention;
    const ValidationReport r = validate_bsdf_sampler(*c.sampler, c.material(), c.ggx(), c.wi(), o, &references[key]);
    EXPECT_LT(weight_p(r), kNegativeControlP)
        << c.sampler->name << " alpha " << c.alpha << " theta " << c.theta_deg << (c.inside ? " inside" : " outside");
    ++rejected;
  }
  EXPECT_GE(rejected, 75) << "the grid's controls with an effect";
}

// Where a bug changes nothing, nothing rejects it: the roughness squared at alpha = 1, and the refraction
// weight seen from inside beyond the critical angle at alpha 1e-3 (every visible normal reflects totally).
TEST(BsdfSamplers, ABugWithoutEffectPassesAndIsSaidToHaveNone) {
  const struct {
    std::string_view name;
    View view;
  } cases[] = {{"cond_alpha_sq", {1.0, 60, false}}, {"diel_eta2_twice", {1e-3, 60, true}}};
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
  const BsdfSamplerInfo& bug = *find_bsdf_sampler("diel_eta2_twice");
  // From outside, the refraction weights are off by 1 / eta^2: seen at 1e6 samples, not by one.
  EXPECT_GT(mean_weight_shift_z(bug.sample, s.sample, g, kZooDielectricEta, wi, 1'000'000), 100);
  EXPECT_LT(mean_weight_shift_z(bug.sample, s.sample, g, kZooDielectricEta, wi, 1), 6);
  // From inside beyond the critical angle at alpha 1e-3 nothing refracts: no shift at all.
  EXPECT_EQ(mean_weight_shift_z(bug.sample, s.sample, GGX<double>(1e-3, 1e-3), 1 / kZooDielectricEta, wi, 1'000'000), 0);
}

// Transport modes (bsdf_convention.h): each correct dielectric sampler passes in its own mode and is rejected by
// the weight test in the other (a refraction's weight differs by eta^2), from outside and from inside, while
// its directions pass (they do not depend on the mode). A conductor is the same in both modes.
TEST(BsdfSamplers, EachTransportModesCorrectSamplerIsRejectedInTheOtherMode) {
  for (const View v : {View{0.3, 30, false}, View{0.3, 30, true}})
    for (const auto& [name, other] : {std::pair{"dielectric_vndf", TransportMode::importance},
                                      std::pair{"dielectric_vndf_importance", TransportMode::radiance}}) {
      EXPECT_TRUE(validate(name, v).passed) << name << " inside " << v.inside;
      const ValidationReport r = validate(name, v, other);
      EXPECT_FALSE(r.passed) << name << " inside " << v.inside;
      EXPECT_LT(weight_p(r), 1e-6) << name << " inside " << v.inside;
      EXPECT_GT(r.chi2("sphere").p_value, 1e-3) << name << ": the directions do not depend on the mode";
    }
  EXPECT_TRUE(validate("conductor_vndf", {0.3, 60, false}, TransportMode::importance).passed);
}

// The radiance convention is the importance one with the light's direction reversed: f_radiance(wg, ws) =
// f_importance(ws, wg), so a refraction's f differs by (n_g / n_s)^2 and a reflection's not at all.
TEST(BsdfSamplers, RadianceIsImportanceWithTheDirectionsSwapped) {
  const GGX<double> g(0.4, 0.2);
  const Vec3<double> wi = direction_from_degrees(40.0, 20.0);
  const BsdfConvention radiance{TransportMode::radiance, MaskingForm::height_correlated};
  const BsdfConvention importance{TransportMode::importance, MaskingForm::height_correlated};
  const Vec3<double> refracted = direction_from_degrees(150.0, 200.0), reflected = direction_from_degrees(50.0, 190.0);
  for (const double eta : {1.5, 1 / 1.5}) {
    const double fr = dielectric_bsdf_as(g, eta, wi, refracted, radiance);
    const double fi = dielectric_bsdf_as(g, eta, wi, refracted, importance);
    ASSERT_GT(fi, 0);
    EXPECT_NEAR(fr / fi, 1 / (eta * eta), 1e-12) << eta;
    EXPECT_DOUBLE_EQ(dielectric_bsdf_as(g, eta, wi, reflected, radiance), dielectric_bsdf_as(g, eta, wi, reflected, importance));
  }
}

}  // namespace
}  // namespace microsim
