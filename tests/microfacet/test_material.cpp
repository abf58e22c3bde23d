// Facet materials (microfacet/material.h), refraction (core/math.h) and the per-order scattering
// histogram (stats/scatter_histogram.h).
#include "core/parse.h"
#include "core/random.h"
#include "microfacet/bsdf.h"
#include "microfacet/material.h"
#include "stats/binning.h"
#include "stats/scatter_histogram.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>

namespace microsim {
namespace {

TEST(Material, ParsesEveryKindAndRoundTrips) {
  for (const char* spec : {"mirror", "conductor:0.2,3.9", "conductor:0.2,3.9;0.5,2.4;1.5,1.9", "dielectric:1.5",
                           "dielectric:0.6666", "lambertian:0.8"}) {
    const Material m = parse_material("--material", spec);
    EXPECT_EQ(parse_material("--material", m.describe()), m) << spec;
  }
  EXPECT_EQ(parse_material("--material", "conductor:0.2,3.9;0.5,2.4;1.5,1.9").channels(), 3);
  EXPECT_EQ(parse_material("--material", "lambertian").albedo(), 1.0);
  EXPECT_TRUE(parse_material("--material", "dielectric:1.5").transmits());
}

TEST(Material, RejectsBadSpecsNamingThePart) {
  const std::pair<const char*, const char*> bad[] = {
      {"gold", "unknown material"},      {"dielectric:0", "eta"},        {"dielectric:-1.5", "eta"},
      {"dielectric:nan", "eta"},         {"dielectric:1", "eta 1"},      {"conductor:0.2,-1", "k"},
      {"conductor:0.2", "channel 1"},    {"conductor:0.2,3;", "channel 2"}, {"lambertian:1.5", "albedo"},
      {"conductor:", "unknown material"}, {"mirror:1", "unknown material"}};
  for (const auto& [spec, named] : bad) {
    try {
      parse_material("--material", spec);
      ADD_FAILURE() << spec << " was accepted";
    } catch (const ParseError& e) {
      EXPECT_NE(std::string(e.what()).find(named), std::string::npos) << spec << ": " << e.what();
    }
  }
}

TEST(Refract, ObeysSnellAndReportsTotalInternalReflection) {
  const Vec3<double> n(0, 0, 1), w = direction_from_degrees(50.0, 20.0);
  Vec3<double> t;
  ASSERT_TRUE(refract(w, n, 1.5, t));
  EXPECT_NEAR(t.norm(), 1.0, 1e-15);
  EXPECT_LT(t.z(), 0.0);
  EXPECT_NEAR(sin_theta(t) * 1.5, sin_theta(w), 1e-14);  // n_i sin i = n_t sin t
  EXPECT_NEAR(t.x() * w.y() - t.y() * w.x(), 0.0, 1e-15);  // in the plane of incidence,
  EXPECT_LT(t.x() * w.x() + t.y() * w.y(), 0.0);             // on the far side of the normal
  EXPECT_FALSE(refract(w, n, 1.0 / 1.5, t));  // 50 deg > the critical angle 41.8 deg from inside
  EXPECT_FALSE(refract(Vec3<double>(-w), n, 1.5, t));  // w on the wrong side
}

TEST(FacetEvent, ConductorFactorsAreTheExactFresnelPerChannel) {
  const Material gold = parse_material("m", "conductor:0.18,3.4;0.42,2.35;1.37,1.77");
  const Vec3<double> m = direction_from_degrees(20.0, 0.0), wi = direction_from_degrees(60.0, 180.0);
  double f[3];
  const FacetEvent e = scatter_on_facet(gold, wi, m, false, {0.5, 0.5}, f);
  for (int c = 0; c < 3; ++c) EXPECT_EQ(f[c], fresnel_conductor(wi.dot(m), gold.ior(c)));
  EXPECT_NEAR((e.wo - reflect(wi, m)).norm(), 0.0, 1e-15);
  EXPECT_FALSE(e.refracted);
}

// The dielectric chooses reflection with probability F: over 200 000 events with counter-based uniforms
// the reflected fraction is within 5 standard errors of F (a 5-sigma band: a false alarm ~ 6e-7), on both
// sides; a choice made with 1 - F instead (the negative control) lies far outside the band.
TEST(FacetEvent, DielectricReflectsWithTheFresnelProbabilityFromEitherSide) {
  const Material glass = Material::dielectric(1.5);
  const Vec3<double> m(0, 0, 1);
  for (const bool inside : {false, true}) {
    const Vec3<double> wi = direction_from_degrees(inside ? 35.0 : 70.0, 10.0);
    const double F = fresnel_dielectric(wi.z(), inside ? 1.0 / 1.5 : 1.5);
    CounterRng rng(7, inside);
    const int n = 200000;
    int reflected = 0;
    double f[1];
    for (int i = 0; i < n; ++i) {
      const FacetEvent e = scatter_on_facet(glass, wi, m, inside, {rng.uniform(), rng.uniform()}, f);
      EXPECT_EQ(f[0], 1.0);
      reflected += !e.refracted;
      if (e.refracted) {
        ASSERT_LT(e.wo.z(), 0.0);
      }
    }
    const double p = double(reflected) / n, se = std::sqrt(F * (1 - F) / n);
    EXPECT_NEAR(p, F, 5 * se) << "inside " << inside;
    EXPECT_GT(std::abs(p - (1 - F)), 5 * se) << "negative control";
  }
}

// Lambertian facet: cosine-distributed about m, so E[cos] = 2/3 and cos^2 is uniform (5-sigma bands).
TEST(FacetEvent, LambertianIsCosineDistributedAboutTheNormal) {
  const Material white = Material::lambertian(0.7);
  const Vec3<double> m = direction_from_degrees(30.0, 45.0), wi = direction_from_degrees(10.0, 0.0);
  CounterRng rng(3, 0);
  const int n = 100000;
  double sum = 0, sum2 = 0, f[1];
  for (int i = 0; i < n; ++i) {
    const FacetEvent e = scatter_on_facet(white, wi, m, false, {rng.uniform(), rng.uniform()}, f);
    ASSERT_EQ(f[0], 0.7);
    const double c = e.wo.dot(m);
    ASSERT_GE(c, 0.0);
    sum += c;
    sum2 += c * c;
  }
  const double mean = sum / n, var = sum2 / n - mean * mean;
  EXPECT_NEAR(mean, 2.0 / 3.0, 5 * std::sqrt(var / n));
  EXPECT_NEAR(sum2 / n, 0.5, 5 * std::sqrt(1.0 / 12.0 / n));  // cos^2 is uniform on [0, 1]
  EXPECT_GT(std::abs(mean - 0.5), 10 * std::sqrt(var / n)) << "negative control: a uniform hemisphere has E[cos] = 1/2";
}

ScatterHistogram small_histogram(std::vector<std::string> channels = {"c0", "c1"}) {
  const DirectionBinning b = DirectionBinning::hemispheres(2);
  std::vector<bool> reflection(std::size_t(b.size()));
  for (int i = 0; i < b.size(); ++i) reflection[std::size_t(i)] = i < b.size() / 2;
  return ScatterHistogram(b.describe().dump(), std::size_t(b.size()), reflection, std::move(channels));
}

TEST(ScatterHistogram, AlbedoPerOrderAndSideWithItsStandardError) {
  ScatterHistogram h = small_histogram();
  h.add_launched(4);
  const double w1[] = {1.0, 0.5}, w2[] = {0.25, 0.25};
  h.add_escaped(1, 0, w1);       // reflected, order 1
  h.add_escaped(2, 20, w2);      // transmitted (lower half), order 2
  h.add_escaped(7, 1, w1);       // order 7 goes to the 5+ bin
  h.add_unfinished(w2);
  const Estimate r1 = h.albedo(0, 0, ScatterSide::reflected);
  EXPECT_DOUBLE_EQ(r1.value, 0.25);
  EXPECT_DOUBLE_EQ(r1.standard_error, std::sqrt((0.25 - 0.0625) / 3.0));
  EXPECT_DOUBLE_EQ(h.albedo(0, 1, ScatterSide::transmitted).value, 0.0625);
  EXPECT_DOUBLE_EQ(h.albedo(0, 1, ScatterSide::reflected).value, 0.0);
  EXPECT_DOUBLE_EQ(h.albedo(1, scatter_order_bin(7)).value, 0.125);
  EXPECT_DOUBLE_EQ(h.albedo(0, -1).value, (1.0 + 0.25 + 1.0) / 4);
  EXPECT_DOUBLE_EQ(h.unfinished(1).value, 0.0625);
  EXPECT_EQ(mean_per_path(1.0, 1.0, 0).value, 0.0);  // no paths: 0, never NaN
}

TEST(ScatterHistogram, MergeIsExactAndRefusesOtherBinningsOrChannels) {
  ScatterHistogram a = small_histogram(), b = small_histogram(), whole = small_histogram();
  CounterRng rng(11, 0);
  for (int i = 0; i < 1000; ++i) {
    const double w[] = {rng.uniform(), rng.uniform()};
    const int order = 1 + int(8 * rng.uniform());
    const std::size_t bin = std::size_t(32 * rng.uniform());
    (i < 400 ? a : b).add_escaped(order, bin, w);
    whole.add_escaped(order, bin, w);
  }
  a.add_launched(400), b.add_launched(600), whole.add_launched(1000);
  ScatterHistogram merged = b;
  merged.merge(a);
  EXPECT_TRUE(merged == whole);
  EXPECT_THROW(merged.merge(small_histogram({"R", "G"})), HistogramMergeError);
  const DirectionBinning other = DirectionBinning::hemispheres(3);
  ScatterHistogram c(other.describe().dump(), std::size_t(other.size()), std::vector<bool>(std::size_t(other.size())),
                     {"c0", "c1"});
  EXPECT_THROW(merged.merge(c), HistogramMergeError);
}

TEST(HemispheresBinning, SplitsAtTheEquatorAndRoundTripsItsDescription) {
  const DirectionBinning b = DirectionBinning::hemispheres(8);
  EXPECT_EQ(b.rows(), 16);
  EXPECT_LT(*b.bin_of(Vec3<double>(1, 0, 1e-9)), b.size() / 2);
  EXPECT_GE(*b.bin_of(Vec3<double>(1, 0, -1e-9)), b.size() / 2);
  EXPECT_EQ(DirectionBinning::from_description(b.describe()).describe(), b.describe());
  EXPECT_EQ(b.describe()["kind"], "hemispheres");
  EXPECT_THROW(DirectionBinning::sphere(16), std::invalid_argument);  // the VNDF sphere keeps odd rows
}

}  // namespace
}  // namespace microsim
