// End to end: `microsim scatter --model analytic` writes the exact single-scattering expectation,
// `microsim compare-scattering` compares two or three scatter files (measured and analytic) and rejects a
// measurement of another roughness (the negative control), too little data is exit 2, and `microsim merge`
// joins scatter shards into the single run bit for bit, refusing gaps and overlaps.
#include "cli_helpers.h"
#include "scatter_samples.h"

#include "stats/scatter_io.h"
#include "stats/scatter_merge.h"

#include <fmt/core.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <map>
#include <string>

namespace microsim::test {
namespace {

using json = nlohmann::json;

constexpr double kTheta = 40;  // degrees

// The notes `microsim scatter` writes, for the configuration of the synthetic runs.
std::map<std::string, std::string> notes(double alpha) {
  return {{"model", "synthetic"}, {"ndf", "ggx"}, {"alpha", fmt::format("{},{}", alpha, alpha)},
          {"theta", fmt::format("{}", kTheta)}, {"phi", "0"}, {"material", "mirror"}};
}

ScatterOptions run_options(std::uint64_t seed, std::uint64_t paths = 150000) {
  ScatterOptions o;
  o.wi = Vec3<double>(std::sin(kTheta * kPi<double> / 180), 0, std::cos(kTheta * kPi<double> / 180));
  o.paths = paths;
  o.seed = seed;
  o.rows = 5;
  return o;
}

void write_run(const fs::path& path, std::uint64_t seed, double alpha, std::uint64_t paths = 150000) {
  write_scatter_exr(path, synthetic_scatter(run_options(seed, paths), alpha), notes(alpha));
}

// A shard's part as `scatter --shard K/N --out PART.json` writes it.
void write_part(const fs::path& path, const ScatterHistogram& h, const std::map<std::string, std::string>& notes) {
  std::ofstream(path) << scatter_part_json(h, notes).dump() << "\n";
}

class CompareScatteringCli : public ::testing::Test {
protected:
  void SetUp() override {
    dir = scratch_dir("compare_scattering", ::testing::UnitTest::GetInstance()->current_test_info()->name());
    write_run(dir / "m1.exr", 1, 0.5);
    write_run(dir / "m2.exr", 2, 0.5);
  }
  void TearDown() override { fs::remove_all(dir); }
  fs::path dir;
};

TEST_F(CompareScatteringCli, AnalyticModelWritesTheExpectation) {
  const CliRun r = run_cli(dir, "scatter --model analytic --alpha 0.5 --theta 40 --material mirror --rows 5 --out a.exr --json a.json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const ScatterFile f = read_scatter_exr(dir / "a.exr");
  ASSERT_EQ(f.kind, ScatterFileKind::expectation);
  EXPECT_EQ(f.notes.at("material"), "mirror");
  const json j = json::parse(slurp(dir / "a.json"));
  const double e = j["channels"][0]["albedo"]["order1"]["both"]["value"].get<double>();
  double bins = 0;
  for (double v : f.expectation.order1[0]) bins += v;
  EXPECT_EQ(e, bins);
  EXPECT_NEAR(e, 0.682, 0.001);  // GGX alpha 0.5, mu = cos 40 deg: between E(0.5) = 0.698 and a dip below E(1) = 0.688
  EXPECT_NE(r.out.find("order1"), std::string::npos) << r.out;
  // Beckmann: another lobe of the same roughness.
  ASSERT_EQ(run_cli(dir, "scatter --model analytic --ndf beckmann --alpha 0.5 --theta 40 --rows 5 --out b.exr").exit_code, 0);
  const ScatterFile b = read_scatter_exr(dir / "b.exr");
  EXPECT_EQ(b.notes.at("ndf"), "beckmann");
  EXPECT_NE(b.expectation.order1, f.expectation.order1);
  EXPECT_NE(b.expectation.measurement.find("beckmann"), std::string::npos);
}

TEST_F(CompareScatteringCli, TwoRunsOfOneConfigurationPass) {
  // The synthetic runs have orders 1 and 2 only.
  const CliRun r = run_cli(dir, "compare-scattering m1.exr m2.exr --orders 1,2,total --json c.json --svg c.svg");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const json j = json::parse(slurp(dir / "c.json"));
  EXPECT_FALSE(j["rejected"].get<bool>());
  EXPECT_EQ(j["comparisons"][0]["lobes"].size(), 3u);
  const std::string svg = slurp(dir / "c.svg");
  EXPECT_NE(svg.find("<svg"), std::string::npos);
  EXPECT_NE(svg.find("A - B"), std::string::npos);
}

TEST_F(CompareScatteringCli, ThreeWayWithTheAnalyticFileAndTheAnalyticOption) {
  ASSERT_EQ(run_cli(dir, "scatter --model analytic --alpha 0.5 --theta 40 --rows 5 --out a.exr").exit_code, 0);
  CliRun r = run_cli(dir, "compare-scattering m1.exr m2.exr a.exr --orders 1,2,total --json c.json");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const json j = json::parse(slurp(dir / "c.json"));
  ASSERT_EQ(j["comparisons"].size(), 3u);
  EXPECT_EQ(j["comparisons"][0]["lobes"].size(), 3u);  // A-B: orders 1, 2 and total
  EXPECT_EQ(j["comparisons"][1]["lobes"].size(), 1u);  // A-C: order 1 only (C is single scattering)
  EXPECT_EQ(j["comparisons"][1]["lobes"][0]["order"], "order1");
  r = run_cli(dir, "compare-scattering m1.exr --analytic --orders 1");
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
}

TEST_F(CompareScatteringCli, AnotherRoughnessIsRejected) {  // the negative control
  write_run(dir / "rough.exr", 3, 0.6);
  const CliRun r = run_cli(dir, "compare-scattering m1.exr rough.exr --orders 1 --json c.json");
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_TRUE(json::parse(slurp(dir / "c.json"))["rejected"].get<bool>());
  // --analytic follows the notes: right for rough.exr, wrong for a file whose notes claim another roughness.
  EXPECT_EQ(run_cli(dir, "compare-scattering rough.exr --analytic").exit_code, 0);
  write_scatter_exr(dir / "liar.exr", synthetic_scatter(run_options(5), 0.6), notes(0.5));
  EXPECT_EQ(run_cli(dir, "compare-scattering liar.exr --analytic").exit_code, 1);
}

TEST_F(CompareScatteringCli, TooLittleDataIsAnErrorAndWritesNothing) {
  write_run(dir / "tiny.exr", 4, 0.5, 20);
  BadInputCase c{"tiny", "compare-scattering m1.exr tiny.exr --orders 1 --json c.json --svg c.svg", 2, "too little data"};
  c.prepare = [&](const fs::path& d) {
    fs::copy_file(dir / "m1.exr", d / "m1.exr");
    fs::copy_file(dir / "tiny.exr", d / "tiny.exr");
  };
  expect_bad_input(c, "compare_scattering_tiny");
  // Orders where no path leaves (3 and more) are too little data too, unless left out.
  const CliRun r = run_cli(dir, "compare-scattering m1.exr m2.exr --orders 3");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("order3"), std::string::npos) << r.err;
}

// ---- merge ---------------------------------------------------------------------------------------------------

TEST_F(CompareScatteringCli, MergedShardsAreTheSingleRunBitForBit) {
  ScatterOptions o = run_options(9, 7 * kPathsPerBlock + 5);
  const ScatterHistogram whole = synthetic_scatter(o, 0.5);
  write_scatter_exr(dir / "whole.exr", whole, notes(0.5));
  std::string parts;
  for (int k = 3; k >= 1; --k) {
    o.blocks = shard_range(whole.provenance.total_blocks, std::uint64_t(k), 3);
    const std::string part = fmt::format("p{}.json", k);  // (not "p" + to_string: GCC 12 -Wrestrict false positive)
    write_part(dir / part, synthetic_scatter(o, 0.5), notes(0.5));
    parts += " " + part;
  }
  const CliRun r = run_cli(dir, "merge" + parts + " --out merged.exr --json merged.json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(slurp(dir / "merged.exr"), slurp(dir / "whole.exr"));
  json merged = json::parse(slurp(dir / "merged.json"));
  EXPECT_EQ(merged["notes"], json(notes(0.5)));  // the report adds the parts' notes and what each hemisphere holds
  EXPECT_EQ(merged["hemispheres"]["upper"], "reflected");
  merged.erase("notes");
  merged.erase("hemispheres");
  EXPECT_EQ(merged, scatter_summary_json(whole));

  for (const auto& [args, message] : std::vector<std::pair<std::string, std::string>>{
           {"merge p1.json p3.json --out m.exr", "missing"},
           {"merge p1.json p2.json p3.json p2.json --out m.exr", "more than one part"},
           {"merge p1.json m1.json --out m.exr", "not parts of one run"}}) {
    BadInputCase c{"merge", args, 2, message};
    write_part(dir / "m1.json", synthetic_scatter(run_options(1), 0.5), notes(0.5));
    c.prepare = [&](const fs::path& d) {
      for (const char* f : {"p1.json", "p2.json", "p3.json", "m1.json"}) fs::copy_file(dir / f, d / f);
    };
    expect_bad_input(c, "compare_scattering_merge");
  }
}

}  // namespace
}  // namespace microsim::test
