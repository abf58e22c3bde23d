// The one test battery of validate and compare (validate/battery.h), and the registry traits that replace
// special cases keyed on sampler and assembly names (microfacet/samplers.h, microgeom/assembly.h).
#include "microgeom/assembly.h"
#include "validate/battery.h"
#include "validate/compare.h"
#include "validate/stability.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_battery {

using namespace microsim;

namespace {

battery::SampleSource no_samples() {
  battery::SampleSource s;
  s.name = "none";
  s.stream = [](const SampleBlockVisitor&, const ChunkDone&) {};
  return s;
}

}  // namespace

// ---- the sampler registry's traits ----------------------------------------------------------------------

// The bounded sampler's cap is a jump of its claimed pdf that the cubature must know: a property of the
// registry entry, so a copy under another name (a test double, a float variant) gets the same reference.
// Keyed on the name, the copy's reference lost the break and its bin probabilities changed.
TEST(SamplerTraits, ACopyUnderAnotherNameKeepsTheJumpOfItsClaimedPdf) {
  ASSERT_NE(find_sampler("bounded2023"), nullptr);
  const SamplerInfo& bounded = *find_sampler("bounded2023");
  ASSERT_NE(bounded.claimed_pdf_jump, nullptr);
  SamplerInfo copy = bounded;
  copy.name = "bounded2023-copy";
  const GGX<double> ggx(0.05);
  const Vec3<double> wi = direction_from_degrees(80.0, 0.0);
  const auto original = claimed_reference(bounded, ggx, wi, 9);
  const auto renamed = claimed_reference(copy, ggx, wi, 9);
  EXPECT_EQ(renamed->sphere_probability.probability, original->sphere_probability.probability);
  EXPECT_EQ(renamed->lobe_probability.probability, original->lobe_probability.probability);
  // Control: without the jump the cubature differs, so the comparison above can fail.
  copy.claimed_pdf_jump = nullptr;
  const auto without = claimed_reference(copy, ggx, wi, 9);
  EXPECT_NE(without->sphere_probability.probability, original->sphere_probability.probability);
}

TEST(SamplerTraits, EachClaimedDensityHasOneTrustedReferenceSampler) {
  for (const ClaimedPdf claims : {ClaimedPdf::visible_normals, ClaimedPdf::ndf_cosine, ClaimedPdf::bounded_reflection}) {
    int references = 0;
    for (const SamplerInfo& s : sampler_registry()) {
      if (!s.reference || s.claims != claims) continue;
      ++references;
      EXPECT_FALSE(s.negative_control) << s.name;
    }
    EXPECT_EQ(references, 1);
    EXPECT_EQ(reference_sampler(claims).claims, claims);
  }
  EXPECT_EQ(reference_sampler(ClaimedPdf::visible_normals).name, "heitz2018");
  EXPECT_EQ(reference_sampler(ClaimedPdf::ndf_cosine).name, "ndf");
  // Samplers that claim the same density share its function (and so one reference in `validate --all`).
  for (const SamplerInfo& s : sampler_registry())
    EXPECT_EQ(s.claimed_pdf, reference_sampler(s.claims).claimed_pdf) << s.name;
}

// The stability bound follows the returned-pdf trait of the row's sampler, not its name.
TEST(SamplerTraits, StabilityBoundFollowsTheReturnedPdfTrait) {
  StabilityMetrics row;
  row.subject = "a-renamed-bounded-sampler";
  row.is_sampler = true;
  row.regime = StabilityRegime::grazing;
  row.returned_pdf_check = ReturnedPdfCheck::except_near_back_reflection;
  EXPECT_TRUE(stability_bound(row).claimed_unverifiable_at_u_ends);
  row.returned_pdf_check = ReturnedPdfCheck::everywhere;
  row.subject = "bounded2023";
  EXPECT_FALSE(stability_bound(row).claimed_unverifiable_at_u_ends);
  row.returned_pdf_check = ReturnedPdfCheck::except_near_back_reflection;
  row.regime = StabilityRegime::moderate;
  EXPECT_FALSE(stability_bound(row).claimed_unverifiable_at_u_ends);
}

