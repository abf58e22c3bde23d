// End to end: `microsim compare-scattering` on two or three traced histograms of `microsim trace vndf`:
// two seeds of one ellipsoid pass, another roughness is rejected (the negative control), and the inputs
// must be of one kind.
#include "cli_helpers.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <string>

namespace microsim::test {
namespace {

using json = nlohmann::json;

class CompareTracedCli : public ::testing::Test {
protected:
  void SetUp() override {
    dir = scratch_dir("compare_traced", ::testing::UnitTest::GetInstance()->current_test_info()->name());
    trace("a.exr", "0.5", 1);
    trace("b.exr", "0.5", 2);
  }
  void TearDown() override { fs::remove_all(dir); }
  void trace(const std::string& out, const std::string& alpha, int seed) {
    const CliRun r = run_cli(dir, "trace vndf --alpha " + alpha + " --theta 40 --rays 400000 --rows 11 --seed " +
                                      std::to_string(seed) + " --threads 2 --out " + out);
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  fs::path dir;
};

// Level 0.01 family-wise (Sidak over the chi-square and the hit-fraction test of both binnings).
TEST_F(CompareTracedCli, TwoSeedsOfOneSurfacePass) {
  const CliRun r = run_cli(dir, "compare-scattering a.exr b.exr --json c.json --svg c.svg");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const json j = json::parse(slurp(dir / "c.json"));
  EXPECT_EQ(j["kind"], "traced-histograms");
  EXPECT_FALSE(j["rejected"].get<bool>());
  ASSERT_EQ(j["comparisons"][0]["binnings"].size(), 2u);  // sphere and lobe: same alpha, view and rows
  for (const json& b : j["comparisons"][0]["binnings"]) {
    EXPECT_LT(b["tv"].get<double>(), 2 * b["tv_noise_floor"].get<double>()) << b.dump();
    const double hits = b["hit_fraction_a"]["value"].get<double>();  // the beam covers the ellipsoid's shadow and more
    EXPECT_GT(hits, 0.5);
    EXPECT_LT(hits, 1.0);
  }
  EXPECT_NE(slurp(dir / "c.svg").find("A - B"), std::string::npos);
  EXPECT_NE(r.out.find("passed"), std::string::npos) << r.out;
}

TEST_F(CompareTracedCli, AnotherRoughnessIsRejected) {  // the negative control
  trace("rough.exr", "0.6", 3);
  const CliRun r = run_cli(dir, "compare-scattering a.exr b.exr rough.exr --json c.json");
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  const json j = json::parse(slurp(dir / "c.json"));
  EXPECT_TRUE(j["rejected"].get<bool>());
  ASSERT_EQ(j["comparisons"].size(), 3u);
  EXPECT_FALSE(j["comparisons"][0]["binnings"][0]["chi2"]["rejected"].get<bool>());  // A-B
  ASSERT_EQ(j["comparisons"][1]["binnings"].size(), 1u);  // A-C: the sphere binning only (the lobe follows alpha)
  EXPECT_TRUE(j["comparisons"][1]["binnings"][0]["chi2"]["rejected"].get<bool>());
  EXPECT_NE(r.out.find("REJECTED"), std::string::npos) << r.out;
}

TEST_F(CompareTracedCli, InputsOfOneKindAndNoScatterOptions) {
  ASSERT_EQ(run_cli(dir, "scatter --model analytic --alpha 0.5 --theta 40 --rows 5 --out s.exr").exit_code, 0);
  CliRun r = run_cli(dir, "compare-scattering a.exr s.exr");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("one kind"), std::string::npos) << r.err;
  r = run_cli(dir, "compare-scattering s.exr a.exr");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("one kind"), std::string::npos) << r.err;
  r = run_cli(dir, "compare-scattering a.exr b.exr --orders 1");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--orders"), std::string::npos) << r.err;
  r = run_cli(dir, "compare-scattering a.exr --analytic");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--analytic"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "c.json"));
}

}  // namespace
}  // namespace microsim::test
