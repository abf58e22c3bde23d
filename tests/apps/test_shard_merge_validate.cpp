// Shard and merge for validate and stability: a run split with --shard K/N and joined by
// `microsim merge` is the single run, bit for bit (every non-timing JSON number: p-values, statistics,
// counts, worst cases; and the table on stdout), for one validation against its claimed pdf (double and
// float, normals and reflected directions, a rejected negative control), against a traced histogram, for
// the batch `validate --all`, and for the stability sweep; in the library, the tallies of any grouping of
// blocks merge into the single run's tally bit for bit (the per-block checks reduced again in block order).
// Parts with a gap, an overlap, another seed or another parameter, or of another kind are refused (exit 2)
// with the ranges or the difference named, and nothing is written.
#include "cli_helpers.h"
#include "merge_errors_suite.h"
#include "output_digest.h"

#include "measure/validation.h"
#include "validate/stability_part.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace microsim::test {
namespace {

// stdout without the lines that measure the machine ("time 1.23 s").
std::string validation_table_of(const std::string& out) {
  std::istringstream in(out);
  std::string line, table;
  while (std::getline(in, line))
    if (!line.starts_with("time ")) table += line + "\n";
  return table;
}

struct ValidateShardCase {
  std::string name;
  std::string prepare;   // a command run first ("" for none)
  std::string validate;  // validate arguments without --shard/--json
  int shards;
  int exit_code;         // of the single run and of the merge
};

void PrintTo(const ValidateShardCase& c, std::ostream* os) { *os << c.name; }

class ValidateShardMerge : public ::testing::TestWithParam<ValidateShardCase> {};

TEST_P(ValidateShardMerge, MergedShardsAreTheSingleRunBitForBit) {
  const ValidateShardCase& c = GetParam();
  const fs::path dir = scratch_dir("validate_shard", c.name);
  if (!c.prepare.empty()) {
    ASSERT_EQ(run_cli(dir, c.prepare).exit_code, 0) << c.prepare;
  }
  const CliRun whole = run_cli(dir, c.validate + " --json whole.json");
  ASSERT_EQ(whole.exit_code, c.exit_code) << whole.err;
  std::string parts;
  for (int k = c.shards; k >= 1; --k) {  // any order
    const std::string part = "part" + std::to_string(k) + ".json";
    const CliRun r = run_cli(dir, c.validate + " --shard " + std::to_string(k) + "/" + std::to_string(c.shards) +
                                      " --json " + part);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    parts += " " + part;
  }
  const CliRun merged = run_cli(dir, "merge" + parts + " --json merged.json");
  ASSERT_EQ(merged.exit_code, c.exit_code) << merged.err;
  const json want = pinned_part(json::parse(slurp(dir / "whole.json")));
  const json got = pinned_part(json::parse(slurp(dir / "merged.json")));
  ASSERT_TRUE(want.contains("p_value"));
  expect_contains(want, got, c.name + " (whole in merged)");
  expect_contains(got, want, c.name + " (merged in whole)");
  EXPECT_EQ(validation_table_of(merged.out), validation_table_of(whole.out));
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(
    Runs, ValidateShardMerge,
    ::testing::Values(
        ValidateShardCase{"heitz2018", "", "validate --sampler heitz2018 --alpha 0.3 --theta 40 --samples 300000 --seed 5",
                          3, 0},
        ValidateShardCase{"dupuy2023_float_anisotropic", "",
                          "validate --sampler dupuy2023 --float --alpha 0.2,0.5 --theta 70 --phi 30 --samples 400000 "
                          "--seed 2",
                          4, 0},
        ValidateShardCase{"bounded2023_reflected", "",
                          "validate --sampler bounded2023 --alpha 0.05 --theta 80 --samples 200000 --seed 3 --rows 15", 2,
                          0},
        ValidateShardCase{"negative_control_rejected", "",
                          "validate --sampler heitz2018-talk --alpha 0.5 --theta 60 --samples 200000 --seed 1", 3, 1},
        ValidateShardCase{"one_shard", "", "validate --sampler ndf --alpha 0.8 --theta 10 --samples 50000 --rows 9", 1, 0},
        ValidateShardCase{"against_histogram",
                          "trace vndf --alpha 0.4 --theta 50 --rays 400000 --seed 6 --out h.exr --json h.json",
                          "validate --sampler heitz2018 --alpha 0.4 --theta 50 --samples 250000 --seed 6 --against h.exr",
                          3, 0}),
    [](const auto& info) { return info.param.name; });

// The batch: every sampler of the zoo over the grid, 2 blocks of samples each (the second one sample), in 2
// shards given in reverse order (3 blocks in 3 shards took 57 s; the uneven 3-way split is the cases' above).
TEST(ValidateAllShardMerge, MergedShardsAreTheSingleBatchBitForBit) {
  const fs::path dir = scratch_dir("validate_shard", "all");
  const std::string all = "validate --all --samples 65537 --rows 3 --seed 3";
  const CliRun whole = run_cli(dir, all + " --json whole.json");
  ASSERT_EQ(whole.exit_code, 0) << whole.err;
  for (int k = 1; k <= 2; ++k)
    ASSERT_EQ(run_cli(dir, all + " --shard " + std::to_string(k) + "/2 --json p" + std::to_string(k) + ".json").exit_code, 0);
  const CliRun merged = run_cli(dir, "merge p2.json p1.json --json merged.json");
  ASSERT_EQ(merged.exit_code, 0) << merged.err;
  const json want = pinned_part(json::parse(slurp(dir / "whole.json")));
  const json got = pinned_part(json::parse(slurp(dir / "merged.json")));
  ASSERT_EQ(want["results"].size(), 240u + 135u);  // the direction zoo, then the BSDF section
  expect_contains(want, got, "all (whole in merged)");
  expect_contains(got, want, "all (merged in whole)");
  fs::remove_all(dir);
}

// ---- library: tallies of any grouping of blocks ----------------------------------------------------------

bool same_bits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }

void expect_same_tally(const battery::Tally& a, const battery::Tally& b, const std::string& where) {
  EXPECT_EQ(a.samples, b.samples) << where;
  EXPECT_EQ(a.failed, b.failed) << where;
  EXPECT_EQ(a.outside, b.outside) << where;
  EXPECT_EQ(a.counts, b.counts) << where;
  ASSERT_EQ(a.block_checks.size(), b.block_checks.size()) << where;
  const battery::PdfChecks &x = a.checks, &y = b.checks;
  EXPECT_TRUE(same_bits(x.weight.n, y.weight.n) && same_bits(x.weight.mean, y.weight.mean) &&
              same_bits(x.weight.m2, y.weight.m2))
      << where << ": weight moments differ";
  EXPECT_TRUE(same_bits(x.pdf_worst, y.pdf_worst) && x.pdf_worst_index == y.pdf_worst_index &&
              x.pdf_outliers == y.pdf_outliers && x.worst_direction == y.worst_direction)
      << where << ": returned-pdf checks differ";
}

TEST(ValidationTallies, AnyGroupingOfBlocksIsTheSingleRun) {
  for (const char* name : {"heitz2018", "bounded2023", "ndf"}) {
    ValidationRun run;
    run.options.samples = 6 * kSampleBlock + 77;  // 7 blocks, the last one short
    run.options.rows = 9;
    run.cases = {{find_sampler(name), 0.3, 0.6, 65, 20, 11}};
    run.options.run.threads = 2;
    const ValidationPart whole = sample_validation_part(run, {0, 7}, nullptr);
    std::vector<ValidationPart> parts;
    for (const BlockRange blocks : {BlockRange{4, 7}, BlockRange{0, 1}, BlockRange{1, 4}}) {
      run.options.run.threads = int(blocks.begin % 2) + 1;
      // Through the part's JSON, as `microsim merge` reads it.
      const json part = json::parse(validation_part_json(sample_validation_part(run, blocks, nullptr)).dump());
      parts.push_back(read_validation_part(part));
    }
    const ValidationPart merged = merge_validation_parts(parts);
    ASSERT_EQ(merged.tallies.size(), 1u);
    expect_same_tally(merged.tallies[0], whole.tallies[0], name);
    EXPECT_EQ(whole.tallies[0].block_checks.size(), 7u) << name;
    // The weights are real numbers reduced block by block: a merge that added the parts' reductions
    // instead of reducing the blocks again would differ in the last bits (the test would not see it
    // otherwise).
    if (std::string(name) == "heitz2018") {
      EXPECT_NE(whole.tallies[0].checks.weight.mean, std::floor(whole.tallies[0].checks.weight.mean));
    }
  }
}

// ---- merge errors ----------------------------------------------------------------------------------------

// The parts of a validation of 8 blocks (500000 samples) in three shards: [0, 2), [2, 5), [5, 8); and parts of
// other runs: another seed, another roughness, a stability part.
class ValidateMergeErrors : public MergeErrorsSuite<ValidateMergeErrors> {
protected:
  static void SetUpTestSuite() {
    dir() = scratch_dir("validate_merge", "errors");
    // The parts, made once per build of the tests (shared_fixture_dir) and copied here.
    copy_fixture_files(shared_fixture_dir("validate_merge_errors", [](const fs::path& d) {
      const std::string run = "validate --sampler heitz2018 --theta 30 --samples 500000";
      for (int k = 1; k <= 3; ++k)
        ASSERT_EQ(run_cli(d, run + " --alpha 0.3 --seed 7 --shard " + std::to_string(k) + "/3 --json p" +
                                     std::to_string(k) + ".json").exit_code, 0);
      ASSERT_EQ(run_cli(d, run + " --alpha 0.3 --seed 8 --shard 2/3 --json seed8.json").exit_code, 0);
      ASSERT_EQ(run_cli(d, run + " --alpha 0.4 --seed 7 --shard 2/3 --json alpha04.json").exit_code, 0);
      ASSERT_EQ(run_cli(d, "stability --random-u 2 --shard 1/2 --json s1.json").exit_code, 0);
      ASSERT_EQ(run_cli(d, "trace vndf --alpha 0.3 --theta 30 --rays 20000 --shard 1/1 --out vpart.json --json v.json").exit_code, 0);
      // A part whose tally was edited: a count that is not a count.
      json bad = json::parse(slurp(d / "p2.json"));
      bad["tallies"][0]["counts"][1][3] = -1;
      std::ofstream(d / "bad.json") << bad.dump();
    }), dir());
  }
};

TEST_F(ValidateMergeErrors, TheShardsMerge) {
  const CliRun r = run_cli(dir(), "merge p3.json p1.json p2.json --json merged.json");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir() / "merged.json"));
  fs::remove(dir() / "merged.json");
}
TEST_F(ValidateMergeErrors, AGapIsNamed) { expect_refused("p1.json p3.json --json m.json", "blocks [2, 5) of [0, 8) are missing"); }
TEST_F(ValidateMergeErrors, AMissingEndIsNamed) { expect_refused("p1.json p2.json", "blocks [5, 8) of [0, 8) are missing"); }
TEST_F(ValidateMergeErrors, AnOverlapIsNamed) {
  expect_refused("p1.json p2.json p2.json p3.json --json m.json", "blocks [2, 5) are in more than one part");
}
TEST_F(ValidateMergeErrors, AnotherSeedIsRefused) { expect_refused("p1.json seed8.json p3.json", "seed '7' vs '8'"); }
TEST_F(ValidateMergeErrors, AnotherRoughnessIsRefused) {
  expect_refused("p1.json alpha04.json p3.json", "part 2 is not part of the same run: alpha is '[0.4,0.4]' there");
}
TEST_F(ValidateMergeErrors, AStabilityPartIsAnotherKind) {
  expect_refused("p1.json s1.json p3.json", "part 's1.json': not a validate report");
  expect_refused("p1.json vpart.json p3.json", "parts of one run are of one kind");
}
TEST_F(ValidateMergeErrors, AReportIsNotAPart) {
  expect_refused("v.json p1.json", "part 'v.json': not a partial result");
}
TEST_F(ValidateMergeErrors, AMalformedTallyIsNamed) {
  expect_refused("p1.json bad.json p3.json", "part 'bad.json': not a validate part: tallies/0/counts/1/3 is not a count");
}
TEST_F(ValidateMergeErrors, AnExrOutputIsRefused) { expect_refused("p1.json p2.json p3.json --out m.exr", "--out 'm.exr'"); }
TEST_F(ValidateMergeErrors, AnOutputThatIsAPartIsRefused) { expect_refused("p1.json p2.json p3.json --json p2.json", "p2.json"); }