// ---- the assembly registry's traits ---------------------------------------------------------------------

TEST(AssemblyTraits, NamesAndReferenceNdfsComeFromTheRegistry) {
  EXPECT_EQ(microgeom::assembly_names(","), "smith,beckmann,mixture,sorted,spikes");
  EXPECT_EQ(ndf_kind_from_string("ggx"), NdfKind::ggx);
  EXPECT_EQ(ndf_kind_from_string("beckmann"), NdfKind::beckmann);
  EXPECT_FALSE(ndf_kind_from_string("GGX").has_value());
  EXPECT_FALSE(ndf_kind_from_string("").has_value());
}

// "spikes" is "sorted" turned upside down: the same recipe with the upside_down trait, height for height.
TEST(AssemblyTraits, UpsideDownNegatesTheHeightsOfTheSameRecipe) {
  const auto* sorted = microgeom::find_assembly("sorted");
  const auto* spikes = microgeom::find_assembly("spikes");
  ASSERT_TRUE(sorted && spikes);
  EXPECT_EQ(spikes->shaping, sorted->shaping);
  EXPECT_EQ(spikes->reference, sorted->reference);
  EXPECT_TRUE(spikes->upside_down);
  EXPECT_FALSE(sorted->upside_down);
  microgeom::AssemblyParams p;
  p.resolution = 64;
  p.alpha_x = p.alpha_y = 0.4;
  p.seed = 5;
  p.assembly = "sorted";
  const microgeom::Heightfield a = microgeom::build_assembly(p);
  p.assembly = "spikes";
  const microgeom::Heightfield b = microgeom::build_assembly(p);
  ASSERT_EQ(a.heights().size(), b.heights().size());
  for (std::size_t k = 0; k < a.heights().size(); ++k) ASSERT_EQ(b.heights()[k], -a.heights()[k]) << k;
}

// ---- the battery ----------------------------------------------------------------------------------------

// validate and compare report the same tests under the same names: one chi-square test per binning, then
// the checks; the report is looked up by name, and an unknown name is an error, not a default.
TEST(Battery, ValidateAndCompareReportTheSameTests) {
  const SamplerInfo& s = reference_sampler(ClaimedPdf::visible_normals);
  const GGX<double> ggx(0.5);
  const Vec3<double> wi = direction_from_degrees(30.0, 0.0);
  ValidationOptions o;
  o.samples = 20'000;
  o.rows = 9;
  const ValidationReport analytic = validate_sampler(s, ggx, wi, o);
  OracleTraceOptions t;
  t.rays = 200'000;
  t.rows = 9;
  const ValidationReport oracle = compare_sampler_to_trace(s, ggx, wi, o, trace_vndf_histogram(ggx, wi, t));
  for (const ValidationReport* r : {&analytic, &oracle}) {
    ASSERT_EQ(r->binned.size(), 2u);
    EXPECT_EQ(r->binned[0].name, "chi2_sphere");
    EXPECT_EQ(r->binned[0].binning, "sphere");
    EXPECT_EQ(r->binned[1].name, "chi2_lobe");
    EXPECT_EQ(r->binned[1].binning, "lobe");
    // The comparison with a traced oracle adds the statement of its reference's bias (compare.h).
    const bool traced = r == &oracle;
    ASSERT_EQ(r->checks.size(), traced ? 5u : 4u);
    const char* names[] = {"domain", "pdf_integral", "returned_pdf", "weight_mean", "reference_bias"};
    for (std::size_t k = 0; k < r->checks.size(); ++k) EXPECT_EQ(r->checks[k].name, names[k]);
    EXPECT_EQ(r->histograms.size(), 2u);
    EXPECT_EQ(&r->chi2("lobe"), &r->binned[1].chi2);
    EXPECT_THROW(r->chi2("hemisphere"), std::out_of_range);
    EXPECT_THROW(r->check("weight"), std::out_of_range);
    EXPECT_TRUE(r->passed) << r->sampler;
  }
  EXPECT_EQ(analytic.statistical_tests, 3);  // two binnings and E[weight]
  EXPECT_EQ(oracle.statistical_tests, 2);    // two binnings
  EXPECT_FALSE(oracle.check("weight_mean").applicable);
  EXPECT_EQ(oracle.binned[0].chi2.test, "two_sample_homogeneity");
  EXPECT_EQ(analytic.binned[0].chi2.test, "goodness_of_fit");
}

