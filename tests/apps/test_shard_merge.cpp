// Shard and merge: a run split with --shard K/N and joined by `microsim merge` is the single run,
// bit for bit (every histogram channel, every non-timing JSON number), on the exact quadric, the meshed
// ellipsoid and a heightfield; parts with a gap, an overlap, another seed or other binnings are refused
// (exit 2) with the ranges or the difference named, and nothing is written.
#include "cli_helpers.h"
#include "output_digest.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace microsim::test {
namespace {

struct ShardCase {
  std::string name;
  std::string prepare;  // a command run first ("" for none)
  std::string trace;    // trace vndf arguments without --shard/--out/--json
  int shards;
};

void PrintTo(const ShardCase& c, std::ostream* os) { *os << c.name; }

class ShardMerge : public ::testing::TestWithParam<ShardCase> {};

TEST_P(ShardMerge, MergedShardsAreTheSingleRunBitForBit) {
  const ShardCase& c = GetParam();
  const fs::path dir = scratch_dir("shard", c.name);
  if (!c.prepare.empty()) {
    ASSERT_EQ(run_cli(dir, c.prepare).exit_code, 0) << c.prepare;
  }
  const CliRun whole = run_cli(dir, c.trace + " --out whole.exr --json whole.json");
  ASSERT_EQ(whole.exit_code, 0) << whole.err;
  std::string parts;
  for (int k = c.shards; k >= 1; --k) {  // any order
    const std::string part = "part" + std::to_string(k);
    const CliRun r = run_cli(dir, c.trace + " --threads " + std::to_string(1 + k % 2) + " --shard " + std::to_string(k) +
                                      "/" + std::to_string(c.shards) + " --out " + part + ".json");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    parts += " " + part + ".json";
  }
  const CliRun merged = run_cli(dir, "merge" + parts + " --out merged.exr --json merged.json");
  ASSERT_EQ(merged.exit_code, 0) << merged.err;
  EXPECT_EQ(exr_digest(dir / "merged.exr"), exr_digest(dir / "whole.exr"));
  const json want = pinned_part(json::parse(slurp(dir / "whole.json")));
  expect_contains(want, pinned_part(json::parse(slurp(dir / "merged.json"))), c.name);
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(
    Runs, ShardMerge,
    ::testing::Values(
        ShardCase{"quadric", "", "trace vndf --alpha 0.3,0.6 --theta 50 --phi 20 --rays 300000 --seed 7", 4},
        ShardCase{"mesh", "", "trace vndf --alpha 0.5 --mesh-level 3 --theta 30 --rays 100000 --seed 2", 3},
        ShardCase{"heightfield", "surface build --assembly smith --res 256 --alpha 0.3 --seed 1 --out s.exr --quiet",
                  "trace vndf --surface s.exr --theta 40 --phi 10 --rays 150000 --seed 3", 5},
        ShardCase{"one_shard", "", "trace vndf --alpha 0.2 --theta 10 --rays 50000 --seed 1", 1}),
    [](const auto& info) { return info.param.name; });

// The parts of a run of 49 blocks (200000 rays) in three shards: [0, 16), [16, 32), [32, 49).
class MergeErrors : public ::testing::Test {
protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(scratch_dir("merge", "errors"));
    // The parts, made once per build of the tests (shared_fixture_dir) and copied here.
    copy_fixture_files(shared_fixture_dir("merge_errors", [](const fs::path& d) {
      const std::string run = "trace vndf --alpha 0.3 --theta 40 --rays 200000 --seed 7";
      for (int k = 1; k <= 3; ++k)
        ASSERT_EQ(run_cli(d, run + " --shard " + std::to_string(k) + "/3 --out p" + std::to_string(k) + ".json").exit_code, 0);
      ASSERT_EQ(run_cli(d, "trace vndf --alpha 0.3 --theta 40 --rays 200000 --seed 8 --shard 2/3 --out seed8.json").exit_code, 0);
      ASSERT_EQ(run_cli(d, run + " --rows 15 --shard 2/3 --out rows15.json").exit_code, 0);
      // A histogram of the single run: the part form of earlier versions.
      ASSERT_EQ(run_cli(d, "trace vndf --alpha 0.3 --theta 40 --rays 5000 --seed 7 --out old.exr").exit_code, 0);
    }), *dir_);
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }
  static void expect_refused(const std::string& parts, const std::string& message) {
    const auto before = snapshot_files(*dir_);
    const CliRun r = run_cli(*dir_, "merge " + parts + " --out merged.exr --json merged.json");
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
    EXPECT_TRUE(snapshot_files(*dir_) == before) << "merge " << parts << " wrote a file";
  }
  static fs::path* dir_;
};
fs::path* MergeErrors::dir_ = nullptr;

TEST_F(MergeErrors, AGapIsNamed) { expect_refused("p1.json p3.json", "blocks [16, 32) of [0, 49) are missing"); }
TEST_F(MergeErrors, AMissingEndIsNamed) { expect_refused("p1.json p2.json", "blocks [32, 49) of [0, 49) are missing"); }
TEST_F(MergeErrors, AnOverlapIsNamed) { expect_refused("p1.json p2.json p2.json p3.json", "blocks [16, 32) are in more than one part"); }
TEST_F(MergeErrors, AnotherSeedIsRefused) { expect_refused("p1.json seed8.json p3.json", "attribute seed"); }
TEST_F(MergeErrors, OtherBinningsAreRefused) { expect_refused("p1.json rows15.json p3.json", "not part of the same run"); }
TEST_F(MergeErrors, AnExrPartSaysPartsAreJson) {
  expect_refused("old.exr", "part 'old.exr' is an EXR file: parts are JSON now");
  expect_refused("p1.json old.exr", "re-run the shard");
}
TEST_F(MergeErrors, AnOutputThatIsAPartIsRefused) {
  const auto before = snapshot_files(*dir_);
  const CliRun r = run_cli(*dir_, "merge p1.json p2.json p3.json --out p2.json");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_TRUE(snapshot_files(*dir_) == before);
}
TEST_F(MergeErrors, ABadShardIsBadUsage) {
  for (const char* shard : {"0/3", "4/3", "3", "1/0", "a/b", "1/100"}) {
    const CliRun r = run_cli(*dir_, std::string("trace vndf --alpha 0.3 --theta 40 --rays 200000 --shard ") + shard + " --out x.json");
    EXPECT_EQ(r.exit_code, 2) << shard << ": " << r.err;
    EXPECT_NE(r.err.find("--shard"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(*dir_ / "x.json"));
  }
}

}  // namespace
}  // namespace microsim::test