// A comparison's parts name the histogram they were drawn against: another histogram at that path is refused.
TEST(ValidateMergeAgainst, AnotherHistogramIsRefused) {
  const fs::path dir = scratch_dir("validate_merge", "against");
  const std::string trace = "trace vndf --alpha 0.4 --theta 50 --rays 200000 --out h.exr";
  ASSERT_EQ(run_cli(dir, trace + " --seed 1").exit_code, 0);
  const std::string run = "validate --sampler heitz2018 --alpha 0.4 --theta 50 --samples 150000 --against h.exr";
  for (int k = 1; k <= 2; ++k)
    ASSERT_EQ(run_cli(dir, run + " --shard " + std::to_string(k) + "/2 --json p" + std::to_string(k) + ".json").exit_code, 0);
  ASSERT_EQ(run_cli(dir, trace + " --seed 2").exit_code, 0);  // h.exr replaced by another trace
  const CliRun r = run_cli(dir, "merge p1.json p2.json --json m.json");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("'h.exr' is not the traced histogram the parts were compared with"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "m.json"));
  fs::remove_all(dir);
}

// ---- stability ---------------------------------------------------------------------------------------------

TEST(StabilityShardMerge, MergedShardsAreTheSingleSweepBitForBit) {
  const fs::path dir = scratch_dir("stability_shard", "merge");
  const CliRun whole = run_cli(dir, "stability --random-u 6 --seed 4 --json whole.json");
  ASSERT_EQ(whole.exit_code, 0) << whole.err;
  std::string parts;
  for (int k = 5; k >= 1; --k) {
    ASSERT_EQ(run_cli(dir, "stability --random-u 6 --seed 4 --shard " + std::to_string(k) + "/5 --json p" +
                               std::to_string(k) + ".json").exit_code, 0);
    parts += " p" + std::to_string(k) + ".json";
  }
  const CliRun merged = run_cli(dir, "merge" + parts + " --json merged.json");
  ASSERT_EQ(merged.exit_code, 0) << merged.err;
  EXPECT_EQ(slurp(dir / "merged.json"), slurp(dir / "whole.json"));  // no timing in it: byte for byte
  EXPECT_EQ(merged.out, whole.out);
  // Parts of other sweeps and gaps are refused, naming the difference.
  ASSERT_EQ(run_cli(dir, "stability --random-u 7 --seed 4 --shard 2/5 --json u7.json").exit_code, 0);
  ASSERT_EQ(run_cli(dir, "stability --random-u 6 --seed 5 --shard 2/5 --json seed5.json").exit_code, 0);
  const auto before = snapshot_files(dir);
  const CliRun gap = run_cli(dir, "merge p1.json p3.json p4.json p5.json --json m.json");
  EXPECT_EQ(gap.exit_code, 2);
  EXPECT_NE(gap.err.find("blocks [166, 333) of [0, 833) are missing"), std::string::npos) << gap.err;
  const CliRun other = run_cli(dir, "merge p1.json u7.json p3.json p4.json p5.json --json m.json");
  EXPECT_EQ(other.exit_code, 2);
  EXPECT_NE(other.err.find("part 2 is not part of the same run: grid is"), std::string::npos) << other.err;
  const CliRun seed = run_cli(dir, "merge p1.json seed5.json p3.json p4.json p5.json --json m.json");
  EXPECT_EQ(seed.exit_code, 2);
  EXPECT_NE(seed.err.find("seed '4' vs '5'"), std::string::npos) << seed.err;
  EXPECT_TRUE(snapshot_files(dir) == before);
  fs::remove_all(dir);
}

