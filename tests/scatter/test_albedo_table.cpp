// Energy-compensation tables (scatter/albedo_table.h): the analytic single-scattering albedo against the
// published values and against an independent computation (the sum of
// the bins of analytic_single_scattering: cubature over wo, not over the visible normals), its error
// estimate against the error it makes; the Gauss-Legendre grid; the Smith walk's furnace (mirror: every
// path leaves, E = 1; dielectric: R + T = 1) and its order 1 against the analytic table (chi-square over
// the cells at level 1e-3, fixed seeds, with negative controls: a table at another alpha or eta must be
// rejected); the explicit surface's furnace; determinism, cancellation and the request's checks.
#include "scatter/albedo_table.h"

#include "microfacet/bsdf.h"

#include "core/parse.h"
#include "scatter/albedo_table_io.h"
#include "scatter/analytic_scatter.h"

#include <boost/math/distributions/chi_squared.hpp>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <sstream>

namespace microsim {
namespace {

constexpr double kLevel = 1e-3;  // significance level of every chi-square test here

SingleScatteringAlbedo ggx_albedo(double alpha, const Material& m, double mu, bool inside = false,
                                  double tolerance = 1e-10) {
  return single_scattering_albedo(GGX<double>(alpha), m, 0, albedo_view(mu, inside), tolerance);
}

// ---- the mu grid ---------------------------------------------------------------------------------------------

TEST(AlbedoGrid, GaussLegendreIsExactToDegreeTwoNMinusOneAndNoFurther) {
  for (const int n : {2, 3, 7, 16, 64}) {
    const MuGrid g = gauss_legendre_mus(n);
    ASSERT_EQ(int(g.mus.size()), n);
    for (int i = 0; i < n; ++i) {
      EXPECT_GT(g.mus[std::size_t(i)], 0.0);
      EXPECT_LT(g.mus[std::size_t(i)], 1.0);
      if (i > 0) {
        EXPECT_GT(g.mus[std::size_t(i)], g.mus[std::size_t(i - 1)]);
      }
    }
    const auto moment = [&](int k) {
      double s = 0;
      for (int i = 0; i < n; ++i) s += g.weights[std::size_t(i)] * std::pow(g.mus[std::size_t(i)], k);
      return s;
    };
    for (int k = 0; k <= 2 * n - 1; ++k) EXPECT_NEAR(moment(k), 1.0 / (k + 1), 1e-13) << "n " << n << " degree " << k;
    if (n <= 7) {
      EXPECT_GT(std::abs(moment(2 * n) - 1.0 / (2 * n + 1)), 1e-12) << "n " << n << ": degree 2n is not exact";
    }
  }
}

// ---- the analytic single scattering --------------------------------------------------------------------------

// Published values (oracle.md sec. 6, three decimals); microsim's cubature gives 0.306853 at mu 1, alpha 1.
TEST(AlbedoAnalytic, MirrorGgxIsThePublishedSingleScatteringAlbedo) {
  const Material mirror = Material::mirror();
  EXPECT_NEAR(ggx_albedo(1.0, mirror, 1.0).total().value, 0.306853, 2e-6);
  EXPECT_NEAR(ggx_albedo(1.0, mirror, 0.5).total().value, 0.451, 6e-4);
  EXPECT_NEAR(ggx_albedo(0.5, mirror, 1.0).total().value, 0.688, 6e-4);
  EXPECT_NEAR(ggx_albedo(0.5, mirror, 0.5).total().value, 0.698, 6e-4);
  // Small alpha: E near 1 (the GGX tail still sends a little below the horizon at grazing views).
  for (const double mu : {1.0, 0.5}) EXPECT_GT(ggx_albedo(0.02, mirror, mu).total().value, 0.998) << mu;
  EXPECT_GT(ggx_albedo(0.02, mirror, 0.2).total().value, 0.99);
  EXPECT_NEAR(ggx_albedo(1.0, mirror, 0.5).transmitted.value, 0.0, 0.0) << "a mirror transmits nothing";
}

TEST(AlbedoAnalytic, MirrorGgxAverageIsThePublishedOne) {
  AlbedoTableRequest r;
  r.alphas = {0.5, 1.0};
  r.mus = 16;
  const AlbedoTable t = albedo_table(r);
  ASSERT_EQ(t.quantities.size(), 1u);
  EXPECT_EQ(t.quantities[0].name, "E1");
  EXPECT_NEAR(t.quantities[0].average[0].value, 0.700, 1e-3);
  EXPECT_NEAR(t.quantities[0].average[1].value, 0.409, 1e-3);
  EXPECT_FALSE(t.partial);
}

// The independent computation: cubature over wo in the hemispheres binning, bins summed per side.
void expect_matches_binned(double alpha, const Material& m, double mu, bool inside) {
  const SingleScatteringAlbedo a = ggx_albedo(alpha, m, mu, inside);
  const ScatterExpectation e = analytic_single_scattering(GGX<double>(alpha), albedo_view(mu, inside), m, 2);
  double up = 0, down = 0;
  for (std::size_t b = 0; b < e.bins(); ++b) (e.reflection_bins[b] ? up : down) += e.order1[0][b];
  const double reflected = inside ? down : up, transmitted = inside ? up : down;
  const double tolerance = 2e-6 + e.error_estimate[0];
  EXPECT_NEAR(a.reflected.value, reflected, tolerance + a.reflected.standard_error)
      << m.describe() << " alpha " << alpha << " mu " << mu << (inside ? " inside" : "");
  EXPECT_NEAR(a.transmitted.value, transmitted, tolerance + a.transmitted.standard_error)
      << m.describe() << " alpha " << alpha << " mu " << mu << (inside ? " inside" : "");
}

TEST(AlbedoAnalytic, MatchesTheBinnedCubatureOverOutgoingDirections) {
  for (const double alpha : {0.2, 1.0})
    for (const double mu : {0.9, 0.08}) {
      expect_matches_binned(alpha, Material::mirror(), mu, false);
      expect_matches_binned(alpha, Material::dielectric(1.5), mu, false);
      expect_matches_binned(alpha, Material::dielectric(1.5), mu, true);
    }
}

TEST(AlbedoAnalytic, BeckmannMatchesTheBinnedCubatureAndIsNotGgx) {
  for (const double mu : {0.9, 0.3}) {
    const Vec3<double> wi = albedo_view(mu, false);
    const SingleScatteringAlbedo a = single_scattering_albedo(Beckmann<double>(0.6), Material::mirror(), 0, wi, 1e-10);
    const ScatterExpectation e = analytic_single_scattering(Beckmann<double>(0.6), wi, Material::mirror(), 2);
    double sum = 0;
    for (const double x : e.order1[0]) sum += x;
    EXPECT_NEAR(a.reflected.value, sum, 2e-6 + e.error_estimate[0]) << mu;
    EXPECT_GT(std::abs(a.reflected.value - ggx_albedo(0.6, Material::mirror(), mu).reflected.value), 1e-3) << mu;
  }
}

// The Beckmann mirror in its visible slopes (beckmann_mirror_split) against the sampler-square quadrature of
// single_scattering_albedo (another parametrisation, with its kinks searched for), both channels of the split
// weighted alike; and its error estimate against a much tighter run of itself (the loose run's error is not
// zero, so the comparison can fail: the negative control).
TEST(AlbedoAnalytic, BeckmannMirrorInItsVisibleSlopesIsTheSamplerQuadraturesAndItsErrorIsCovered) {
  for (const auto& [alpha, mu] : {std::pair{0.05, 0.1}, std::pair{0.5, 0.7}, std::pair{1.5, 0.3}}) {
    const SchlickSplitAlbedo fast = beckmann_mirror_split(alpha, mu, 1e-10);
    const SingleScatteringAlbedo general =
        single_scattering_albedo(Beckmann<double>(alpha), Material::mirror(), 0, albedo_view(mu, false), 1e-10);
    EXPECT_NEAR(fast.unit.value, general.reflected.value, 1e-9) << alpha << " " << mu;
    EXPECT_GT(fast.grazing.value, 0.0);
    EXPECT_LT(fast.grazing.value, fast.unit.value);
  }
  double made = 0;
  for (const double alpha : {1e-3, 0.05, 0.3, 1.0, 2.0})
    for (const double mu : {0.02, 0.2, 0.6, 0.95, 1.0}) {
      const SchlickSplitAlbedo loose = beckmann_mirror_split(alpha, mu, 1e-5);
      const SchlickSplitAlbedo tight = beckmann_mirror_split(alpha, mu, 1e-12);
      const double u = std::abs(loose.unit.value - tight.unit.value);
      const double g = std::abs(loose.grazing.value - tight.grazing.value);
      EXPECT_LE(u, loose.unit.standard_error) << alpha << " " << mu;
      EXPECT_LE(g, loose.grazing.standard_error) << alpha << " " << mu;
      EXPECT_LE(loose.unit.standard_error, 1e-5) << alpha << " " << mu;
      EXPECT_LE(tight.unit.standard_error, 1e-11) << alpha << " " << mu;
      made += u + g;
    }
  EXPECT_GT(made, 0.0);
  EXPECT_THROW(beckmann_mirror_split(0.5, 0.0, 1e-6), std::invalid_argument);
}

// The error estimate is realistic: a loose tolerance's result is within 3 times its stated error of a tight
// one (the estimate is Kronrod - Gauss, not a bound: docs/records/scattering.md measured it exceeded by at most 2.4 times
// over 177 cells x 2 sides), and a tight run's error is small. Negative control: the loose run's error is not
// zero, so the comparison can fail.
TEST(AlbedoAnalytic, ErrorEstimateCoversTheErrorMade) {
  for (const double alpha : {0.05, 0.5, 1.5})
    for (const double mu : {0.9, 0.1}) {
      const Material glass = Material::dielectric(1.5);
      const SingleScatteringAlbedo loose = ggx_albedo(alpha, glass, mu, true, 1e-4);
      const SingleScatteringAlbedo tight = ggx_albedo(alpha, glass, mu, true, 1e-11);
      const double r = std::abs(loose.reflected.value - tight.reflected.value);
      const double t = std::abs(loose.transmitted.value - tight.transmitted.value);
      EXPECT_LE(r, 3 * loose.reflected.standard_error) << alpha << " " << mu;
      EXPECT_LE(t, 3 * loose.transmitted.standard_error) << alpha << " " << mu;
      EXPECT_GT(r + t, 0.0) << alpha << " " << mu;
      EXPECT_LE(tight.total().standard_error, 1e-10) << alpha << " " << mu;
      EXPECT_LE(loose.total().value, 1.0 + 1e-6);
    }
}

// The calibration behind the figures of albedo_table.h and docs/guide/scattering-and-energy-tables.md (about 25 s, so disabled:
// run with --gtest_also_run_disabled_tests --gtest_filter='*Calibration*'): per tolerance, the error made
// (against tolerance 1e-12) over the stated error, on GGX, alpha 0.02..1.5, mu 0.03..0.97, mirror and
// dielectric 1.5 from both sides. Fails when the estimate is exceeded more than 3 times or more than 3 times over.
TEST(AlbedoAnalytic, DISABLED_ErrorEstimateCalibration) {
  for (const double tolerance : {1e-4, 1e-6, 1e-8}) {
    int compared = 0, over = 0;
    double worst = 0;
    for (const double alpha : {0.02, 0.05, 0.2, 0.5, 1.0, 1.5})
      for (const double mu : {0.97, 0.9, 0.6, 0.3, 0.1, 0.03})
        for (const int m : {0, 1, 2}) {
          const Material material = m == 0 ? Material::mirror() : Material::dielectric(1.5);
          const SingleScatteringAlbedo a = ggx_albedo(alpha, material, mu, m == 2, tolerance);
          const SingleScatteringAlbedo b = ggx_albedo(alpha, material, mu, m == 2, 1e-12);
          for (const auto& [x, y] : {std::pair{a.reflected, b.reflected}, std::pair{a.transmitted, b.transmitted}}) {
            const double error = std::abs(x.value - y.value);
            if (error < 1e-13) continue;
            ++compared;
            over += error > x.standard_error;
            worst = std::max(worst, error / x.standard_error);
          }
        }
    std::printf("tolerance %g: %d compared, %d over their estimate, worst error / estimate %.3f\n", tolerance, compared,
                over, worst);
    EXPECT_LE(over, 3) << tolerance;
    EXPECT_LE(worst, 3.0) << tolerance;
  }
}

// The same calibration for the Beckmann mirror in its visible slopes (beckmann_mirror_split; about 2 s, so
// disabled: --gtest_also_run_disabled_tests --gtest_filter='*BeckmannErrorEstimateCalibration*'): per tolerance,
// the error made against tolerance 1e-13 over the stated error, of both integrals (E and the Schlick-weighted
// one), alpha 1e-4..2, mu 0.005..1; docs/records/energy-tables.md quotes its output.
TEST(AlbedoAnalytic, DISABLED_BeckmannErrorEstimateCalibration) {
  for (const double tolerance : {1e-4, 1e-6, 1e-8}) {
    int compared = 0, over = 0;
    double worst = 0, largest = 0;
    for (const double alpha : {1e-4, 0.005, 0.02, 0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 1.0, 1.5, 2.0})
      for (const double mu : {0.005, 0.02, 0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 0.9, 0.98, 1.0}) {
        const SchlickSplitAlbedo a = beckmann_mirror_split(alpha, mu, tolerance);
        const SchlickSplitAlbedo b = beckmann_mirror_split(alpha, mu, 1e-13);
        for (const auto& [x, y] : {std::pair{a.unit, b.unit}, std::pair{a.grazing, b.grazing}}) {
          const double error = std::abs(x.value - y.value);
          ++compared;
          over += error > x.standard_error;
          worst = std::max(worst, error / x.standard_error);
          largest = std::max(largest, x.standard_error);
        }
      }
    std::printf("tolerance %g: %d compared, %d over their estimate, worst error / estimate %.3f, largest estimate %.3g\n",
                tolerance, compared, over, worst, largest);
    EXPECT_LE(over, 3) << tolerance;
    EXPECT_LE(worst, 3.0) << tolerance;
  }
}

// ---- the Smith walk -----------------------------------------------------------------------------------------

AlbedoTableRequest walk_request(const Material& m, bool inside, std::vector<double> alphas, std::uint64_t paths) {
  AlbedoTableRequest r;
  r.model = AlbedoModel::smith_walk;
  r.material = m;
  r.inside = inside;
  r.alphas = std::move(alphas);
  r.mus = 4;
  r.paths = paths;
  r.seed = 7;
  return r;
}

// The analytic table of a sampled request's cells (its error, 1e-6, is far below the sampling's).
AlbedoTableRequest analytic_like(AlbedoTableRequest r) {
  r.model = AlbedoModel::analytic;
  r.tolerance = 1e-6;
  return r;
}

// Pearson's statistic of the cells of `name` in the sampled table against the analytic one: sum of z^2
// with z = (sampled - analytic) / sqrt(var), var = p (1 - p) / paths under the hypothesis (p the analytic
// value: a mirror's or a dielectric's paths carry weight 1, so an order-1 albedo is a binomial fraction)
// plus the quadrature's error squared; its p-value under chi-square(cells).
double chi2_p_value(const AlbedoTable& sampled, const AlbedoTable& analytic, const std::string& name) {
  const AlbedoQuantity* s = sampled.find(name);
  const AlbedoQuantity* a = analytic.find(name);
  EXPECT_TRUE(s && a) << name;
  if (!s || !a) return 0;
  double statistic = 0;
  const double n = double(sampled.request.paths);
  for (std::size_t i = 0; i < s->cells.size(); ++i) {
    const double p = a->cells[i].value;
    const double var = p * (1 - p) / n + sqr(a->cells[i].standard_error);
    statistic += sqr(s->cells[i].value - p) / var;
  }
  const boost::math::chi_squared_distribution<double> chi2(double(s->cells.size()));
  return boost::math::cdf(boost::math::complement(chi2, statistic));
}

TEST(AlbedoWalk, MirrorFurnaceEveryPathLeavesAndOrderCapOneFails) {
  AlbedoTableRequest r = walk_request(Material::mirror(), false, {0.5, 1.0}, 20000);
  const AlbedoTable t = albedo_table(r);
  ASSERT_EQ(albedo_quantity_names(r.model, r.material), (std::vector<std::string>{"E", "E1", "unfinished"}));
  for (std::size_t a = 0; a < 2; ++a) {
    for (std::size_t m = 0; m < 4; ++m) {
      EXPECT_EQ(t.cell("E", a, m).value, 1.0) << a << " " << m;  // weights 1, exact sums
      EXPECT_EQ(t.cell("unfinished", a, m).value, 0.0);
    }
    EXPECT_NEAR(t.find("E")->average[a].value, 1.0, 1e-12);
  }
  r.max_order = 1;  // negative control: the walks stopped after one event do not conserve energy
  const AlbedoTable capped = albedo_table(r);
  const Estimate e = capped.cell("E", 1, 0);
  EXPECT_GT((1.0 - e.value) / e.standard_error, 6.0);
}

TEST(AlbedoWalk, OrderOneIsTheAnalyticTableAndAnotherAlphaIsRejected) {
  const AlbedoTableRequest r = walk_request(Material::mirror(), false, {0.3, 1.0}, 40000);
  const AlbedoTable walk = albedo_table(r);
  EXPECT_GT(chi2_p_value(walk, albedo_table(analytic_like(r)), "E1"), kLevel);
  AlbedoTableRequest other = analytic_like(r);
  other.alphas = {0.33, 1.1};
  EXPECT_LT(chi2_p_value(walk, albedo_table(other), "E1"), kLevel) << "negative control";
}

// A dielectric walk: every path leaves on one side or the other (R + T = 1), and its order 1 is the
// analytic table of each side, from outside and from inside; the table of another eta is rejected.
TEST(AlbedoWalk, DielectricReflectsPlusTransmitsOneAndOrderOneIsAnalytic) {
  for (const bool inside : {false, true}) {
    const AlbedoTableRequest r = walk_request(Material::dielectric(1.5), inside, {0.2, 0.8}, 20000);
    const AlbedoTable walk = albedo_table(r);
    for (std::size_t a = 0; a < 2; ++a)
      for (std::size_t m = 0; m < 4; ++m) {
        EXPECT_EQ(walk.cell("unfinished", a, m).value, 0.0);
        EXPECT_NEAR(walk.cell("E", a, m).value, 1.0, 1e-12);
        EXPECT_NEAR(walk.cell("E_R", a, m).value + walk.cell("E_T", a, m).value, 1.0, 1e-12);
      }
    const AlbedoTable analytic = albedo_table(analytic_like(r));
    for (const char* q : {"E1_R", "E1_T"}) EXPECT_GT(chi2_p_value(walk, analytic, q), kLevel) << q << (inside ? " inside" : "");
    AlbedoTableRequest other = analytic_like(r);
    other.material = Material::dielectric(1.7);
    EXPECT_LT(chi2_p_value(walk, albedo_table(other), "E1_R"), kLevel) << "negative control" << (inside ? " inside" : "");
  }
}

TEST(AlbedoWalk, SameSeedSameTableWhateverTheThreadsAndAnotherSeedDiffers) {
  AlbedoTableRequest r = walk_request(Material::dielectric(1.3), true, {0.4}, 3 * kPathsPerBlock + 17);
  r.run.threads = 1;
  const AlbedoTable one = albedo_table(r);
  r.run.threads = 2;
  const AlbedoTable two = albedo_table(r);
  EXPECT_EQ(albedo_table_csv(one), albedo_table_csv(two));
  r.seed = 8;
  EXPECT_NE(albedo_table_csv(albedo_table(r)), albedo_table_csv(two));
}

// A cancel between rows keeps the complete rows; a cancel before any keeps none; both are partial.
TEST(AlbedoWalk, CancelKeepsTheCompleteRowsMarkedPartial) {
  CancelToken token;
  AlbedoTableRequest r = walk_request(Material::mirror(), false, {0.2, 0.4, 0.6}, 4096);
  r.run.cancel = &token;
  const AlbedoTable t = albedo_table(r, [&](const AlbedoTable&, std::size_t row) {
    if (row == 0) token.cancel();
  });
  EXPECT_TRUE(t.partial);
  EXPECT_EQ(t.alphas, std::vector<double>{0.2});
  EXPECT_EQ(t.find("E1")->average.size(), 1u);
  EXPECT_EQ(t.find("E1")->cells.size(), 4u);
  const AlbedoTable none = albedo_table(r);  // the token is still set
  EXPECT_TRUE(none.partial);
  EXPECT_TRUE(none.alphas.empty());
  EXPECT_THROW(albedo_table_exr(none), std::invalid_argument);
  AlbedoTableRequest analytic = analytic_like(r);
  EXPECT_TRUE(albedo_table(analytic).alphas.empty());
}

// ---- the explicit surface -----------------------------------------------------------------------------------

// A mirror heightfield reflects everything (what is not lost), and its order 1 is near Smith's (a loose
// physical bound: the 256^2 tile is one realisation, not the Smith microsurface; its order 1 is measured
// 0.02-0.04 above Smith's at alpha 0.5, docs/guide/scattering-and-energy-tables.md).
TEST(AlbedoSurface, MirrorFurnaceAndOrderOneNearSmith) {
  AlbedoTableRequest r;
  r.model = AlbedoModel::surface;
  r.alphas = {0.5};
  r.mus = 2;
  r.paths = 20000;
  r.resolution = 256;
  const AlbedoTable t = albedo_table(r);
  ASSERT_EQ(t.quantities.back().name, "lost");
  const AlbedoTable analytic = albedo_table(analytic_like(r));
  for (std::size_t m = 0; m < 2; ++m) {
    EXPECT_NEAR(t.cell("E", 0, m).value + t.cell("lost", 0, m).value + t.cell("unfinished", 0, m).value, 1.0, 1e-12);
    EXPECT_LT(t.cell("lost", 0, m).value, 1e-3);
    EXPECT_NEAR(t.cell("E1", 0, m).value, analytic.cell("E1", 0, m).value, 0.08) << m;
    EXPECT_LT(t.cell("E1", 0, m).value, t.cell("E", 0, m).value - 0.1) << "multiple scattering is there";
  }
  ASSERT_EQ(t.build_seconds.size(), 1u);
}

// ---- conductors ----------------------------------------------------------------------------------------------

// A conductor's table: F_avg against known values (k = 0 is a dielectric's external reflectance, whose
// hemispherical average for eta 1.5 is the classic 0.0918; a large k reflects nearly all), and E1 between the
// mirror's scaled by the least F over incidence and the mirror's.
TEST(AlbedoConductor, FresnelAverageAndSingleScatteringOfAConductor) {
  EXPECT_NEAR(fresnel_average(Material::conductor({{1.5, 0.0}})), 0.0918, 5e-4);
  EXPECT_GT(fresnel_average(Material::conductor({{0.05, 100.0}})), 0.999);
  EXPECT_THROW(fresnel_average(Material::mirror()), std::invalid_argument);
  AlbedoTableRequest r;
  r.material = Material::conductor({{0.2, 3.9}});  // about silver at 550 nm
  r.alphas = {0.5, 1.0};
  r.mus = 8;
  const AlbedoTable t = albedo_table(r);
  ASSERT_TRUE(t.fresnel_average.has_value());
  EXPECT_NEAR(*t.fresnel_average, fresnel_average(r.material), 0.0);
  r.material = Material::mirror();
  const AlbedoTable mirror = albedo_table(r);
  EXPECT_FALSE(mirror.fresnel_average.has_value());
  double f0 = 1;  // the least F over incidence (a metal's F dips below F(0) toward grazing)
  for (int i = 0; i <= 1000; ++i) f0 = std::min(f0, fresnel_conductor(i / 1000.0, std::complex<double>(0.2, 3.9)));
  for (std::size_t k = 0; k < t.quantities[0].cells.size(); ++k) {
    const double e = t.quantities[0].cells[k].value, m = mirror.quantities[0].cells[k].value;
    EXPECT_LE(e, m + 1e-9) << k;
    EXPECT_GE(e, f0 * m - 1e-9) << k;
  }
}

// ---- the request ---------------------------------------------------------------------------------------------

TEST(AlbedoRequest, RefusesWhatItCannotTabulate) {
  const auto refused = [](const std::function<void(AlbedoTableRequest&)>& change, const std::string& text) {
    AlbedoTableRequest r;
    change(r);
    try {
      check_albedo_request(r);
      ADD_FAILURE() << "accepted: " << text;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
    }
  };
  refused([](auto& r) { r.material = Material::conductor({{0.2, 3.9}, {0.5, 2.4}}); }, "one conductor channel");
  refused([](auto& r) { r.material = Material::conductor({{0.2, 3.9}}); r.inside = true; }, "inside");
  refused([](auto& r) { r.material = Material::lambertian(); }, "lambertian");
  refused([](auto& r) { r.inside = true; }, "inside");
  refused([](auto& r) { r.alphas = {}; }, "no alphas");
  refused([](auto& r) { r.alphas = {0.001}; }, "0.001");
  refused([](auto& r) { r.alphas = {0.5, 0.3}; }, "increase");
  refused([](auto& r) { r.mus = 1; }, "1 mus");
  refused([](auto& r) { r.tolerance = 0; }, "tolerance");
  refused([](auto& r) { r.model = AlbedoModel::smith_walk; r.paths = 0; }, "paths");
  refused([](auto& r) { r.model = AlbedoModel::smith_walk; r.max_order = 0; }, "order cap");
  refused([](auto& r) { r.model = AlbedoModel::surface; r.resolution = 64; }, "resolution 64");
  EXPECT_THROW(parse_albedo_model("--model", "walk"), ParseError);
  EXPECT_EQ(parse_albedo_model("--model", "smith-walk"), AlbedoModel::smith_walk);
}

// ---- files ---------------------------------------------------------------------------------------------------

TEST(AlbedoFiles, ExrCsvAndJsonHoldTheTable) {
  AlbedoTableRequest r;
  r.material = Material::dielectric(1.5);
  r.alphas = {0.3, 0.9};
  r.mus = 3;
  r.tolerance = 1e-6;
  const AlbedoTable t = albedo_table(r);
  const microgeom::ExrImage image = albedo_table_exr(t);
  EXPECT_EQ(image.width, 3);
  EXPECT_EQ(image.height, 2);
  ASSERT_NE(image.find("E1_T.value"), nullptr);
  EXPECT_FLOAT_EQ(image.find("E1_T.value")->data[1 * 3 + 2], float(t.cell("E1_T", 1, 2).value));
  EXPECT_EQ(image.attributes.at("alphas"), "0.29999999999999999,0.90000000000000002");
  EXPECT_EQ(image.attributes.at("side"), "outside");
  EXPECT_EQ(image.attributes.at("error"), "quadrature error estimate");
  const std::string csv = albedo_table_csv(t);
  std::istringstream lines(csv);
  std::string line, header;
  int rows = 0;
  while (std::getline(lines, line)) {
    if (line.rfind("#", 0) == 0) continue;  // comments
    if (header.empty()) {
      header = line;
    } else {
      ++rows;
    }
  }
  EXPECT_EQ(rows, 6);
  EXPECT_EQ(header, "alpha,mu,mu_weight,E1,E1_error,E1_R,E1_R_error,E1_T,E1_T_error,E1_avg,E1_avg_error,"
                    "E1_R_avg,E1_R_avg_error,E1_T_avg,E1_T_avg_error");
  const nlohmann::json j = albedo_table_json(t);
  EXPECT_EQ(j["quantities"]["E1_R"]["value"][1][0].get<double>(), t.cell("E1_R", 1, 0).value);
  EXPECT_EQ(j["quantities"]["E1"]["average"][0].get<double>(), t.find("E1")->average[0].value);
  EXPECT_EQ(j["partial"], false);
}

}  // namespace
}  // namespace microsim
