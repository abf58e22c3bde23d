// The bsdf kind of an experiment (src/experiment/measurement_bsdf.cpp): a spec names a BSDF plugin and the
// material it claims; the run loads it and runs the battery of `check-bsdf` once. The worked plugin of
// examples/plugins/rough_ggx.c (a rough GGX dielectric in the radiance convention) passes, and its run's verdict
// is pass; the same plugin with the planted eval() bug (the radiance factor forgotten in eval only) is rejected
// and fails the run's verdict (the negative control). Fixed seed, level 0.01, one view of 20000 samples: the
// battery's eval and reciprocity tests at its query pairs see the bug whatever the views. A spec naming no
// plugin file, or parameters create() refuses, is bad input naming the key.
// The files form (dump and eval, as check-bsdf-files takes them): the zoo's GGX conductor sampled at 30 deg, its
// dump and eval file (tests/sample_dumps.h, 20000 rows, fixed seed, level 0.01) pass the run with check-bsdf-files'
// own report; the same files with the weights scaled by 1.01 (a planted weight bug) are rejected by the consistency
// test and fail the run. An unknown key, a plugin's key beside files, a plugin and files, a missing file, bad columns
// are SpecErrors naming the key and its line; rows that do not match the view are bad input naming the key.
#include "experiment/plan.h"
#include "experiment/run.h"
#include "experiment/spec.h"
#include "experiment/verdict.h"
#include "measure/bsdf_file_check.h"
#include "sample_dumps.h"
#include "scratch_dir.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_experiment_bsdf {

namespace {

using namespace microsim::experiment;

// A gold conductor's bsdf quantity, its own keys to follow (from line 12).
constexpr const char* kGoldBsdfQuantity = R"(
seed = 7
[[material]]
name = "gold"
alpha = 0.3
type = "conductor"
eta = 0.2
k = 3.9
[[quantity]]
kind = "bsdf"
material = "gold"
)";

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

// A resumed or merged run reads its plan back from JSON: the battery runs at the material's alpha there too, and
// its verdict is the single run's (read back without its alpha, the correct plugin was tested at alpha 0 and
// rejected).
TEST(ExperimentBsdf, APlanReadBackKeepsTheAlphaAndTheVerdict) {
  const ExperimentSpec good = plugin_spec(MICROSIM_PLUGIN_GOOD);
  const ExperimentPlan plan = plan_experiment(good, PlanOptions{});
  const ExperimentPlan back = plan_from_json(plan_json(plan, good), good);
  ASSERT_EQ(back.decisions.size(), 1u);
  EXPECT_EQ(back.decisions[0].alpha, std::make_pair(0.3, 0.3));
  const ExperimentResults r = run_experiment(good, back, RunOptions{});
  EXPECT_EQ(r.measurements.at(0).values.at("battery").at("alpha"), "0.3");
  EXPECT_EQ(run_verdict(r).verdict, Verdict::pass);
}

// A plugin drawing its normals from D(m) cos (its flag): as check-bsdf tests it, the plan counts the grid without
// 89.9 deg and the run passes a conductor; a dielectric so sampled is refused at plan time naming the key.
TEST(ExperimentBsdf, APluginSamplingTheNdfIsPlannedAndRunAsCheckBsdfRunsIt) {
  const ExperimentSpec gold = parse_spec_toml(
      fmt::format("{}plugin = \"{}\"\nparams = {{ kind = \"conductor\", alpha = 0.3, eta = 0.2, k = 3.9 }}\nsamples = 20000\n",
                  kGoldBsdfQuantity, MICROSIM_PLUGIN_NDF),
      "gold.toml");
  const ExperimentPlan plan = plan_experiment(gold, PlanOptions{});
  EXPECT_EQ(plan.decisions.at(0).units, 4u * 20000u);  // theta 0, 30, 60, 80
  const ExperimentResults r = run_experiment(gold, plan, RunOptions{});
  EXPECT_EQ(run_verdict(r).verdict, Verdict::pass);
  EXPECT_NE(r.measurements.at(0).values.at("battery").at("convention").get<std::string>().find("D(m) cos"),
            std::string::npos);
  try {
    plan_experiment(plugin_spec(MICROSIM_PLUGIN_NDF), PlanOptions{});
    FAIL() << "a dielectric sampling D(m) cos was planned";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("quantity[0].plugin: declares MICROSIM_BSDF_NDF_SAMPLING"), std::string::npos)
        << e.what();
  }
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

