// Samplers against the traced oracle (two-sample chi-square homogeneity, compare.h), at the validator's
// default sample count (1e6 samples, 31 rows) and the default oracle ray count (4e6 rays), fixed seeds,
// family-wise level 0.01 per validation (Sidak over its two binnings), as `microsim validate --against
// ellipsoid` runs them. Correct VNDF samplers pass; the negative control heitz2018-talk is rejected at
// every view; `ndf` (which samples D(m) m.z, equal to D_v only at normal incidence) is rejected at
// theta >= 45 and passes at theta = 0.
#include "validate/compare.h"
#include "core/random.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <limits>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_trace_compare {

using namespace microsim;

namespace {

void check_samplers_against_oracle(double ax, double ay) {
  const GGX<double> ggx(ax, ay);
  for (double theta : {0.0, 45.0, 75.0, 88.0}) {
    const Vec3<double> wi = direction_from_degrees(theta, 30.0);
    const ValidationOptions options;  // defaults: 1e6 samples, seed 1
    OracleTraceOptions trace_options;  // defaults: 4e6 rays, 31 rows, exact quadric
    trace_options.seed = oracle_seed(options.seed);  // as `validate --against ellipsoid` does
    const TracedHistogram traced = trace_vndf_histogram(ggx, wi, trace_options);
    ASSERT_FALSE(traced.partial);
    for (const char* name : {"heitz2018", "heitz2014", "dupuy2023", "heitz2018-talk", "ndf"}) {
      const SamplerInfo* s = find_sampler(name);
      ASSERT_NE(s, nullptr) << name;
      const ValidationReport r = compare_sampler_to_trace(*s, ggx, wi, options, traced);
      std::printf("alpha (%g, %g) theta %g %-15s p = %.4g %s\n", ax, ay, theta, name, r.p_value,
                  r.passed ? "pass" : "fail");
      const bool must_pass = s->name != "heitz2018-talk" && !(s->name == "ndf" && theta >= 45);
      EXPECT_EQ(r.passed, must_pass) << name << " alpha (" << ax << ", " << ay << ") theta " << theta
                                     << " p = " << r.p_value;
      if (!must_pass) {
        EXPECT_LT(r.p_value, 1e-6) << name << " theta " << theta;
      }
      EXPECT_EQ(r.samples, options.samples);
      EXPECT_EQ(r.statistical_tests, 2);
    }
  }
}

}  // namespace

TEST(TraceCompare, SamplersAgainstOracleIsotropic) { check_samplers_against_oracle(0.5, 0.5); }
TEST(TraceCompare, SamplersAgainstOracleAnisotropic) { check_samplers_against_oracle(0.1, 0.8); }

TEST(TraceCompare, SamplesFromFileAndConfigurationChecks) {
  const GGX<double> ggx(0.3, 0.3);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  OracleTraceOptions t;
  t.rays = 400'000;
  t.rows = 15;
  const TracedHistogram traced = trace_vndf_histogram(ggx, wi, t);
  // Samples of the exact VNDF drawn by a second, independent trace's normals are not available as a
  // list; use heitz2018's samples as "a file", and a wrong set (normals of the NDF) as the control.
  std::vector<Vec3<double>> good, bad;
  CounterRng rng(9, 0);
  for (int i = 0; i < 200'000; ++i) {
    const Vec2<double> u(rng.uniform(), rng.uniform());
    good.push_back(sample_heitz2018(ggx, wi, u)->direction);
    bad.push_back(sample_ndf(ggx, wi, u)->direction);
  }
  ValidationOptions o;
  const ValidationReport rg = compare_samples_to_trace(good, "good.npy", ggx, wi, o, traced);
  const ValidationReport rb = compare_samples_to_trace(bad, "bad.npy", ggx, wi, o, traced);
  EXPECT_TRUE(rg.passed) << rg.p_value;
  EXPECT_FALSE(rb.passed);
  EXPECT_EQ(rg.samples, 200'000u);
  // A non-unit sample fails the domain check.
  std::vector<Vec3<double>> broken = good;
  broken[5] *= 2.0;
  EXPECT_FALSE(compare_samples_to_trace(broken, "broken", ggx, wi, o, traced).passed);
  // The histogram's configuration must match.
  EXPECT_THROW(compare_samples_to_trace(good, "x", GGX<double>(0.31, 0.3), wi, o, traced), std::invalid_argument);
  EXPECT_THROW(compare_samples_to_trace(good, "x", ggx, direction_from_degrees(61.0, 0.0), o, traced),
               std::invalid_argument);
  // Samplers of reflected directions cannot be compared with normals.
  EXPECT_THROW(compare_sampler_to_trace(*find_sampler("bounded2023"), ggx, wi, o, traced), std::invalid_argument);
}

// A traced reference is a ground truth only as far as it is D_v: one that departs from it (here an exact
// trace of alpha 0.32 labelled alpha 0.3, as a finite tile's missing tail or a faceted mesh departs) rejects
// even an exact sampler once the samples resolve the difference. The comparison refuses such sample counts
// before drawing (BiasedReference), names the largest count the reference serves, and at that count the
// exact sampler passes while the negative control is still rejected. An exact trace serves any count.
TEST(TraceCompare, AReferenceThatDepartsFromDvIsRefusedWhereItWouldRejectAnExactSampler) {
  const GGX<double> ggx(0.3, 0.3);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  OracleTraceOptions t;
  t.rays = 400'000;
  t.rows = 15;
  const TracedHistogram exact = trace_vndf_histogram(ggx, wi, t);
  const ReferenceBias fine = reference_bias(exact, 1'000'000, 0.01);
  EXPECT_TRUE(fine.usable()) << fine.describe();
  EXPECT_EQ(fine.max_samples, std::numeric_limits<std::uint64_t>::max()) << fine.describe();

  TracedHistogram off = trace_vndf_histogram(GGX<double>(0.31, 0.31), wi, t);
  off.attributes["alpha"] = "0.3,0.3";
  const ReferenceBias biased = reference_bias(off, 1'000'000, 0.01);
  std::printf("%s\n", biased.describe().c_str());
  ASSERT_FALSE(biased.usable());
  ASSERT_GT(biased.max_samples, 2'000u);
  ASSERT_LT(biased.max_samples, 1'000'000u);
  ValidationOptions o;  // 1e6 samples
  const SamplerInfo& heitz = *find_sampler("heitz2018");
  try {
    compare_sampler_to_trace(heitz, ggx, wi, o, off);
    ADD_FAILURE() << "an unusable reference gave a verdict";
  } catch (const BiasedReference& e) {
    EXPECT_NE(std::string(e.what()).find(std::to_string(biased.max_samples)), std::string::npos) << e.what();
  }
  o.samples = biased.max_samples;
  const ValidationReport pass = compare_sampler_to_trace(heitz, ggx, wi, o, off);
  EXPECT_TRUE(pass.passed) << pass.p_value;
  EXPECT_TRUE(pass.check("reference_bias").passed);
  EXPECT_LE(pass.check("reference_bias").value, 0.02);
  EXPECT_FALSE(compare_sampler_to_trace(*find_sampler("heitz2018-talk"), ggx, wi, o, off).passed);
}

}  // namespace test_trace_compare
