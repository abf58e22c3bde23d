// Tests of the statistical validator: negative controls are rejected, correct samplers pass, each
// sub-test fails on the input it is meant to catch. All at fixed seeds; levels stated per test.
#include "core/atomic_file.h"
#include "core/random.h"
#include "validate/dump_validation.h"
#include "validate/sample_io.h"
#include "validate/validate.h"
#include "sample_dumps.h"

#include <fmt/core.h>
#include <fmt/printf.h>
#include <fmt/ranges.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <sstream>
#include <tuple>

#include <unistd.h>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_validate {

using namespace microsim;
namespace fs = std::filesystem;

namespace {

// References are expensive (adaptive cubature over 2 x 1922 bins): share them between tests.
std::shared_ptr<const ReferenceDistribution> cached_claimed(const SamplerInfo& s, double ax, double ay, double theta,
                                                            double phi) {
  static std::mutex mutex;
  static std::map<std::tuple<const void*, double, double, double, double>, std::shared_ptr<const ReferenceDistribution>> cache;
  std::lock_guard lock(mutex);
  auto& ref = cache[{reinterpret_cast<const void*>(s.claimed_pdf), ax, ay, theta, phi}];
  if (!ref) ref = claimed_reference(s, GGX<double>(ax, ay), direction_from_degrees(theta, phi), 31);
  return ref;
}

// Normals drawn by a sampler of the zoo with another roughness, or any sampling function.
template <class F> std::vector<Vec3<double>> draw(F&& sample, std::uint64_t n, std::uint64_t seed) {
  std::vector<Vec3<double>> out;
  out.reserve(n);
  for (std::uint64_t i = 0; i < n; ++i) {
    CounterRng rng(seed, i);
    const auto s = sample(Vec2<double>(rng.uniform(), rng.uniform()));
    if (s) out.push_back(s->direction);
  }
  return out;
}

// A deliberately wrong sampler for the returned-pdf test: heitz2018's samples with 5% too much pdf.
SampleResult<double> heitz2018_pdf_too_high(const GGX<double>& g, const Vec3<double>& wi, Vec2<double> u) {
  auto s = sample_heitz2018<double>(g, wi, u);
  if (s) s->pdf *= 1.05;
  return s;
}
SampleResult<float> heitz2018_pdf_too_high_f(const GGX<float>& g, const Vec3<float>& wi, Vec2<float> u) {
  auto s = sample_heitz2018<float>(g, wi, u);
  if (s) s->pdf *= 1.05f;
  return s;
}

const SamplerInfo& sampler(const char* name) {
  const SamplerInfo* s = find_sampler(name);
  if (!s) throw std::runtime_error(name);
  return *s;
}

}  // namespace

// The negative control of the zoo (the 2018 talk's listing) is rejected at every theta of the grid for
// alpha = 0.3, with 200k samples at seed 7, family-wise level 0.01, and p < 1e-6.
TEST(Validate, TalkListingIsRejectedAtEveryTheta) {
  const SamplerInfo& talk = sampler("heitz2018-talk");
  for (double theta : {0.0, 30.0, 60.0, 80.0, 89.0}) {
    ValidationOptions o;
    o.samples = 200'000;
    o.seed = 7;
    const ValidationReport r = validate_sampler(talk, GGX<double>(0.3), direction_from_degrees(theta, 0.0), o,
                                                cached_claimed(talk, 0.3, 0.3, theta, 0));
    EXPECT_FALSE(r.passed) << "theta " << theta;
    EXPECT_LT(r.p_value, 1e-6) << "theta " << theta;
    EXPECT_FALSE(r.failures.empty());
  }
}

// Every correct sampler passes a small grid (100k samples per validation, fixed seeds), with the Sidak
// correction over the 5 x 8 validations of the grid at family-wise level 0.01.
class CorrectSamplerGrid : public ::testing::TestWithParam<const char*> {};

TEST_P(CorrectSamplerGrid, PassesTheGrid) {
  const SamplerInfo& s = sampler(GetParam());
  struct Config {
    double ax, ay, theta, phi;
  };
  const Config grid[] = {{1e-3, 1e-3, 30, 0}, {1e-3, 1e-3, 89, 0}, {0.3, 0.3, 30, 0},   {0.3, 0.3, 89, 0},
                         {2, 2, 30, 0},       {2, 2, 89, 0},       {0.05, 0.5, 60, 30}, {1e-3, 0.3, 0, 30}};
  const int n_validations = 5 * int(std::size(grid));
  int k = 0;
  for (const Config& c : grid) {
    ValidationOptions o;
    o.samples = 100'000;
    o.seed = 1000 + k++;
    o.significance = sidak_significance(0.01, n_validations);
    const ValidationReport r = validate_sampler(s, GGX<double>(c.ax, c.ay), direction_from_degrees(c.theta, c.phi), o,
                                                cached_claimed(s, c.ax, c.ay, c.theta, c.phi));
    EXPECT_TRUE(r.passed) << s.name << " alpha (" << c.ax << ", " << c.ay << ") theta " << c.theta << ": "
                          << (r.failures.empty() ? "" : r.failures.front());
    EXPECT_NEAR(r.check("pdf_integral").value, 1.0, 1e-6);
    EXPECT_EQ(r.failed_samples, 0u);
  }
}

