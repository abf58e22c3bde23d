// The validator hardened: too few samples is never a pass, the returned-pdf check at
// alpha 1e-4, theta 89.99 deg, and validations that stream their samples in bounded memory
// with results bit-identical to the former in-memory implementation. Fixed seeds.
#include "cli_helpers.h"
#include "stats/chi2.h"
#include "validate/compare.h"
#include "validate/sample_io.h"
#include "microfacet/samplers_impl.h"
#include "validate/validate.h"

#include <gtest/gtest.h>

#include <sys/resource.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_validate_hardening {

using namespace microsim;
namespace fs = std::filesystem;

namespace {

const SamplerInfo& sampler(const char* name) {
  const SamplerInfo* s = find_sampler(name);
  if (!s) throw std::runtime_error(name);
  return *s;
}

fs::path scratch() {
  const fs::path dir = fs::temp_directory_path() / ("microsim_validate_hardening_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

}  // namespace

// ---- how many samples a test needs ------------------------------------------------------------

TEST(MinimumSamples, IsExactlyWherePoolingLeavesTwoCells) {
  // n p_max >= 5 and n (1 - p_max) >= 5.
  EXPECT_EQ(goodness_of_fit_minimum_samples(std::vector<double>{0.5, 0.3, 0.2}), 10u);
  EXPECT_EQ(goodness_of_fit_minimum_samples(std::vector<double>{0.9, 0.1}), 50u);
  EXPECT_EQ(goodness_of_fit_minimum_samples(std::vector<double>{0.25, 0.25, 0.25, 0.25}), 20u);
  EXPECT_EQ(goodness_of_fit_minimum_samples(std::vector<double>{1.0, 0.0}), kNoSampleCountSuffices);
  // At the bound the test has a degree of freedom; one sample fewer, none (it cannot reject).
  const std::vector<double> p = {0.02, 0.03, 0.05, 0.1, 0.3, 0.5};
  const std::uint64_t n = goodness_of_fit_minimum_samples(p);
  const std::vector<double> observed(p.size(), 0.0);
  EXPECT_GE(goodness_of_fit(observed, p, double(n)).dof, 1);
  EXPECT_EQ(goodness_of_fit(observed, p, double(n - 1)).dof, 0);
  EXPECT_EQ(minimum_samples_for_any_test(), 10u);
}

TEST(MinimumSamples, TooFewDrawnSamplesThrowSayingHowManyAreNeeded) {
  const SamplerInfo& s = sampler("heitz2018");
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  const auto ref = claimed_reference(s, ggx, wi, 31);
  const std::uint64_t needed = minimum_samples(*ref);
  EXPECT_GT(needed, 1000u);  // lobe bins of 31 rows: ~1922 cells of similar mass
  ValidationOptions o;
  for (std::uint64_t n : {std::uint64_t(1), std::uint64_t(2), std::uint64_t(9), needed - 1}) {
    o.samples = n;
    try {
      validate_sampler(s, ggx, wi, o, ref);
      ADD_FAILURE() << n << " samples did not throw";
    } catch (const InsufficientData& e) {
      EXPECT_EQ(e.given, n);
      EXPECT_EQ(e.needed, n < 10 ? 10u : needed);
      EXPECT_NE(std::string(e.what()).find("at least " + std::to_string(e.needed)), std::string::npos) << e.what();
    }
  }
  o.samples = needed;
  const ValidationReport r = validate_sampler(s, ggx, wi, o, ref);
  EXPECT_GE(r.chi2("sphere").dof, 1);
  EXPECT_GE(r.chi2("lobe").dof, 1);
}

TEST(MinimumSamples, TooFewSamplesFromElsewhereThrow) {
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  const std::vector<Vec3<double>> one(1, Vec3<double>(0, 0, 1)), five(5, Vec3<double>(0, 0, 1));
  EXPECT_THROW(validate_samples(one, SampleDomain::microfacet_normal, ggx, wi, ValidationOptions{}), InsufficientData);
  EXPECT_THROW(validate_samples(five, SampleDomain::reflected_direction, ggx, wi, ValidationOptions{}), InsufficientData);
  // Two-sample comparison with the traced oracle: too few samples, and too few oracle hits.
  OracleTraceOptions t;
  t.rays = 200'000;
  t.rows = 15;
  const TracedHistogram traced = trace_vndf_histogram(ggx, wi, t);
  EXPECT_THROW(compare_samples_to_trace(five, "five", ggx, wi, ValidationOptions{}, traced), InsufficientData);
  ValidationOptions o;
  o.samples = 5;
  EXPECT_THROW(compare_sampler_to_trace(sampler("heitz2018"), ggx, wi, o, traced), InsufficientData);
  t.rays = 8;  // at most 8 hits: below the 10 of any test
  const TracedHistogram tiny = trace_vndf_histogram(ggx, wi, t);
  o.samples = 100'000;
  EXPECT_THROW(compare_sampler_to_trace(sampler("heitz2018"), ggx, wi, o, tiny), InsufficientData);
}

// ---- the returned pdf of bounded2023 at alpha 1e-4, theta 89.99 deg ---------------------------

namespace {
// bounded2023 with a pdf 1e-4 (relative) too high: the negative control of the returned-pdf check.
SampleResult<double> bounded_pdf_off(const GGX<double>& g, const Vec3<double>& wi, Vec2<double> u) {
  auto s = sample_bounded2023<double>(g, wi, u);
  if (s) s->pdf *= 1 + 1e-4;
  return s;
}
SampleResult<float> bounded_pdf_off_f(const GGX<float>& g, const Vec3<float>& wi, Vec2<float> u) {
  auto s = sample_bounded2023<float>(g, wi, u);
  if (s) s->pdf *= 1 + 1e-4f;
  return s;
}
}  // namespace

TEST(ReturnedPdf, Bounded2023AtGrazingTinyAlphaPassesAndAWrongPdfIsCaught) {
  const SamplerInfo& s = sampler("bounded2023");
  const GGX<double> ggx(1e-4);
  const Vec3<double> wi = direction_from_degrees(89.99, 0.0);
  const auto ref = claimed_reference(s, ggx, wi, 31);
  ValidationOptions o;  // 1e6 samples, double
  for (std::uint64_t seed : {1, 3, 4}) {
    o.seed = seed;
    const ValidationReport r = validate_sampler(s, ggx, wi, o, ref);
    EXPECT_TRUE(r.check("returned_pdf").passed) << "seed " << seed << ": " << r.check("returned_pdf").detail;
  }
  SamplerInfo wrong = s;
  wrong.sample_double = &bounded_pdf_off;
  wrong.sample_float = &bounded_pdf_off_f;
  o.seed = 3;
  const ValidationReport bad = validate_sampler(wrong, ggx, wi, o, ref);
  EXPECT_FALSE(bad.check("returned_pdf").passed) << bad.check("returned_pdf").detail;
  EXPECT_FALSE(bad.passed);
}

// ---- streaming, bit-identical, bounded memory ---------------------------------------------

namespace {
const GGX<double> kGgx03(0.3);
const Vec3<double> kWi60 = direction_from_degrees(60.0, 0.0);
ValidationOptions seeded(std::uint64_t samples, std::uint64_t seed) {
  ValidationOptions o;
  o.samples = samples;
  o.seed = seed;
  return o;
}
}  // namespace

// Figures of the in-memory implementation (commit 59518dc, `microsim validate ... --json`), to the bit.
TEST(Streaming, DrawnSamplesGiveTheFormerResultsBitForBit) {
  ValidationOptions o = seeded(100'000, 1);
  const ValidationReport d = validate_sampler(sampler("heitz2018"), kGgx03, kWi60, o);
  EXPECT_EQ(d.p_value, 0.4589443247903953);
  EXPECT_EQ(d.chi2("sphere").statistic, 579.98184436605);
  EXPECT_EQ(d.chi2("lobe").statistic, 1636.3169125637278);
  EXPECT_EQ(d.check("weight_mean").value, 0.5317356917396162);
  EXPECT_EQ(d.check("returned_pdf").value, 1.2483602807749123e-14);
  // Float, 1.5e6 samples: 23 blocks in two chunks, weight moments merged across them.
  o.samples = 1'500'000;
  o.seed = 2;
  o.precision = Precision::float32;
  const ValidationReport f = validate_sampler(sampler("dupuy2023"), kGgx03, kWi60, o);
  EXPECT_EQ(f.p_value, 0.1604168405971407);
  EXPECT_EQ(f.chi2("sphere").statistic, 675.4987071609509);
  EXPECT_EQ(f.chi2("lobe").statistic, 1727.5885182360487);
  EXPECT_EQ(f.check("weight_mean").p_value, 0.9989751415461502);
  EXPECT_EQ(f.check("weight_mean").value, 0.5317356849096311);
  EXPECT_EQ(f.check("returned_pdf").value, 2.869412313662803e-05);
}

TEST(Streaming, FilesGiveTheFormerResultsBitForBit) {
  const SampleSet set = draw_samples(sampler("heitz2018"), kGgx03, kWi60, seeded(200'000, 7));
  const fs::path dir = scratch();
  write_npy(dir / "s.npy", set.directions, false);
  write_npy(dir / "s_f4.npy", set.directions, true);
  write_text_samples(dir / "s.txt", set.directions);
  for (const char* name : {"s.npy", "s_f4.npy", "s.txt"}) {
    DirectionSampleReader reader(dir / name);
    const ValidationReport r =
        validate_sample_file(reader, SampleDomain::microfacet_normal, kGgx03, kWi60, ValidationOptions{});
    EXPECT_EQ(r.samples, 200'000u) << name;
    EXPECT_EQ(r.p_value, 0.7094498516745257) << name;
    EXPECT_EQ(r.chi2("sphere").statistic, 638.8322918847076) << name;
    EXPECT_EQ(r.chi2("lobe").statistic, 1552.1533853830877) << name;
    // The block reader returns exactly what the whole-file reader returns.
    EXPECT_EQ(read_direction_samples(dir / name).size(), 200'000u);
  }
  fs::remove_all(dir);
}

TEST(Streaming, TextReaderKeepsLineNumbersAcrossChunksAndSkipsLongComments) {
  const fs::path dir = scratch();
  {
    std::ofstream out(dir / "long.txt", std::ios::binary);
    out << "# " << std::string(3 << 20, 'c') << "\n";  // a 3 MiB comment line: longer than a chunk
    for (int i = 0; i < 200'000; ++i) out << "0 0 1\n";
    out << "0 0 2\n";  // line 200002: not unit length
  }
  try {
    read_direction_samples(dir / "long.txt");
    ADD_FAILURE() << "no error";
  } catch (const SampleFileError& e) {
    EXPECT_NE(std::string(e.what()).find("line 200002"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

// 4e6 samples held 42 bytes each before (175 MB resident); streamed, the process stays near its base.
// AddressSanitizer keeps freed memory in quarantine and maps shadow memory, so a peak resident size says
// nothing about the program's own memory under it: the bound is checked on the plain build only.
TEST(Streaming, MemoryDoesNotGrowWithTheSampleCount) {
  if (test::microsim_binary_is_instrumented()) GTEST_SKIP() << "peak memory is not the program's own under AddressSanitizer";
  const fs::path dir = scratch();
  const test::CliRun r =
      test::run_cli(dir, "validate --sampler ndf --alpha 0.3 --theta 60 --samples 4000000");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  rusage usage{};
  getrusage(RUSAGE_CHILDREN, &usage);
  EXPECT_LT(usage.ru_maxrss, 80 * 1024) << "peak resident KB of the largest child";
  fs::remove_all(dir);
}

}  // namespace test_validate_hardening
