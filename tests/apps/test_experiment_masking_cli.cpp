// `microsim run` of masking quantities end to end (seconds): G1 and G2 by the closed forms at three views and
// conditional masking traced on a 128^2 assembly: exit 0, every target met, results.json and the report hold
// the values (the report with its masking curves); a bad masking spec: exit 2, the key and line named,
// nothing written.
#include "cli_helpers.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <string>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_experiment_masking_cli {

namespace {

namespace fs = std::filesystem;
using microsim::test::run_cli;
using microsim::test::scratch_dir;
using microsim::test::slurp;

const char* kMaskingCliSpec = R"(name = "masking-cli"
seed = 6

[[material]]
name = "m"
alpha = 0.4
type = "mirror"

[[quantity]]
kind = "masking"
material = "m"
what = ["g1", "g2"]
theta = [20, 50, 80]
light_theta = [30, 70]
light_phi = [180]
target_standard_error = 0.001

[[quantity]]
kind = "masking"
material = "m"
what = "conditional"
theta = [70]
bins = 4
resolution = 128
target_standard_error = 0.01
)";

TEST(ExperimentMaskingCli, RunsMeetsTheTargetsAndReportsAgainstSmith) {
  const fs::path dir = scratch_dir("masking_cli", "run");
  std::ofstream(dir / "masking.toml") << kMaskingCliSpec;
  const auto r = run_cli(dir, "run masking.toml --out out");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json doc = nlohmann::json::parse(slurp(dir / "out" / "results.json"));
  EXPECT_TRUE(doc["results"]["all_targets_met"].get<bool>());
  const nlohmann::json& measurements = doc["results"]["measurements"];
  ASSERT_EQ(measurements.size(), 4u);
  EXPECT_EQ(doc["plan"]["decisions"][0]["model"], "analytic");
  EXPECT_EQ(doc["plan"]["decisions"][3]["model"], "heightfield");
  const nlohmann::json& traced = measurements[3]["values"]["masking"];
  EXPECT_EQ(traced["conditional"]["by_normal"].size(), 4u);
  const std::string page = slurp(dir / "out" / "index.html");
  EXPECT_NE(page.find("Masking curves"), std::string::npos);
  EXPECT_NE(page.find("G1(v | height)"), std::string::npos);
  fs::remove_all(dir);
}

TEST(ExperimentMaskingCli, ABadMaskingSpecNamesKeyAndLineAndRunsNothing) {
  const fs::path dir = scratch_dir("masking_cli", "bad");
  std::string text = kMaskingCliSpec;
  text.replace(text.find("light_theta = [30, 70]"), 22, "light_theta = [30, 90]");
  std::ofstream(dir / "bad.toml") << text;
  const auto r = run_cli(dir, "run bad.toml --out out");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("bad.toml:14: quantity[0].light_theta"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out"));
  fs::remove_all(dir);
}

}  // namespace

}  // namespace test_experiment_masking_cli