INSTANTIATE_TEST_SUITE_P(Zoo, CorrectSamplerGrid,
                         ::testing::Values("ndf", "heitz2014", "heitz2018", "dupuy2023", "bounded2023"));

// The float versions pass too (the returned pdf within the float tolerance).
TEST(Validate, FloatVersionsPass) {
  for (const char* name : {"heitz2018", "dupuy2023", "bounded2023"}) {
    const SamplerInfo& s = sampler(name);
    ValidationOptions o;
    o.samples = 100'000;
    o.seed = 11;
    o.precision = Precision::float32;
    o.significance = sidak_significance(0.01, 3);
    const ValidationReport r =
        validate_sampler(s, GGX<double>(0.3), direction_from_degrees(60.0, 0.0), o, cached_claimed(s, 0.3, 0.3, 60, 0));
    EXPECT_TRUE(r.passed) << name << ": " << (r.failures.empty() ? "" : r.failures.front());
    EXPECT_LE(r.check("returned_pdf").value, kPdfToleranceFloat);
  }
}

// ndf samples D(m) m.z: validated against the pdf it claims it passes; its normals validated as VNDF
// samples (against D_v) are rejected at theta = 60 degrees (200k samples, seed 3, level 0.01).
TEST(Validate, NdfIsNotAVndfSampler) {
  const SamplerInfo& ndf = sampler("ndf");
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  ValidationOptions o;
  o.samples = 200'000;
  o.seed = 3;
  const ValidationReport own = validate_sampler(ndf, ggx, wi, o, cached_claimed(ndf, 0.3, 0.3, 60, 0));
  EXPECT_TRUE(own.passed) << (own.failures.empty() ? "" : own.failures.front());
  EXPECT_TRUE(own.check("weight_mean").applicable);
  const auto normals = draw([&](Vec2<double> u) { return sample_ndf<double>(ggx, wi, u); }, o.samples, o.seed);
  const ValidationReport as_vndf = validate_samples(normals, SampleDomain::microfacet_normal, ggx, wi, o);
  EXPECT_FALSE(as_vndf.passed);
  EXPECT_LT(as_vndf.p_value, 1e-6);
  EXPECT_FALSE(as_vndf.check("returned_pdf").applicable);
  EXPECT_FALSE(as_vndf.check("weight_mean").applicable);
}

// A subtly wrong sampler: heitz2018 run with alpha 5% too large, checked against the VNDF of alpha = 0.3
// at theta = 60 degrees, is rejected at 1e6 samples (seed 5, level 0.01).
TEST(Validate, SubtlyWrongRoughnessIsRejected) {
  const GGX<double> ggx(0.3), wrong(0.3 * 1.05);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  ValidationOptions o;
  o.seed = 5;
  const auto normals = draw([&](Vec2<double> u) { return sample_heitz2018<double>(wrong, wi, u); }, 1'000'000, o.seed);
  const ValidationReport r = validate_samples(normals, SampleDomain::microfacet_normal, ggx, wi, o);
  EXPECT_FALSE(r.passed);
  EXPECT_LT(r.p_value, 1e-4);
  // The same samples are accepted against the roughness they were drawn with.
  const ValidationReport ok = validate_samples(normals, SampleDomain::microfacet_normal, wrong, wi, o);
  EXPECT_TRUE(ok.passed) << (ok.failures.empty() ? "" : ok.failures.front());
}

