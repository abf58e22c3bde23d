// The weight test of a BSDF sampler's dump (validate/weight_test.h): a conductor
// sampler's reflections with the weight f cos / pdf pass against the BSDF; the same directions with the
// weights of the bugs renderers really had are rejected, at level 0.01 (Sidak over the validation's tests).
#include "core/random.h"
#include "microfacet/bsdf.h"
#include "microfacet/samplers.h"
#include "validate/validate.h"
#include "validate/weight_test.h"

#include <gtest/gtest.h>
#include <fmt/core.h>

#include <complex>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <unistd.h>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_weight_test {

using namespace microsim;
namespace fs = std::filesystem;

namespace {

const std::vector<std::complex<double>> kGold = {{0.18, 3.42}, {0.42, 2.35}, {1.37, 1.77}};

// A dump of n reflections of heitz2018 normals seen from wi: x y z and one weight per channel, from
// weight(channel, m, wo); below the horizon the weight is 0 (the sample kept, as a sampler that fails).
using WeightOf = std::function<double(int, const Vec3<double>&, const Vec3<double>&)>;
fs::path write_dump(const std::string& name, const GGX<double>& ggx, const Vec3<double>& wi, int n, const WeightOf& weight) {
  const fs::path p = fs::temp_directory_path() / fmt::format("microsim_weight_test_{}_{}.txt", ::getpid(), name);
  std::ofstream out(p);
  for (int i = 0; i < n; ++i) {
    CounterRng rng(77, std::uint64_t(i));
    const auto s = sample_heitz2018<double>(ggx, wi, Vec2<double>(rng.uniform(), rng.uniform()));
    if (!s) continue;
    const Vec3<double> wo = reflect(wi, s->direction).normalized();
    out << fmt::format("{:.17g} {:.17g} {:.17g}", wo.x(), wo.y(), wo.z());
    for (int c = 0; c < 3; ++c) out << fmt::format(" {:.17g}", wo.z() > 0 ? weight(c, s->direction, wo) : 0.0);
    out << "\n";
  }
  return p;
}

ValidationReport validate_dump(const fs::path& p, const GGX<double>& ggx, const Vec3<double>& wi) {
  ValidationOptions o;
  o.bsdf = Material::conductor(kGold);
  DirectionSampleReader reader(p, SampleColumns::parse("x,y,z,weight,weight,weight"));
  const ClaimedDensity d = claimed_density(FilePdf::reflection, ggx, wi);
  return validate_sample_file(reader, d.domain, ggx, wi, o, density_reference(d, ggx, wi, o.rows));
}

// The validation of a dump of 2e5 samples with these weights (the dump removed after).
ValidationReport validate_weights(const std::string& name, const GGX<double>& ggx, const Vec3<double>& wi,
                                  const WeightOf& weight) {
  const fs::path p = write_dump(name, ggx, wi, 200'000, weight);
  ValidationReport r = validate_dump(p, ggx, wi);
  fs::remove(p);
  return r;
}

}  // namespace

TEST(BsdfWeights, ACorrectConductorSamplerPassesAndRenderersBugsAreRejected) {
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  const GGX<double> squared(0.09);  // the roughness squared twice
  const std::map<std::string, WeightOf> weights = {
      // f cos / pdf of VNDF sampling: F(<wi, m>) G2(wi, wo) / G1(wi)
      {"correct", [&](int c, const Vec3<double>& m, const Vec3<double>& wo) {
         return fresnel_conductor(wi.dot(m), kGold[std::size_t(c)]) * ggx.G2(wi, wo) / ggx.G1(wi); }},
      {"no_g1_wo", [&](int c, const Vec3<double>& m, const Vec3<double>&) {
         return fresnel_conductor(wi.dot(m), kGold[std::size_t(c)]); }},
      {"fresnel_at_cos_o", [&](int c, const Vec3<double>&, const Vec3<double>& wo) {
         return fresnel_conductor(wo.z(), kGold[std::size_t(c)]) * ggx.G2(wi, wo) / ggx.G1(wi); }},
      {"alpha_squared", [&](int c, const Vec3<double>& m, const Vec3<double>& wo) {
         return fresnel_conductor(wi.dot(m), kGold[std::size_t(c)]) * squared.G2(wi, wo) / squared.G1(wi); }},
  };
  for (const auto& [name, weight] : weights) {
    const ValidationReport r = validate_weights(name, ggx, wi, weight);
    const SubTest& albedo = r.check("bsdf_albedo");
    const SubTest& bins = r.check("bsdf_bins");
    ASSERT_TRUE(albedo.statistical && bins.statistical) << name;
    if (name == "correct") {
      EXPECT_TRUE(r.passed) << (r.failures.empty() ? "" : r.failures.front());
      EXPECT_GT(albedo.p_value, 0.01) << albedo.detail;
      EXPECT_GT(bins.p_value, 0.01) << bins.detail;
    } else {
      EXPECT_FALSE(r.passed) << name;
      EXPECT_LT(std::min(albedo.p_value, bins.p_value), 1e-6) << name << ": " << albedo.detail << "; " << bins.detail;
      EXPECT_GT(r.chi2("sphere").p_value, 1e-4) << name << ": the directions are right";
    }
  }
}

TEST(BsdfWeights, RefusesWhatItCannotTest) {
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(30.0, 0.0);
  const auto ref = density_reference(claimed_density(FilePdf::reflection, ggx, wi), ggx, wi, 11);
  const auto normals = density_reference(claimed_density(FilePdf::vndf, ggx, wi), ggx, wi, 11);
  const SampleColumns one = SampleColumns::parse("x,y,z,weight");
  ValidationOptions o;
  EXPECT_THROW(bsdf_weight_tests("none.txt", one, SampleFrame::z_up, *normals, Material::mirror(), o), std::invalid_argument);
  EXPECT_THROW(bsdf_weight_tests("none.txt", one, SampleFrame::z_up, *ref, Material::lambertian(0.5), o), std::invalid_argument);
  EXPECT_THROW(bsdf_weight_tests("none.txt", one, SampleFrame::z_up, *ref, Material::conductor(kGold), o), std::invalid_argument);
}

// Bugs the samples' own variance hides: a few huge weights (fireflies) raise the variance with the mean, one
// negative weight moves no mean; and a bug in one channel must be reported in that channel's figures.
TEST(BsdfWeights, FirefliesANegativeWeightAndOneChannelsBugAreCaught) {
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  const auto correct = [&](int c, const Vec3<double>& m, const Vec3<double>& wo) {
    return fresnel_conductor(wi.dot(m), kGold[std::size_t(c)]) * ggx.G2(wi, wo) / ggx.G1(wi);
  };
  // The weight of the k-th call: calls come per sample, channel 0, 1, 2.
  const auto planted = [&](std::function<double(int, int, double)> edit) {
    return [correct, edit, calls = 0](int c, const Vec3<double>& m, const Vec3<double>& wo) mutable {
      return edit(calls++ / 3, c, correct(c, m, wo));
    };
  };
  const std::map<std::string, WeightOf> weights = {
      {"correct", correct},
      {"fireflies", planted([](int i, int, double w) { return i == 5 || i == 900 || i == 7000 ? w * 1e5 : w; })},
      {"negative", planted([](int i, int c, double w) { return i == 5 && c == 1 ? -0.5 : w; })},
      {"blue", planted([](int, int c, double w) { return c == 2 ? w * 1.03 : w; })},
  };
  const std::string blue = Material::conductor(kGold).channel_name(2);
  for (const auto& [name, weight] : weights) {
    const ValidationReport r = validate_weights(name, ggx, wi, weight);
    const SubTest& sign = r.check("bsdf_weight_sign");
    const SubTest& albedo = r.check("bsdf_albedo");
    EXPECT_EQ(r.passed, name == "correct") << name << ": " << (r.failures.empty() ? "" : r.failures.front());
    EXPECT_EQ(sign.passed, name != "negative") << name << ": " << sign.detail;
    if (name == "negative") {
      EXPECT_NE(sign.detail.find("1 of "), std::string::npos) << sign.detail;
    }
    if (name == "fireflies") {
      EXPECT_LT(albedo.p_value, 1e-6) << albedo.detail;
    }
    if (name == "blue") {
      EXPECT_LT(albedo.p_value, 1e-6) << albedo.detail;
      EXPECT_NE(albedo.detail.find("channel " + blue), std::string::npos) << albedo.detail;
    }
  }
}

}  // namespace test_weight_test
