// The bsdf kind of an experiment (src/experiment/measurement_bsdf.cpp): a spec names a BSDF plugin and the
// material it claims; the run loads it and runs the battery of `check-bsdf` once. The worked plugin of
// examples/plugins/rough_ggx.c (a rough GGX dielectric in the radiance convention) passes, and its run's verdict
// is pass; the same plugin with the planted eval() bug (the radiance factor forgotten in eval only) is rejected
// and fails the run's verdict (the negative control). Fixed seed, level 0.01, one view of 20000 samples: the
// battery's eval and reciprocity tests at its query pairs see the bug whatever the views. A spec naming no
// plugin file, or parameters create() refuses, is bad input naming the key.
#include "experiment/plan.h"
#include "experiment/run.h"
#include "experiment/spec.h"
#include "experiment/verdict.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace {

using namespace microsim::experiment;

ExperimentSpec plugin_spec(const std::string& plugin, const std::string& params = "kind = \"dielectric\", alpha = 0.3, eta = 1.5") {
  return parse_spec_toml(fmt::format(R"(
seed = 7
[[material]]
name = "glass"
alpha = 0.3
type = "dielectric"
eta = 1.5
[[quantity]]
kind = "bsdf"
material = "glass"
plugin = "{}"
params = {{ {} }}
views = [60]
samples = 20000
)", plugin, params), "bsdf.toml");
}

ExperimentResults run_plugin(const ExperimentSpec& spec) {
  const ExperimentPlan plan = plan_experiment(spec, PlanOptions{});
  return run_experiment(spec, plan, RunOptions{});
}

TEST(ExperimentBsdf, TheWorkedPluginPassesAndThePlantedEvalBugFailsTheRun) {
  const ExperimentSpec good = plugin_spec(MICROSIM_PLUGIN_GOOD);
  const ExperimentPlan plan = plan_experiment(good, PlanOptions{});
  ASSERT_EQ(plan.decisions.size(), 1u);
  EXPECT_EQ(plan.decisions[0].units, 20000u);
  EXPECT_TRUE(plan.decisions[0].runnable);
  const ExperimentResults passed = run_experiment(good, plan, RunOptions{});
  const MeasurementResult& m = passed.measurements.at(0);
  ASSERT_TRUE(m.ran);
  EXPECT_TRUE(m.met);
  const nlohmann::json& b = m.values.at("battery");
  EXPECT_EQ(b.at("verdict"), "pass") << b.dump(1);
  EXPECT_EQ(b.at("bsdf"), "dielectric:1.5");
  EXPECT_EQ(b.at("params"), "alpha=0.3 eta=1.5 kind=dielectric");  // by key
  EXPECT_EQ(b.at("tests").back().at("test"), "reciprocity");
  EXPECT_EQ(run_verdict(passed).verdict, Verdict::pass);
  EXPECT_EQ(run_verdict(passed).tested, 1);

  const ExperimentResults rejected = run_plugin(plugin_spec(MICROSIM_PLUGIN_EVAL_BUG));
  const MeasurementResult& bug = rejected.measurements.at(0);
  EXPECT_EQ(bug.values.at("battery").at("verdict"), "fail");
  for (const nlohmann::json& t : bug.values.at("battery").at("tests")) {
    if (t.at("test") == "eval" || t.at("test") == "reciprocity") {
      EXPECT_FALSE(t.at("passed").get<bool>()) << t.dump();
    }
  }
  const RunVerdict v = run_verdict(rejected);
  EXPECT_EQ(v.verdict, Verdict::fail);
  EXPECT_EQ(v.rejected, std::vector<std::string>{bug.decision.label});
}

TEST(ExperimentBsdf, AMissingPluginIsABadSpecAndARefusedOneStopsThePlan) {
  try {
    plugin_spec("no-such-plugin.so");
    FAIL() << "read";
  } catch (const SpecError& e) {
    EXPECT_EQ(e.key(), "quantity[0].plugin") << e.what();
    EXPECT_EQ(e.line(), 11) << e.what();
  }
  try {
    plan_experiment(plugin_spec(MICROSIM_PLUGIN_GOOD, "colour = \"red\""), PlanOptions{});
    FAIL() << "planned";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("quantity[0].plugin"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("refused the parameters"), std::string::npos) << e.what();
  }
}

}  // namespace
