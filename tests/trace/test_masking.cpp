// Tests of the heightfield estimators (src/trace/masking.h): the leak test on every assembly up to
// 85 degrees (and its negative controls: a tracer that does not wrap, one that self-hits), determinism
// across thread counts, calibration of the standard errors, exact identities, and the traced VNDF against
// the empirical-NDF Smith VNDF at normal incidence (where a heightfield masks nothing).
#include "microgeom/assembly.h"
#include "stats/chi2.h"
#include "trace/masking.h"
#include "core/random.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <memory>

namespace microsim {
namespace {

constexpr double kLeakSigmas = 4.0;  // the leak test's threshold (as in `trace masking`)

struct Surface {
  microgeom::Heightfield field;
  std::unique_ptr<HeightfieldScene> scene;
  std::unique_ptr<EmpiricalSmith> empirical;
  std::unique_ptr<AnalyticSmith> analytic;
};

// Small surfaces, built once per (assembly, alpha): 128^2, correlation length 8 cells.
const Surface& surface(const std::string& assembly, double alpha) {
  static std::map<std::pair<std::string, double>, std::unique_ptr<Surface>> cache;
  auto& slot = cache[{assembly, alpha}];
  if (!slot) {
    microgeom::AssemblyParams p;
    p.assembly = assembly;
    p.alpha_x = p.alpha_y = alpha;
    p.resolution = 128;
    p.seed = 7;
    slot = std::make_unique<Surface>(Surface{microgeom::build_assembly(p), nullptr, nullptr, nullptr});
    slot->scene = std::make_unique<HeightfieldScene>(slot->field);
    slot->empirical = std::make_unique<EmpiricalSmith>(slot->field);
    slot->analytic = std::make_unique<AnalyticSmith>(analytic_reference(slot->field));
  }
  return *slot;
}

MaskingOptions quiet(std::uint64_t samples, std::uint64_t seed = 1) {
  MaskingOptions o;
  o.samples = samples;
  o.seed = seed;
  return o;
}

// The weighted visible fraction over cos(theta_v) is 1 on any heightfield: on every assembly, at views up
// to 85 degrees, within kLeakSigmas standard errors, with no leaked ray. The standard error is required
// to be small (<= 1.5%) so that the test has power.
TEST(MaskingLeak, EveryAssemblyUpTo85Degrees) {
  for (const auto& info : microgeom::assembly_registry()) {
    for (double alpha : {0.1, 0.5, 1.0}) {
      const Surface& s = surface(info.name, alpha);
      for (double theta : {0.0, 45.0, 75.0, 85.0}) {
        if (alpha != 0.5 && theta != 85.0) continue;  // every angle at 0.5, the hardest angle at all alphas
        MaskingOptions o = quiet(60'000, 3);
        o.mirror = false;
        const Vec3<double> v = direction_from_degrees(theta, 30.0);
        const MaskingResult r = estimate_masking(*s.scene, *s.analytic, *s.empirical, v, o);
        const std::string line = fmt::format("{} alpha {} theta {}: leak ratio {:.5f} +- {:.5f} ({:+.2f} SE)", info.name,
                                             alpha, theta, r.leak_ratio.value, r.leak_ratio.standard_error,
                                             (r.leak_ratio.value - 1.0) / r.leak_ratio.standard_error);
        std::printf("  %s\n", line.c_str());
        SCOPED_TRACE(line);
        EXPECT_EQ(r.leaked, 0u);
        EXPECT_EQ(r.unresolved, 0u);
        EXPECT_LE(r.leak_ratio.standard_error, 0.015);
        EXPECT_LE(std::abs(r.leak_ratio.value - 1.0), kLeakSigmas * r.leak_ratio.standard_error + 1e-12);
        // Scalar G1 equals the empirical-NDF Smith G1 (the same statement, through the ratio estimator).
        EXPECT_LE(std::abs(r.g1.value - r.g1_smith_empirical), kLeakSigmas * r.g1.standard_error + 1e-12);
      }
    }
  }
}

// The leak statistic detects broken tracers (negative controls, computed here with raw Embree calls on
// the same scene): (a) no wrap-around (a ray leaving the tile counts as escaped) -> visible fraction too
// large; (b) no lift and no skip of the start triangle -> self-hits, visible fraction too small.
TEST(MaskingLeak, NegativeControlsFail) {
  const Surface& s = surface("smith", 0.5);
  const auto& f = s.field;
  const Vec3<double> v = direction_from_degrees(75.0, 30.0);
  const Vec3<float> vf = v.cast<float>();
  const HeightfieldScene embree_triangles(f, HeightfieldGeometry::triangles);  // (a) calls Embree itself
  const auto& es = embree_triangles.embree_scene();
  embree::FlushDenormalsScope ftz;
  double sum_good = 0, sum_nowrap = 0, sum_selfhit = 0, sq_good = 0, sq_nowrap = 0, sq_selfhit = 0;
  const int n = 40'000;
  CounterRng rng(5, 0);
  for (int i = 0; i < n; ++i) {
    const double x = rng.uniform(), y = rng.uniform();
    const auto tri = f.triangle_at(x, y);
    const Vec3<double> m = f.triangle_normal(tri);
    const double w = std::max(v.dot(m), 0.0) / m.z();
    if (!(w > 0)) continue;
    const Vec3<double> p(x, y, f.height_at(x, y));
    const double good = s.scene->escapes(p, v, tri) ? w : 0.0;
    // (a) lifted start, skip by... nothing needed (the lift avoids self-hits): one unclipped Embree call,
    // no wrapping: whatever leaves the tile's geometry escapes.
    const Vec3<float> lifted = s.scene->lifted(p, tri).cast<float>();
    const double nowrap = es.occluded(lifted, vf, 0.0f, std::numeric_limits<float>::infinity()) ? 0.0 : w;
    // (b) wrapped correctly but from the float-rounded start point itself, no lift, and the start
    // triangle not skipped: emulate by starting slightly below the facet (1e-4 cells) as float rounding
    // does for about half the points at N = 4096.
    const Vec3<double> below = p - 1e-4 * f.cell_size() * m;
    const double selfhit = s.scene->trace(below, v).is_hit() ? 0.0 : w;
    sum_good += good, sq_good += good * good;
    sum_nowrap += nowrap, sq_nowrap += nowrap * nowrap;
    sum_selfhit += selfhit, sq_selfhit += selfhit * selfhit;
  }
  auto ratio = [&](double sum, double sq) {
    const double mean = sum / n, se = std::sqrt(std::max(sq / n - mean * mean, 0.0) / (n - 1));
    return std::pair<double, double>(mean / v.z(), se / v.z());
  };
  const auto [g, gse] = ratio(sum_good, sq_good);
  const auto [a, ase] = ratio(sum_nowrap, sq_nowrap);
  const auto [b, bse] = ratio(sum_selfhit, sq_selfhit);
  EXPECT_LE(std::abs(g - 1.0), kLeakSigmas * gse) << g << " +- " << gse;
  EXPECT_GT(a - 1.0, kLeakSigmas * ase) << "no-wrap tracer not detected: " << a << " +- " << ase;
  EXPECT_GT(1.0 - b, kLeakSigmas * bse) << "self-hitting tracer not detected: " << b << " +- " << bse;
}

TEST(Masking, DeterministicWhateverTheThreadCount) {
  const Surface& s = surface("mixture", 0.5);
  MaskingOptions o = quiet(20'000, 9);
  o.light = direction_from_degrees(50.0, 200.0);
  const Vec3<double> v = direction_from_degrees(70.0, 30.0);
  o.run.threads = 1;
  const MaskingResult a = estimate_masking(*s.scene, *s.analytic, *s.empirical, v, o);
  o.run.threads = 2;
  const MaskingResult b = estimate_masking(*s.scene, *s.analytic, *s.empirical, v, o);
  EXPECT_EQ(a.rays, b.rays);
  EXPECT_EQ(a.leak_ratio.value, b.leak_ratio.value);
  EXPECT_EQ(a.g1.value, b.g1.value);
  EXPECT_EQ(a.g1.standard_error, b.g1.standard_error);
  for (std::size_t k = 0; k < a.by_normal.size(); ++k) EXPECT_EQ(a.by_normal[k].ratio.value, b.by_normal[k].ratio.value);
  for (std::size_t k = 0; k < a.by_height.size(); ++k) EXPECT_EQ(a.by_height[k].g1.value, b.by_height[k].g1.value);
  EXPECT_EQ(a.mirror->value.value, b.mirror->value.value);
  EXPECT_EQ(a.pair->value.value, b.pair->value.value);
  // The VNDF histogram too.
  const std::vector<DirectionBinning> bins = {DirectionBinning::sphere(9)};
  TraceOptions t;
  t.rays = 30'000;
  t.run.threads = 1;
  const TraceResult va = trace_vndf_heightfield(*s.scene, v, bins, t);
  t.run.threads = 2;
  const TraceResult vb = trace_vndf_heightfield(*s.scene, v, bins, t);
  EXPECT_EQ(va.counts, vb.counts);
}

// Identities: the light along v gives G2(v, v) = G1(v) exactly (the same shadow ray twice); the bins of
// <v, m> and of height partition the samples (their weighted G1 average is G1); the normal bins hold
// equal exact shares.
TEST(Masking, Identities) {
  const Surface& s = surface("sorted", 0.5);
  const Vec3<double> v = direction_from_degrees(60.0, 30.0);
  MaskingOptions o = quiet(20'000, 4);
  o.light = v;
  const MaskingResult r = estimate_masking(*s.scene, *s.analytic, *s.empirical, v, o);
  EXPECT_NEAR(r.pair->value.value, r.g1.value, 1e-12);
  double weighted = 0, share = 0;
  for (const auto& b : r.by_height) weighted += b.share * b.g1.value, share += b.share;
  EXPECT_NEAR(share, 1.0, 1e-12);
  EXPECT_NEAR(weighted, r.g1.value, 1e-12);
  for (const auto& b : r.by_normal) EXPECT_NEAR(b.share, 0.1, 0.002);
  EXPECT_EQ(r.by_normal.front().lo, 0.0);
  EXPECT_EQ(r.by_normal.back().hi, 1.0);
  // The fine near-grazing class: the bottom 2% of the projected area (exact share, to one facet's weight),
  // inside the first decile, its samples a subset of the decile's.
  EXPECT_EQ(r.near_grazing.lo, 0.0);
  EXPECT_GT(r.near_grazing.hi, 0.0);
  EXPECT_LT(r.near_grazing.hi, r.by_normal.front().hi);
  EXPECT_NEAR(r.near_grazing.share, 0.02, 0.001);
  EXPECT_GE(r.near_grazing.share, 0.02);
  EXPECT_LE(r.near_grazing.samples, r.by_normal.front().samples);
  EXPECT_GT(r.near_grazing.samples, 200u);  // ~2% of 20 000
  EXPECT_LT(r.near_grazing.samples, 600u);
  MaskingOptions bad = quiet(10);
  for (double share : {0.0, 1.0, -0.1, std::nan("")}) {
    bad.grazing_share = share;
    EXPECT_THROW(estimate_masking(*s.scene, *s.analytic, *s.empirical, v, bad), std::invalid_argument) << share;
  }
  // Both samplings estimate the same thing: uniform (x, y) with weights agrees with the projected-area
  // sampling within their standard errors (at 60 degrees, where the uniform weights are still tame).
  MaskingOptions u = quiet(60'000, 8);
  u.sampling = PointSampling::uniform;
  const MaskingResult ru = estimate_masking(*s.scene, *s.analytic, *s.empirical, v, u);
  const MaskingResult rp = estimate_masking(*s.scene, *s.analytic, *s.empirical, v, quiet(60'000, 8));
  EXPECT_LE(std::abs(ru.g1.value - rp.g1.value), 4 * std::hypot(ru.g1.standard_error, rp.g1.standard_error));
  EXPECT_LE(std::abs(ru.leak_ratio.value - 1.0), kLeakSigmas * ru.leak_ratio.standard_error);
  EXPECT_LE(std::abs(ru.mirror->value.value - rp.mirror->value.value), 4 * std::hypot(ru.mirror->value.standard_error, rp.mirror->value.standard_error));
  EXPECT_LT(rp.g1.standard_error, ru.g1.standard_error);  // the point of sampling by projected area
}

// The standard errors are calibrated: over 24 independent seeds the z-scores of G1, of the facing-bin
// ratio, of the near-grazing (2%) ratio and of the mirror G2 against their pooled mean have a chi-square consistent with 23 degrees of
// freedom (two-sided 0.1% bounds: 7.5 .. 51.2).
TEST(Masking, StandardErrorsAreCalibrated) {
  const Surface& s = surface("beckmann", 0.5);
  const Vec3<double> v = direction_from_degrees(70.0, 30.0);
  const int seeds = 24;
  std::vector<MaskingResult> runs;
  for (int k = 0; k < seeds; ++k) runs.push_back(estimate_masking(*s.scene, *s.analytic, *s.empirical, v, quiet(8'000, 100 + k)));
  auto chi2 = [&](auto get) {
    double mean = 0;
    for (const auto& r : runs) mean += get(r).value / seeds;
    double c = 0;
    for (const auto& r : runs) c += sqr((get(r).value - mean) / get(r).standard_error);
    return c * seeds / (seeds - 1);  // the pooled mean uses one degree of freedom
  };
  const double c_g1 = chi2([](const MaskingResult& r) { return r.g1; });
  const double c_facing = chi2([](const MaskingResult& r) { return r.by_normal.back().ratio; });
  const double c_near = chi2([](const MaskingResult& r) { return r.near_grazing.ratio; });
  const double c_g2 = chi2([](const MaskingResult& r) { return r.mirror->value; });
  for (double c : {c_g1, c_facing, c_near, c_g2}) {
    EXPECT_GT(c, 7.5);
    EXPECT_LT(c, 51.2);
  }
  // Negative control: the near-grazing ratio's standard error halved would not pass (the test has power).
  const double c_near_halved = chi2([](const MaskingResult& r) { return Estimate{r.near_grazing.ratio.value, 0.5 * r.near_grazing.ratio.standard_error}; });
  EXPECT_GT(c_near_halved, 51.2);
}

// At normal incidence a heightfield masks nothing: the traced VNDF is exactly the empirical-NDF VNDF,
// D(m) mz. Chi-square p > 0.01 (fixed seed). Negative control: at 75 degrees on the `spikes` surface the
// traced VNDF is distinguishable from the empirical Smith VNDF (masking is not Smith's there).
TEST(MaskingVndf, NormalIncidenceIsTheEmpiricalNdf) {
  const Surface& s = surface("smith", 0.5);
  const Vec3<double> v(0, 0, 1);
  const std::vector<DirectionBinning> bins = {
      DirectionBinning::lobe(GGX<double>(0.5), v, SampleDomain::microfacet_normal, 8)};
  TraceOptions t;
  t.rays = 200'000;
  HeightfieldVndfDiagnostics d;
  const TraceResult r = trace_vndf_heightfield(*s.scene, v, bins, t, &d);
  EXPECT_EQ(r.hits, r.rays);
  EXPECT_EQ(d.backfacing + d.leaked + d.unresolved, 0u);
  const VndfComparison c = compare_vndf(r.counts[0], r.unbinned[0], bins[0], v, *s.analytic, *s.empirical);
  EXPECT_GT(c.p_value_empirical, 0.01) << c.chi2_empirical << " dof " << c.dof_empirical;
  EXPECT_LT(c.tv_empirical, 2.0 * c.tv_noise);

  const Surface& sp = surface("spikes", 0.5);
  const Vec3<double> w = direction_from_degrees(75.0, 30.0);
  const std::vector<DirectionBinning> wb = {
      DirectionBinning::lobe(GGX<double>(0.5), w, SampleDomain::microfacet_normal, 8)};
  const TraceResult rw = trace_vndf_heightfield(*sp.scene, w, wb, t);
  const VndfComparison cw = compare_vndf(rw.counts[0], rw.unbinned[0], wb[0], w, *sp.analytic, *sp.empirical);
  EXPECT_LT(cw.p_value_empirical, 1e-6);
  EXPECT_GT(cw.tv_empirical, 3.0 * cw.tv_noise);
}

TEST(Masking, BadInputThrows) {
  const Surface& s = surface("smith", 0.5);
  EXPECT_THROW(estimate_masking(*s.scene, *s.analytic, *s.empirical, Vec3<double>(1, 0, 0), quiet(10)), std::invalid_argument);
  EXPECT_THROW(estimate_masking(*s.scene, *s.analytic, *s.empirical, Vec3<double>(0, 0, 1), quiet(0)), std::invalid_argument);
  MaskingOptions o = quiet(10);
  o.light = Vec3<double>(0, 0, -1);
  EXPECT_THROW(estimate_masking(*s.scene, *s.analytic, *s.empirical, Vec3<double>(0, 0, 1), o), std::invalid_argument);
  const std::vector<DirectionBinning> bins = {DirectionBinning::sphere(3)};
  TraceOptions t;
  t.rays = 0;
  EXPECT_THROW(trace_vndf_heightfield(*s.scene, Vec3<double>(0, 0, 1), bins, t), std::invalid_argument);
  t.rays = 10;
  EXPECT_THROW(trace_vndf_heightfield(*s.scene, Vec3<double>(0, 1, 0), bins, t), std::invalid_argument);
}

}  // namespace
}  // namespace microsim