// At alpha = 1e-3 the whole lobe sits in the polar sphere bins: only the lobe bins see a 5% error of
// the roughness (300k samples, seed 9; level 0.01).
TEST(Validate, LobeBinsKeepPowerAtSmallAlpha) {
  const GGX<double> ggx(1e-3), wrong(1.05e-3);
  const Vec3<double> wi = direction_from_degrees(30.0, 0.0);
  ValidationOptions o;
  o.seed = 9;
  const auto normals = draw([&](Vec2<double> u) { return sample_heitz2018<double>(wrong, wi, u); }, 300'000, o.seed);
  const ValidationReport r = validate_samples(normals, SampleDomain::microfacet_normal, ggx, wi, o);
  EXPECT_FALSE(r.passed);
  EXPECT_LT(r.chi2("lobe").p_value, 1e-6);
  EXPECT_GT(r.chi2("sphere").p_value, 1e-3) << "sphere bins were expected to be blind here";
}

// Reflected directions: VNDF reflections pass against the VNDF reflection pdf (the --from --reflected
// path); the bounded sampler's reflections do not (its support is smaller), at alpha 0.3, theta 60.
TEST(Validate, ReflectedDirections) {
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  ValidationOptions o;
  o.seed = 13;
  o.significance = sidak_significance(0.01, 2);
  const auto vndf = draw(
      [&](Vec2<double> u) {
        auto s = sample_heitz2018<double>(ggx, wi, u);
        if (s) s->direction = reflect(wi, s->direction);
        return s;
      },
      200'000, o.seed);
  const ValidationReport ok = validate_samples(vndf, SampleDomain::reflected_direction, ggx, wi, o);
  EXPECT_TRUE(ok.passed) << (ok.failures.empty() ? "" : ok.failures.front());
  const auto bounded = draw([&](Vec2<double> u) { return sample_bounded2023<double>(ggx, wi, u); }, 200'000, o.seed);
  const ValidationReport bad = validate_samples(bounded, SampleDomain::reflected_direction, ggx, wi, o);
  EXPECT_FALSE(bad.passed);
  EXPECT_LT(bad.p_value, 1e-6);
}

// Samples outside the domain (NaN, not unit length) reject at once with p = 0.
TEST(Validate, SamplesOutsideTheDomainReject) {
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(30.0, 0.0);
  auto normals = draw([&](Vec2<double> u) { return sample_heitz2018<double>(ggx, wi, u); }, 20'000, 17);
  ValidationOptions o;
  const ValidationReport good = validate_samples(normals, SampleDomain::microfacet_normal, ggx, wi, o);
  EXPECT_TRUE(good.passed) << (good.failures.empty() ? "" : good.failures.front());
  normals[10] = Vec3<double>(std::nan(""), 0, 1);
  normals[20] *= 1.01;
  const ValidationReport bad = validate_samples(normals, SampleDomain::microfacet_normal, ggx, wi, o);
  EXPECT_FALSE(bad.passed);
  EXPECT_EQ(bad.outside_domain, 2u);
  EXPECT_EQ(bad.p_value, 0.0);
  EXPECT_FALSE(bad.check("domain").passed);
}

// A claimed pdf that integrates to more than 1 is rejected; one that integrates to less than 1 makes the
// chi-square reject (the samples exceed the claimed mass).
TEST(Validate, ClaimedPdfIntegralIsChecked) {
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(30.0, 0.0);
  const auto normals = draw([&](Vec2<double> u) { return sample_heitz2018<double>(ggx, wi, u); }, 100'000, 19);
  ValidationOptions o;
  for (double scale : {1.01, 0.97}) {
    const auto ref = prepare_reference([&](const Vec3<double>& m) { return scale * ggx.visible_normal_pdf(wi, m); },
                                       SampleDomain::microfacet_normal, ggx, wi, 31);
    EXPECT_NEAR(ref->sphere_probability.total, scale, 1e-6);
    const ValidationReport r = validate_samples(normals, SampleDomain::microfacet_normal, ggx, wi, o, ref);
    EXPECT_FALSE(r.passed) << "scale " << scale;
    EXPECT_EQ(r.check("pdf_integral").passed, scale < 1) << "scale " << scale;
  }
}

// A sampler whose returned pdf is 5% off fails the returned-pdf check, in double and float.
TEST(Validate, ReturnedPdfIsChecked) {
  const SamplerInfo& h = sampler("heitz2018");
  SamplerInfo wrong = h;
  wrong.name = "heitz2018-pdf-too-high";
  wrong.sample_double = &heitz2018_pdf_too_high;
  wrong.sample_float = &heitz2018_pdf_too_high_f;
  for (Precision precision : {Precision::float64, Precision::float32}) {
    ValidationOptions o;
    o.samples = 50'000;
    o.precision = precision;
    const ValidationReport r =
        validate_sampler(wrong, GGX<double>(0.3), direction_from_degrees(45.0, 0.0), o, cached_claimed(h, 0.3, 0.3, 45, 0));
    EXPECT_FALSE(r.passed);
    EXPECT_FALSE(r.check("returned_pdf").passed);
    EXPECT_NEAR(r.check("returned_pdf").value, 0.05 / 1.05, 1e-3);
    // The weight D <wi, m> / pdf is 5% low on every sample: the E[weight] test sees it too.
    EXPECT_FALSE(r.check("weight_mean").passed);
  }
}

// Same seed, same result, whatever the number of threads.
TEST(Validate, DeterministicWhateverTheThreadCount) {
  const SamplerInfo& s = sampler("heitz2014");
  ValidationOptions o;
  o.samples = 150'000;
  o.seed = 23;
  const auto ref = cached_claimed(s, 0.3, 0.3, 60, 0);
  ValidationReport one;
  {
    tbb::global_control single(tbb::global_control::max_allowed_parallelism, 1);
    one = validate_sampler(s, GGX<double>(0.3), direction_from_degrees(60.0, 0.0), o, ref);
  }
  const ValidationReport many = validate_sampler(s, GGX<double>(0.3), direction_from_degrees(60.0, 0.0), o, ref);
  EXPECT_EQ(one.chi2("sphere").statistic, many.chi2("sphere").statistic);
  EXPECT_EQ(one.chi2("lobe").statistic, many.chi2("lobe").statistic);
  EXPECT_EQ(one.check("weight_mean").value, many.check("weight_mean").value);
  EXPECT_EQ(one.p_value, many.p_value);
  // And a reference computed twice is bit-identical (parallel cubature, one task per bin).
  const auto again = claimed_reference(s, GGX<double>(0.3), direction_from_degrees(60.0, 0.0), 31);
  EXPECT_EQ(again->lobe_probability.probability, ref->lobe_probability.probability);
}

TEST(Validate, JsonCarriesTheVerdictAndSubTests) {
  const SamplerInfo& s = sampler("heitz2018");
  ValidationOptions o;
  o.samples = 20'000;
  const ValidationReport r =
      validate_sampler(s, GGX<double>(0.3), direction_from_degrees(60.0, 0.0), o, cached_claimed(s, 0.3, 0.3, 60, 0));
  const nlohmann::json j = to_json(r);
  for (const char* key : {"verdict", "p_value", "statistic", "dof", "samples", "tests", "sampler", "alpha", "seed"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["verdict"], r.passed ? "pass" : "fail");
  EXPECT_EQ(j["samples"], 20000);
  for (const char* key : {"chi2_sphere", "chi2_lobe", "weight_mean", "returned_pdf", "pdf_integral", "domain"})
    EXPECT_TRUE(j["tests"].contains(key)) << key;
}

// ---- reflected directions as renderers emit them -------------------------------------

namespace {

// A renderer's dump of reflected directions: normals from `sampler`, reflected about them, those below
// the horizon dropped (counted in `dropped`).
template <class F>
std::vector<Vec3<double>> renderer_reflections(F&& sampler, const Vec3<double>& wi, std::uint64_t n, std::uint64_t seed,
                                               std::uint64_t& dropped) {
  std::vector<Vec3<double>> out;
  dropped = 0;
  for (const Vec3<double>& m : draw(sampler, n, seed)) {
    const Vec3<double> wo = reflect(wi, m);
    if (wo.z() > 0) out.push_back(wo.normalized());
    else ++dropped;
  }
  return out;
}

// Validates the rows x,y,z,pdf of the file `p` against `reference` (of the density `d` claims; default options),
// then removes the file.
ValidationReport validate_file_and_remove(const fs::path& p, const GGX<double>& ggx, const Vec3<double>& wi,
                                          const ClaimedDensity& d, std::shared_ptr<const ReferenceDistribution> reference) {
  ValidationReport r;
  {
    DirectionSampleReader reader(p, SampleColumns::parse("x,y,z,pdf"));
    r = validate_sample_file(reader, d.domain, ggx, wi, ValidationOptions{}, std::move(reference));
  }
  fs::remove(p);
  return r;
}

}  // namespace

// At alpha 0.3, 60 deg about 8.9% of the reflections fall below the horizon: a correct renderer-style dump
// fails the full-sphere test (with a note saying why) and passes the test conditioned on wo.z > 0; the
// dropped count is tested against its expected fraction; a wrong sampler still fails (level 0.01).
TEST(ValidateAboveHorizon, ARendererStyleDumpPassesConditionedAndFailsUnconditioned) {
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  std::uint64_t dropped = 0;
  const auto dump = renderer_reflections([&](Vec2<double> u) { return sample_heitz2018<double>(ggx, wi, u); }, wi,
                                         400'000, 5, dropped);
  ASSERT_GT(dropped, 30000u);  // 8.9% of 4e5
  ValidationOptions o;
  const ValidationReport full = validate_samples(dump, SampleDomain::reflected_direction, ggx, wi, o);
  EXPECT_FALSE(full.passed);
  ASSERT_FALSE(full.hints.empty());  // a rejection, and the hint that explains it
  EXPECT_NE(full.hints.back().find("no sample below the horizon"), std::string::npos) << full.hints.back();
  EXPECT_NE(full.hints.back().find("--above-horizon"), std::string::npos) << full.hints.back();

  const auto conditioned = above_horizon_reference(claimed_density(FilePdf::reflection, ggx, wi), ggx, wi, o.rows);
  EXPECT_NEAR(1.0 - conditioned->kept_mass, double(dropped) / 400'000.0, 0.002);
  EXPECT_NEAR(conditioned->sphere_probability.total, 1.0, 1e-6);
  const ValidationReport ok = validate_samples(dump, SampleDomain::reflected_direction, ggx, wi, o, conditioned);
  EXPECT_TRUE(ok.passed) << (ok.failures.empty() ? "" : ok.failures.front());
  EXPECT_FALSE(ok.check("dropped_fraction").applicable);

  o.dropped_below_horizon = dropped;
  const ValidationReport counted = validate_samples(dump, SampleDomain::reflected_direction, ggx, wi, o, conditioned);
  EXPECT_TRUE(counted.passed) << (counted.failures.empty() ? "" : counted.failures.front());
  EXPECT_TRUE(counted.check("dropped_fraction").applicable);
  EXPECT_GT(counted.check("dropped_fraction").p_value, 0.01);
  // Negative control: a dump that claims 20% fewer dropped reflections than it had.
  o.dropped_below_horizon = dropped * 4 / 5;
  const ValidationReport miscounted = validate_samples(dump, SampleDomain::reflected_direction, ggx, wi, o, conditioned);
  EXPECT_FALSE(miscounted.passed);
  EXPECT_LT(miscounted.check("dropped_fraction").p_value, 1e-6);

  // Negative control: the talk listing's reflections, dropped the same way, fail the conditioned test.
  std::uint64_t talk_dropped = 0;
  const auto talk = renderer_reflections([&](Vec2<double> u) { return sample_heitz2018_talk<double>(ggx, wi, u); }, wi,
                                         400'000, 5, talk_dropped);
  ValidationOptions plain;
  EXPECT_FALSE(validate_samples(talk, SampleDomain::reflected_direction, ggx, wi, plain, conditioned).passed);
}

// float32 data stored as float64 (numpy's astype('f8'), Python's arrays) has float32's precision: at alpha
// 0.01, 80 deg rounding a direction to float moves D by more than 1e-6, so the returned pdfs are checked with
// float32's tolerance where they are float32-exact; a pdf 5% off still fails, and so does a true float64
// pdf 1e-5 off (level: every sample, no outlier allowed).
TEST(ValidateReturnedPdf, Float32DataWidenedToFloat64KeepsFloat32sTolerance) {
  const GGX<double> ggx(0.01);
  const Vec3<double> wi = direction_from_degrees(80.0, 0.0);
  std::uint64_t dropped = 0;
  const auto dump = renderer_reflections([&](Vec2<double> u) { return sample_heitz2018<double>(ggx, wi, u); }, wi,
                                         100'000, 9, dropped);
  const ClaimedDensity d = claimed_density(FilePdf::reflection, ggx, wi);
  const auto reference = density_reference(d, ggx, wi, ValidationOptions{}.rows);
  const auto check = [&](const std::string& name, const std::function<double(const Vec3<float>&)>& pdf_of) {
    std::vector<double> table;
    for (const Vec3<double>& wo : dump) {
      const Vec3<float> f = wo.cast<float>();
      table.insert(table.end(), {double(f.x()), double(f.y()), double(f.z()), pdf_of(f)});
    }
    const fs::path p = fs::temp_directory_path() / fmt::format("microsim_widened_{}_{}.npy", ::getpid(), name);
    write_npy_table(p, table, 4, /*as_float32=*/false);
    return validate_file_and_remove(p, ggx, wi, d, reference).check("returned_pdf");
  };
  const auto pdf = [&](const Vec3<float>& f) { return ggx.visible_reflection_pdf(wi, f.cast<double>()); };
  const SubTest widened = check("widened", [&](const Vec3<float>& f) { return double(float(pdf(f))); });
  EXPECT_TRUE(widened.passed) << widened.detail;
  const SubTest off = check("off", [&](const Vec3<float>& f) { return double(float(pdf(f) * 1.05)); });
  EXPECT_FALSE(off.passed) << off.detail;
  const SubTest float64_off = check("f64_off", [&](const Vec3<float>& f) { return pdf(f) * (1 + 1e-5); });
  EXPECT_FALSE(float64_off.passed) << float64_off.detail;
  // float32's tolerance (1e-4) still rejects a pdf 0.2% off, which the former 1e-2 accepted.
  const SubTest slightly_off = check("f32_off", [&](const Vec3<float>& f) { return double(float(pdf(f) * 1.002)); });
  EXPECT_FALSE(slightly_off.passed) << slightly_off.detail;
}

// E[weight] from a text dump: each weight D <wi, m> / pdf moves with the printed digits of the pdf and the
// direction (Jensen: a rounded small pdf raises its weight on average), enough at alpha 3, 60 deg, with %.4f
// (the smallest pdfs about 2e-4) to reject a correct dump. The test takes the deviation beyond the digits'
// bound, and a pdf 1% off still fails it (docs/reference/validator.md). A pdf printed as 0.0000 leaves its
// weight unbounded: the test is then not applicable, never passed or failed on it.
TEST(ValidateWeightMean, TextDigitsBoundTheMeanWeightsDeviation) {
  const GGX<double> ggx(3.0);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  std::vector<DirectionSample<double>> samples;
  for (std::uint64_t i = 0; i < 100'000; ++i) {
    CounterRng rng(43, i);
    if (const auto s = sample_heitz2018<double>(ggx, wi, Vec2<double>(rng.uniform(), rng.uniform()))) samples.push_back(*s);
  }
  const ClaimedDensity d = claimed_density(FilePdf::vndf, ggx, wi);
  const ValidationOptions o;
  const auto reference = density_reference(d, ggx, wi, o.rows);
  const fs::path p = fs::temp_directory_path() / fmt::format("microsim_weight_text_{}.txt", ::getpid());
  const auto write = [&](double factor, double pdf_floor) {
    std::string text;
    for (const DirectionSample<double>& s : samples)
      text += fmt::format("{:.4f} {:.4f} {:.4f} {:.4f}\n", s.direction.x(), s.direction.y(), s.direction.z(),
                          s.pdf < pdf_floor ? 0.0 : s.pdf * factor);
    write_file_atomically(p, text);
  };
  const auto check = [&](double factor, double pdf_floor) {
    write(factor, pdf_floor);
    return validate_file_and_remove(p, ggx, wi, d, reference).check("weight_mean");
  };
  const SubTest ok = check(1.0, 0.0);
  EXPECT_TRUE(ok.applicable && ok.passed) << ok.detail;
  const SubTest off = check(1.01, 0.0);
  EXPECT_FALSE(off.passed) << off.detail;
  const SubTest zero = check(1.0, 1e-3);  // the smallest pdfs printed as 0.0000
  EXPECT_FALSE(zero.applicable) << zero.detail;
  // A dump's validation says so in its notes.
  write(1.0, 1e-3);
  ValidationReport dump;
  {
    const DirectionSampleReader reader(p, SampleColumns::parse("x,y,z,pdf"));
    dump = validate_dump(reader, reference, ggx, wi, o, false);
  }
  fs::remove(p);
  EXPECT_TRUE(std::any_of(dump.notes.begin(), dump.notes.end(),
                          [](const std::string& n) { return n.rfind("E[weight] was not tested: ", 0) == 0; }))
      << fmt::format("{}", fmt::join(dump.notes, " | "));
}

// A weight column is f cos / pdf of a BSDF: a dump that has one but names no BSDF is refused (it would otherwise
// pass with its weights untested), whatever the weights hold; the same rows with the BSDF given are tested.
TEST(ValidateDumpWeights, AWeightColumnWithoutItsBsdfIsRefused) {
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(40.0, 0.0);
  const fs::path p = fs::temp_directory_path() / fmt::format("microsim_weights_no_bsdf_{}.txt", ::getpid());
  std::string text;
  for (std::uint64_t i = 0; i < 20'000; ++i) {
    CounterRng rng(5, i);
    const auto m = sample_heitz2018<double>(ggx, wi, Vec2<double>(rng.uniform(), rng.uniform()));
    if (!m) continue;
    const Vec3<double> wo = reflect(wi, m->direction);
    if (wo.z() <= 0) continue;
    text += fmt::format("{:.9g} {:.9g} {:.9g} {:.9g} -1000\n", wo.x(), wo.y(), wo.z(), m->pdf / (4 * wi.dot(m->direction)));
  }
  write_file_atomically(p, text);
  const auto validate = [&](std::optional<Material> bsdf) {
    DirectionSampleReader reader(p, SampleColumns::parse("x,y,z,pdf,weight"));
    ValidationOptions o;
    o.bsdf = bsdf;
    return validate_dump_as_given(reader, {FilePdf::reflection, bsdf, true, false}, ggx, wi, o, false);
  };
  EXPECT_THROW(
      {
        try {
          validate(std::nullopt);
        } catch (const std::invalid_argument& e) {
          EXPECT_NE(std::string(e.what()).find("no BSDF to test them against"), std::string::npos) << e.what();
          throw;
        }
      },
      std::invalid_argument);
  const ValidationReport r = validate(Material::mirror());  // the weights of -1000 are tested, and fail
  fs::remove(p);
  EXPECT_FALSE(r.passed);
}

// A float32 renderer's text dump, its directions and pdfs from heitz2018's float version printed with %.9g (every
// float's digits): the digits are a float32's, so float32's tolerance applies, and the dump passes; 0.2% off, it
// fails.
TEST(ValidateReturnedPdf, TextOfFloat32ValuesGetsFloat32sTolerance) {
  const GGX<float> ggx(0.01f);
  const Vec3<double> wi = direction_from_degrees(80.0, 0.0);
  const Vec3<float> wf = wi.cast<float>();
  std::vector<DirectionSample<float>> samples;
  for (std::uint64_t i = 0; i < 50'000; ++i) {
    CounterRng rng(41, i);
    const Vec2<float> u(float(rng.uniform()), float(rng.uniform()));
    if (const auto s = sample_heitz2018<float>(ggx, wf, u)) samples.push_back(*s);
  }
  const GGX<double> g(0.01);
  const ClaimedDensity d = claimed_density(FilePdf::vndf, g, wi);
  const ValidationOptions o;
  const auto reference = density_reference(d, g, wi, o.rows);
  const auto check = [&](float factor) {
    std::string text;
    for (const DirectionSample<float>& s : samples) {
      const Vec3<float>& f = s.direction;
      text += fmt::format("{:.9g} {:.9g} {:.9g} {:.9g}\n", f.x(), f.y(), f.z(), s.pdf * factor);
    }
    const fs::path p = fs::temp_directory_path() / fmt::format("microsim_float_text_{}.txt", ::getpid());
    write_file_atomically(p, text);
    return validate_file_and_remove(p, g, wi, d, reference).check("returned_pdf");
  };
  const SubTest ok = check(1.0f);
  EXPECT_TRUE(ok.passed) << ok.detail;
  const SubTest off = check(1.002f);
  EXPECT_FALSE(off.passed) << off.detail;
}

// A text dump's pdfs and directions are as exact as their printed digits (printf's %g keeps 6 significant
// digits, %.4f four decimals): each sample's returned pdf is checked within the rounding of its own digits,
// so correct dumps pass at every common format, and a pdf 0.3% off still fails at each; the same %g
// numbers in a float64 .npy are held to float64 (level: every sample, no outlier allowed).
TEST(ValidateReturnedPdf, TextIsAsExactAsItsPrintedDigits) {
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  const auto normals = draw([&](Vec2<double> u) { return sample_heitz2018<double>(ggx, wi, u); }, 20'000, 31);
  const ClaimedDensity d = claimed_density(FilePdf::vndf, ggx, wi);
  const ValidationOptions o;
  const auto reference = density_reference(d, ggx, wi, o.rows);
  const auto check = [&](const std::string& format, double factor, bool as_npy) {
    const fs::path p = fs::temp_directory_path() / fmt::format("microsim_printed_{}_{}.txt", ::getpid(), as_npy);
    std::string text;
    for (const Vec3<double>& m : normals) {
      const double pdf = ggx.visible_normal_pdf(wi, m) * factor;
      for (const double v : {m.x(), m.y(), m.z(), pdf}) text += fmt::sprintf(format + " ", v);
      text += "\n";
    }
    write_file_atomically(p, text);
    if (as_npy) {
      std::vector<double> table;
      for (std::istringstream in(text); in;) {
        double v = 0;
        if (in >> v) table.push_back(v);
      }
      write_npy_table(p, table, 4, /*as_float32=*/false);
    }
    return validate_file_and_remove(p, ggx, wi, d, reference).check("returned_pdf");
  };
  for (const std::string format : {"%g", "%.4f", "%.5f", "%.6e", "%.9g", "%.17g"}) {
    const SubTest ok = check(format, 1.0, false);
    EXPECT_TRUE(ok.passed) << format << ": " << ok.detail;
    const SubTest off = check(format, 1.003, false);
    EXPECT_FALSE(off.passed) << format << ": " << off.detail;
  }
  const SubTest binary = check("%g", 1.0, true);
  EXPECT_FALSE(binary.passed) << binary.detail;
}

// `--from --pdf`: a file of an NDF sampler's normals or of the bounded VNDF's reflections passes against
// the density it claims and is rejected against the VNDF's (level 0.01): the pdf, not the sampler, is the
// subject of a file's test.
TEST(ValidateFilePdf, EachDensityPassesItsOwnSamplesAndRejectsAnother) {
  const GGX<double> ggx(0.4);
  const Vec3<double> wi = direction_from_degrees(70.0, 20.0);
  ValidationOptions o;
  const auto samples_of = [&](ClaimedPdf claims) {
    const SamplerInfo& s = reference_sampler(claims);
    return draw([&](Vec2<double> u) { return s.sample_double(ggx, wi, u); }, 200'000, 23);
  };
  const auto test = [&](const std::vector<Vec3<double>>& samples, FilePdf pdf) {
    const ClaimedDensity d = claimed_density(pdf, ggx, wi);
    return validate_samples(samples, d.domain, ggx, wi, o, density_reference(d, ggx, wi, o.rows));
  };
  const auto ndf = samples_of(ClaimedPdf::ndf_cosine);
  EXPECT_TRUE(test(ndf, FilePdf::ndf).passed);
  EXPECT_FALSE(test(ndf, FilePdf::vndf).passed);
  const auto vndf = samples_of(ClaimedPdf::visible_normals);
  EXPECT_TRUE(test(vndf, FilePdf::vndf).passed);
  EXPECT_FALSE(test(vndf, FilePdf::ndf).passed);
  const auto bounded = samples_of(ClaimedPdf::bounded_reflection);
  EXPECT_TRUE(test(bounded, FilePdf::bounded).passed);
  EXPECT_FALSE(test(bounded, FilePdf::reflection).passed);
  // The bounded sampler's reflections as a renderer keeps them (above the horizon), conditioned.
  std::vector<Vec3<double>> upper;
  for (const Vec3<double>& wo : bounded)
    if (wo.z() > 0) upper.push_back(wo);
  EXPECT_LT(upper.size(), bounded.size());  // some fall below the horizon at 70 deg
  const ClaimedDensity d = claimed_density(FilePdf::bounded, ggx, wi);
  EXPECT_TRUE(validate_samples(upper, d.domain, ggx, wi, o, above_horizon_reference(d, ggx, wi, o.rows)).passed);
  EXPECT_THROW(above_horizon_reference(claimed_density(FilePdf::ndf, ggx, wi), ggx, wi, o.rows), std::invalid_argument);
  EXPECT_THROW(parse_file_pdf("ggx"), std::invalid_argument);
}

// Normals validated as reflected directions (--reflected given by mistake) and reflections validated as normals
// (--reflected forgotten): each rejection says the other reading passes and which option gives it. The talk
// listing's normals pass neither reading: no such hint.
TEST(ValidateDumpDomain, NormalsAndReflectionsReadTheWrongWayAreNamed) {
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  ValidationOptions o;
  o.samples = 200'000;
  o.seed = 4;
  const auto dump_of = [&](const char* sampler, bool reflected, const char* name) {
    SampleSet s = draw_samples(*find_sampler(sampler), ggx, wi, o);
    if (reflected)
      for (Vec3<double>& m : s.directions) m = reflect(wi, m);
    const fs::path p = fs::temp_directory_path() / fmt::format("microsim_domain_{}_{}.npy", name, ::getpid());
    write_npy(p, s.directions, false);
    return p;
  };
  const auto hints_of = [&](const fs::path& p, FilePdf claims) {
    DirectionSampleReader reader(p, SampleColumns::parse("x,y,z"));
    const ValidationReport r = validate_dump_as_given(reader, {claims, std::nullopt, false, false}, ggx, wi, o, true);
    EXPECT_FALSE(r.passed);
    return fmt::format("{}", fmt::join(r.hints, "\n"));
  };
  const fs::path normals = dump_of("heitz2018", false, "normals"), reflections = dump_of("heitz2018", true, "reflections"),
                 talk = dump_of("heitz2018-talk", false, "talk");
  const std::string as_reflections = hints_of(normals, FilePdf::reflection);
  EXPECT_NE(as_reflections.find("pass as VNDF normals"), std::string::npos) << as_reflections;
  EXPECT_NE(as_reflections.find("leave out --reflected"), std::string::npos) << as_reflections;
  const std::string as_normals = hints_of(reflections, FilePdf::vndf);
  EXPECT_NE(as_normals.find("give --reflected"), std::string::npos) << as_normals;
  const std::string talk_hints = hints_of(talk, FilePdf::vndf);
  EXPECT_EQ(talk_hints.find("--reflected"), std::string::npos) << talk_hints;
  for (const fs::path& p : {normals, reflections, talk}) fs::remove(p);
}

// Float32 reflected directions at alpha 1e-3 seen at 89.9 deg: reflection squeezes the lobe by 2 |wi.z| across
// the view's plane, so its narrowest lobe bins (about 1e-7) are a few float32 roundings wide and the stored
// directions are rejected; the report says so. The same directions in float64 pass without the hint.
TEST(ValidateDumpDomain, Float32ReflectionsTooFineForTheirStorageGetAHint) {
  const GGX<double> ggx(1e-3);
  const Vec3<double> wi = direction_from_degrees(89.9, 30.0);
  ValidationOptions o;
  o.seed = 1;
  SampleSet s = draw_samples(*find_sampler("heitz2018"), ggx, wi, o);
  for (Vec3<double>& m : s.directions) m = reflect(wi, m);
  const auto validate = [&](bool as_float32) {
    const fs::path p = fs::temp_directory_path() / fmt::format("microsim_f32_reflections_{}.npy", ::getpid());
    write_npy(p, s.directions, as_float32);
    DirectionSampleReader reader(p, SampleColumns::parse("x,y,z"));
    const ValidationReport r = validate_dump_as_given(reader, {FilePdf::reflection, std::nullopt, false, false}, ggx, wi, o, false);
    fs::remove(p);
    return r;
  };
  const ValidationReport f32 = validate(true), f64 = validate(false);
  EXPECT_FALSE(f32.passed);
  const std::string hints = fmt::format("{}", fmt::join(f32.hints, "\n"));
  EXPECT_NE(hints.find("the directions are float32"), std::string::npos) << hints;
  EXPECT_TRUE(f64.passed) << f64.p_value;
  EXPECT_TRUE(f64.hints.empty());
}

// A cancelled run stops a dump's validation at its next block of rows (Cancelled: the experiment's run marks the
// measurement partial) instead of reading the whole file to a verdict.
TEST(ValidateDumpDomain, ACancelledRunStopsReadingTheDump) {
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(30.0, 0.0);
  const fs::path p = fs::temp_directory_path() / fmt::format("microsim_cancelled_dump_{}.npy", ::getpid());
  test::write_sampler_dump(p, "heitz2018", 0.3, 30.0, 100'000);
  ValidationOptions o;
  const auto validate = [&] {
    DirectionSampleReader reader(p, SampleColumns::parse("x,y,z"));
    return validate_dump_as_given(reader, {FilePdf::vndf, std::nullopt, false, false}, ggx, wi, o, true);
  };
  EXPECT_TRUE(validate().passed);  // the same call, not cancelled
  CancelToken cancel;
  cancel.cancel();
  o.run.cancel = &cancel;
  EXPECT_THROW(validate(), Cancelled);
  fs::remove(p);
}

}  // namespace test_validate