// The verdict: Sidak over the statistical tests, failures in the order hard checks, binned tests,
// statistical checks; the headline among equal p-values by the one stated rule (the last binning's).
TEST(Battery, DecideCombinesListsAndBreaksTiesAsStated) {
  const battery::Tally tally;
  ValidationOptions o;
  o.significance = 0.01;
  ValidationReport r = battery::report_header(no_samples(), SampleDomain::microfacet_normal, GGX<double>(0.5),
                                              Vec3<double>(0, 0, 1), tally, o);
  ChiSquareResult a, b;
  a.p_value = b.p_value = 0;
  a.statistic = 10;
  a.dof = 3;
  b.statistic = 20;
  b.dof = 7;
  r.binned = {{"chi2_sphere", "sphere", "chi-square", a}, {"chi2_lobe", "lobe", "chi-square", b}};
  SubTest hard;
  hard.name = "domain";
  hard.passed = false;
  hard.detail = "3 sample(s) outside";
  SubTest statistical;
  statistical.name = "weight_mean";
  statistical.label = "E[weight]";
  statistical.statistical = true;
  statistical.p_value = 0.5;
  statistical.detail = "fine";
  r.checks = {statistical, hard};
  ValidationReport last = r;
  battery::decide(last);
  EXPECT_EQ(last.statistic, 20);
  EXPECT_EQ(last.dof, 7);
  EXPECT_EQ(last.statistical_tests, 3);
  EXPECT_DOUBLE_EQ(last.per_test_significance, sidak_significance(0.01, 3));
  EXPECT_TRUE(last.checks[0].passed);
  ASSERT_EQ(last.failures.size(), 3u);
  EXPECT_EQ(last.failures[0], "3 sample(s) outside");
  EXPECT_EQ(last.failures[1].rfind("chi-square in sphere bins rejects: p = 0 <", 0), 0u) << last.failures[1];
  EXPECT_EQ(last.failures[2].rfind("chi-square in lobe bins rejects", 0), 0u) << last.failures[2];
  EXPECT_FALSE(last.passed);
  ValidationReport empty = r;
  empty.binned.clear();
  EXPECT_THROW(battery::decide(empty), std::invalid_argument);
}

// One headline rule for validate and compare: a negative control rejected with p = 0 in both binnings
// reports the lobe bins' statistic and dof, against the analytic pdf and against the traced oracle alike
// (the comparison with the oracle used to take the sphere bins').
TEST(Battery, ValidateAndCompareBreakTiesAlike) {
  const SamplerInfo* talk = find_sampler("heitz2018-talk");
  ASSERT_NE(talk, nullptr);
  ASSERT_TRUE(talk->negative_control);
  const GGX<double> ggx(0.5);
  const Vec3<double> wi = direction_from_degrees(70.0, 0.0);
  ValidationOptions o;
  o.samples = 200'000;
  o.rows = 9;
  const ValidationReport analytic = validate_sampler(*talk, ggx, wi, o);
  OracleTraceOptions t;
  t.rays = 400'000;
  t.rows = 9;
  const ValidationReport oracle = compare_sampler_to_trace(*talk, ggx, wi, o, trace_vndf_histogram(ggx, wi, t));
  for (const ValidationReport* r : {&analytic, &oracle}) {
    ASSERT_EQ(r->binned.size(), 2u);
    ASSERT_EQ(r->binned[0].chi2.p_value, r->binned[1].chi2.p_value) << "no tie: the case does not test the rule";
    EXPECT_NE(r->binned[0].chi2.statistic, r->binned[1].chi2.statistic);
    EXPECT_EQ(r->statistic, r->binned[1].chi2.statistic);
    EXPECT_EQ(r->dof, r->binned[1].chi2.dof);
  }
}

}  // namespace test_battery
