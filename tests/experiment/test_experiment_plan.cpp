// The planner's decision rules (src/experiment/plan.h) and the pooling of rounds (run.h), each against an
// independent computation, and plan_experiment's pilots on a tiny spec (the order cap checked by a walk of
// its own).
#include "experiment/measures.h"
#include "experiment/plan.h"
#include "experiment/run.h"

#include "scatter/smith_walk.h"

#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/non_central_chi_squared.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_experiment_plan {

namespace {

using namespace microsim::experiment;

SpecQuantity quantity(QuantityKind kind, Orders orders = Orders::single) {
  SpecQuantity q;
  q.kind = kind;
  q.orders = orders;
  q.target = 0.01;
  return q;
}

TEST(ExperimentPlan, ChoosesTheCheapestSufficientModel) {
  SpecMaterial gold;
  gold.facet = microsim::Material::conductor({{0.2, 3.9}});
  EXPECT_EQ(choose_model(quantity(QuantityKind::vndf), gold).model, Model::ellipsoid_oracle);
  EXPECT_EQ(choose_model(quantity(QuantityKind::albedo), gold).model, Model::analytic);
  EXPECT_NE(choose_model(quantity(QuantityKind::albedo), gold).reason.find("F = 1"), std::string::npos);
  EXPECT_EQ(choose_model(quantity(QuantityKind::albedo, Orders::all), gold).model, Model::smith_walk);
  EXPECT_EQ(choose_model(quantity(QuantityKind::scattering), gold).model, Model::analytic);
  EXPECT_EQ(choose_model(quantity(QuantityKind::scattering, Orders::all), gold).model, Model::smith_walk);
  EXPECT_EQ(choose_model(quantity(QuantityKind::validation), gold).model, Model::analytic_validator);
  SpecQuantity on_surface = quantity(QuantityKind::albedo);
  on_surface.surface = {SurfaceChoice::Kind::assembly, "smith"};
  EXPECT_EQ(choose_model(on_surface, gold).model, Model::heightfield);  // the spec asked for its effects
  on_surface.kind = QuantityKind::vndf;
  EXPECT_EQ(choose_model(on_surface, gold).model, Model::heightfield);
}

TEST(ExperimentPlan, UnitsScaleWithTheSquareOfTheErrorRatio) {
  EXPECT_EQ(units_for_standard_error(1000, 0.02, 0.01), 4000u);
  EXPECT_EQ(units_for_standard_error(1000, 0.01, 0.02), 250u);
  EXPECT_EQ(units_for_standard_error(1000, 0.0, 0.01), 1000u);  // no variance seen: the pilot's count
  EXPECT_EQ(units_for_standard_error(1, 1e-20, 1e-30) > 0, true);
  EXPECT_THROW(units_for_standard_error(1000, 0.1, 0), std::invalid_argument);
  EXPECT_THROW(units_for_standard_error(0, 0.1, 0.1), std::invalid_argument);
}

TEST(ExperimentPlan, NextRoundReachesTheTargetUnderTheOneOverRootNLaw) {
  EXPECT_EQ(next_round_units(1000, 0.009, 0.01), 0u);  // met
  const std::uint64_t more = next_round_units(1000, 0.02, 0.01);
  // Under se ~ 1/sqrt(n) the total after the round meets the target.
  EXPECT_LE(0.02 * std::sqrt(1000.0 / double(1000 + more)), 0.01);
  EXPECT_GE(next_round_units(1000, 0.01001, 0.01), 250u);  // a real step, not a crawl
}

TEST(ExperimentPlan, OrderCapIsTheFirstProbeClearlyBelowTheThreshold) {
  const std::vector<CapProbe> probes{{4, 0.1, 0.01}, {8, 0.009, 0.001}, {16, 0.0009, 0.0001}, {32, 1e-5, 1e-6}};
  EXPECT_EQ(order_cap_for(probes, 0.01), std::optional<int>(16));  // 8: 0.009 + 2 x 0.001 is not below 0.01
  EXPECT_EQ(order_cap_for(probes, 0.5), std::optional<int>(4));
  EXPECT_EQ(order_cap_for(probes, 1e-6), std::nullopt);
}

TEST(ExperimentPlan, ValidationSamplesGiveThePowerAtTheWorstDeviation) {
  namespace bm = boost::math;
  for (const int df : {10, 100, 1921})
    for (const double tv : {0.01, 0.001}) {
      const std::uint64_t n = validation_samples(tv, df, 0.01, 0.9);
      const double critical = bm::quantile(bm::complement(bm::chi_squared(df), 0.01));
      const auto power_at = [&](double samples) {
        return bm::cdf(bm::complement(bm::non_central_chi_squared(df, 4 * samples * tv * tv), critical));
      };
      EXPECT_NEAR(power_at(double(n)), 0.9, 1e-3) << df << " " << tv;
      EXPECT_LT(power_at(0.8 * double(n)), 0.88) << "fewer samples must lose power";
      // The inverse (a dump's rows are given): n samples detect tv, to the rounding of n up.
      EXPECT_LE(detectable_tv(n, df, 0.01, 0.9), tv);
      EXPECT_NEAR(detectable_tv(n, df, 0.01, 0.9), tv, 1e-3 * tv);
      EXPECT_NEAR(detectable_tv(4 * n, df, 0.01, 0.9), tv / 2, 1e-3 * tv);
    }
  EXPECT_GT(validation_samples(0.001, 100, 0.01, 0.9), validation_samples(0.002, 100, 0.01, 0.9));
  EXPECT_THROW(detectable_tv(0, 100, 0.01, 0.9), std::invalid_argument);
  // A TV so large that a handful of samples would "detect" it: at least 5 per cell (df + 1 cells), or the
  // chi-square has too few cells left to reject with (the run stopped on it, after other work); a TV so small
  // that no validation can draw its samples is refused, not rounded past 2^64.
  EXPECT_EQ(validation_samples(0.99, 17, 0.01, 0.9), 90u);
  EXPECT_THROW(validation_samples(1e-9, 241, 0.01, 0.9), std::invalid_argument);
}

// A validation whose detect_tv needs more samples than any validation draws is a spec error naming the key, at
// plan time (before anything runs).
TEST(ExperimentPlan, AnImpossibleDetectTvIsASpecErrorNamingTheKey) {
  const ExperimentSpec spec = parse_spec_toml("[[material]]\nname = \"m\"\nalpha = 0.3\ntype = \"mirror\"\n"
                                              "[[quantity]]\nkind = \"validation\"\nmaterial = \"m\"\n"
                                              "sampler = \"heitz2018\"\ntheta = [40]\nrows = 11\ndetect_tv = 1e-9\n",
                                              "tiny.toml");
  try {
    plan_experiment(spec, PlanOptions{});
    FAIL() << "planned";
  } catch (const SpecError& e) {
    EXPECT_EQ(e.key(), "quantity[0].detect_tv") << e.what();
    EXPECT_NE(std::string(e.what()).find("more than the 1e+12"), std::string::npos) << e.what();
  }
}

TEST(ExperimentPlan, PooledRoundsAreTheRunOfAllTheirUnits) {
  std::mt19937_64 rng(12);
  std::exponential_distribution<double> draw(2.0);
  const std::vector<std::uint64_t> units{1000, 3000, 500};
  std::vector<microsim::Estimate> rounds;
  double sum_all = 0, sum2_all = 0;
  for (std::uint64_t n : units) {
    double s = 0, s2 = 0;
    for (std::uint64_t i = 0; i < n; ++i) {
      const double x = draw(rng);
      s += x, s2 += x * x;
    }
    sum_all += s, sum2_all += s2;
    const double mean = s / double(n);
    rounds.push_back({mean, std::sqrt((s2 / double(n) - mean * mean) / double(n))});
  }
  const double n_all = 4500, mean_all = sum_all / n_all;
  const double se_all = std::sqrt((sum2_all / n_all - mean_all * mean_all) / n_all);
  const microsim::Estimate pooled = pool_rounds(rounds, units);
  EXPECT_NEAR(pooled.value, mean_all, 1e-12);
  EXPECT_NEAR(pooled.standard_error, se_all, 0.03 * se_all);  // per-round variances: close, not equal
  EXPECT_THROW(pool_rounds(rounds, {1, 2}), std::invalid_argument);
}

TEST(ExperimentPlan, PilotsPlanATinySpec) {
  ExperimentSpec spec = parse_spec_toml(R"(
[[material]]
name = "m"
alphas = [0.3, 0.8]
type = "mirror"
[[quantity]]
kind = "albedo"
material = "m"
orders = "all"
mus = 4
target_relative_error = 0.01
[[quantity]]
kind = "vndf"
material = "m"
theta = [45]
rows = 7
target_tv = 0.05
)", "tiny.toml");
  PlanOptions o;
  o.pilot_paths = 1024;
  o.pilot_rays = 1 << 14;
  o.cap_pilot_paths = 1 << 13;
  const ExperimentPlan plan = plan_experiment(spec, o);
  ASSERT_EQ(plan.decisions.size(), 3u);  // the albedo table, then vndf at each alpha
  const Decision& walk = plan.decisions[0];
  EXPECT_EQ(walk.model.model, Model::smith_walk);
  EXPECT_TRUE(walk.runnable);
  ASSERT_GE(walk.order_cap, 4);
  // The cap, checked by a table of its own (another seed, more paths) at the roughest alpha: at every mu the
  // weight left on the surface is below the bias share of the target times E; at a quarter of the cap it is
  // not everywhere (the cap is not wasteful).
  const auto worst_unfinished_at = [&](int cap) {
    microsim::AlbedoTableRequest r;
    r.model = microsim::AlbedoModel::smith_walk;
    r.alphas = {0.8};
    r.mus = 4;
    r.paths = 8192;
    r.seed = 99;
    r.max_order = cap;
    const microsim::AlbedoTable t = microsim::albedo_table(r);
    double worst = 0;
    for (std::size_t m = 0; m < 4; ++m) worst = std::max(worst, t.cell("unfinished", 0, m).value / t.cell("E", 0, m).value);
    return worst;
  };
  EXPECT_LT(worst_unfinished_at(walk.order_cap), kBiasShare * 0.01);
  if (walk.order_cap >= 16) {
    EXPECT_GT(worst_unfinished_at(walk.order_cap / 4), kBiasShare * 0.01 * 0.5);
  }
  EXPECT_GE(walk.units, 1u);
  EXPECT_GT(walk.predicted_seconds, 0);
  for (std::size_t i = 1; i < 3; ++i) {
    const Decision& v = plan.decisions[i];
    EXPECT_EQ(v.model.model, Model::ellipsoid_oracle);
    // The TV noise floor ~ 1/sqrt(rays): the pilot's floor scaled to the planned rays is the target's share.
    EXPECT_NEAR(v.pilot_error * std::sqrt(double(v.pilot_units) / double(v.units)), kNoiseShare * 0.05, 1e-3);
  }
}

}  // namespace

}  // namespace test_experiment_plan