// The library: the rows of any grouping of blocks, reduced in block order, are the whole sweep's.
TEST(StabilityShardMerge, AnyGroupingOfBlocksIsTheWholeSweep) {
  StabilityGrid g = StabilityGrid::standard();
  g.alphas = {{1e-3, 1.0}, {0.3, 0.3}};
  g.thetas_deg = {45, 89.99, 120};
  g.random_u_per_view = 8;
  const std::uint64_t blocks = stability_blocks(g);
  ASSERT_EQ(blocks, 2u * 3 * 4 + 1);
  const StabilityTable whole = run_stability_sweep(g);
  std::vector<StabilityTable> parts;
  for (const BlockRange r : {BlockRange{20, 25}, BlockRange{0, 7}, BlockRange{7, 20}}) {
    StabilityRun run;
    run.blocks = r;
    run.run.threads = int(r.begin % 2) + 1;
    parts.push_back(read_stability_part(json::parse(stability_part_json(run_stability_sweep(g, sampler_registry(), true, run)).dump())));
  }
  const StabilityTable merged = merge_stability_parts(parts);
  EXPECT_EQ(stability_table_json(merged).dump(), stability_table_json(whole).dump());
  EXPECT_EQ(stability_table_markdown(merged), stability_table_markdown(whole));
}

}  // namespace
}  // namespace microsim::test