// The conductor's files in `dir` (d.txt, e.txt), weights times `weight_scale`; a spec naming them, with `extra`
// keys (line 15), seen at `theta`.
ExperimentSpec files_spec(const std::filesystem::path& dir, const std::string& extra = "", double theta = 30) {
  return parse_spec_toml(fmt::format("{}dump = \"{}\"\neval = \"{}\"\ntheta = {}\n{}\n", kGoldBsdfQuantity,
                                     (dir / "d.txt").string(), (dir / "e.txt").string(), theta, extra),
                         "bsdf.toml");
}

TEST(ExperimentBsdf, FilesOfOneBsdfPassAsCheckBsdfFilesPassesThemAndAPlantedWeightBugFailsTheRun) {
  const std::filesystem::path dir = microsim::test::scratch_dir("experiment_bsdf", "files");
  const std::uint64_t lost = microsim::test::write_conductor_bsdf_files(dir / "d.txt", dir / "e.txt");
  const ExperimentSpec good = files_spec(dir, fmt::format("lost = {}", lost));
  const ExperimentPlan plan = plan_experiment(good, PlanOptions{});
  ASSERT_EQ(plan.decisions.size(), 1u);
  EXPECT_EQ(plan.decisions[0].units, 20000u - lost);
  const ExperimentResults passed = run_experiment(good, plan, RunOptions{});
  const nlohmann::json& b = passed.measurements.at(0).values.at("battery");
  EXPECT_EQ(b.at("verdict"), "pass") << b.dump(1);
  EXPECT_EQ(run_verdict(passed).verdict, Verdict::pass);
  microsim::BsdfFileCheckOptions o;
  o.lost = lost;
  const microsim::BatteryReport direct = microsim::check_bsdf_files(
      dir / "d.txt", microsim::SampleColumns::parse("x,y,z,pdf,weight"), dir / "e.txt",
      microsim::EvalColumns::parse("wi,wo,value,pdf"), microsim::direction_from_degrees(30.0, 0.0), o);
  EXPECT_EQ(b.at("tests"), microsim::to_json(direct).at("tests"));
  EXPECT_EQ(b.at("theta"), 30.0);
  EXPECT_EQ(b.at("bsdf"), "conductor:0.2,3.9");

  microsim::test::write_conductor_bsdf_files(dir / "d.txt", dir / "e.txt", 1.01);
  const ExperimentResults rejected = run_plugin(files_spec(dir));
  const nlohmann::json& bug = rejected.measurements.at(0).values.at("battery");
  EXPECT_EQ(bug.at("verdict"), "fail");
  EXPECT_EQ(bug.at("tests").at(0).at("test"), "consistency");
  EXPECT_FALSE(bug.at("tests").at(0).at("passed").get<bool>());
  EXPECT_EQ(run_verdict(rejected).verdict, Verdict::fail);
  try {  // files of another view: bad input naming the eval file's key
    run_plugin(files_spec(dir, "", 60));
    FAIL() << "ran";
  } catch (const SpecError&) {
    FAIL() << "a spec error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("quantity[0].eval"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("is not the view"), std::string::npos) << e.what();
  }
}

TEST(ExperimentBsdf, TheFilesFormsKeysAreCheckedNamingKeyAndLine) {
  const std::filesystem::path dir = microsim::test::scratch_dir("experiment_bsdf", "keys");
  microsim::test::write_conductor_bsdf_files(dir / "d.txt", dir / "e.txt");
  const std::vector<std::pair<std::string, std::string>> cases{
      {"colour = \"red\"", "quantity[0].colour"},
      {"samples = 1000", "quantity[0].samples"},
      {"plugin = \"x.so\"", "quantity[0].dump"},
      {"columns = \"x,y,z\"", "quantity[0].columns"},
      {"eval_columns = \"wi,wo,value\"", "quantity[0].eval_columns"},
      {"cells = \"no-such-cells.txt\"", "quantity[0].cells"},
      {"frame = \"x-up\"", "quantity[0].frame"},
      {"albedo = -1", "quantity[0].albedo"}};
  for (const auto& [extra, key] : cases) {
    try {
      files_spec(dir, extra);
      ADD_FAILURE() << extra << ": read";
    } catch (const SpecError& e) {
      EXPECT_EQ(e.key(), key) << e.what();
      EXPECT_EQ(e.line(), key == "quantity[0].dump" ? 12 : 15) << e.what();
    }
  }
  std::filesystem::remove(dir / "e.txt");
  try {
    files_spec(dir);
    FAIL() << "read";
  } catch (const SpecError& e) {
    EXPECT_EQ(e.key(), "quantity[0].eval") << e.what();
    EXPECT_NE(std::string(e.what()).find("no eval file"), std::string::npos) << e.what();
  }
}

}  // namespace

}  // namespace test_experiment_bsdf
