// `microsim run --shard K/N` and `--merge` end to end (src/experiment/shards.h): a small spec (a VNDF and a
// per-order scattering measurement, split; an analytic albedo table, run by the merge) in 2 and in 3 shards
// (an uneven split), merged: results.json's measured values, every histogram and table equal to the
// one-process run's, bit for bit. The checks can fail: merging with a shard missing, given twice, of another
// seed or another N, or with a part file changed is refused (exit 2, the problem named, nothing written), and
// so are bad --shard values. The merge decides the verdict as the one-process run does: a rejected validation
// (the talk listing, its samples drawn by the shards) exits 1 with the one-process run's directory.
#include "cli_helpers.h"
#include "run_directory_contents.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_experiment_shard_cli {

namespace {

namespace fs = std::filesystem;
using microsim::test::run_cli;
using microsim::test::run_directory_contents;
using microsim::test::scratch_dir;
using microsim::test::snapshot_files;


// Runs shards 1..n of the spec into DIR/n-K; returns the --merge arguments, each prefixed with `prefix`.
std::string run_shards(const fs::path& dir, int n, const std::string& prefix = "") {
  std::string parts;
  for (int k = 1; k <= n; ++k) {
    const std::string part = std::to_string(n) + "-" + std::to_string(k);
    const auto r = run_cli(dir, "run shards.toml --threads 1 --out " + part + " --shard " + std::to_string(k) + "/" +
                                    std::to_string(n));
    EXPECT_EQ(r.exit_code, 0) << r.err;
    parts += " " + prefix + part;
  }
  return parts;
}

class ExperimentShardCli : public ::testing::Test {
protected:
  void SetUp() override {
    dir_ = scratch_dir("shard_cli", ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::ofstream(dir_ / "shards.toml") << microsim::test::split_spec("shards", 11);
    fs::create_directory(dir_ / "a");
  }
  // The one-process run, in a/out: every run directory is `out` beside the spec's `..`: the same command.
  void run_alone() {
    const auto alone = run_cli(dir_ / "a", "run ../shards.toml --out out --threads 1");
    ASSERT_EQ(alone.exit_code, 0) << alone.err;
    expected_ = run_directory_contents(dir_ / "a" / "out");
  }
  // A bad merge: exit 2, `message` on stderr, nothing written or changed.
  void expect_refused(const std::string& args, const std::string& message) {
    const auto before = snapshot_files(dir_);
    const auto r = run_cli(dir_, "run shards.toml --threads 1 " + args);
    EXPECT_EQ(r.exit_code, 2) << args << ": " << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << args << ": " << r.err;
    EXPECT_EQ(snapshot_files(dir_), before) << args;
  }
  fs::path dir_;
  std::string expected_;
};

TEST_F(ExperimentShardCli, TwoAndThreeShardsMergeIntoTheOneProcessRunBitForBit) {
  ASSERT_NO_FATAL_FAILURE(run_alone());
  ASSERT_NE(expected_.find("scattering-1.exr"), std::string::npos);
  EXPECT_TRUE(microsim::test::has_uneven_round(dir_ / "a" / "out", 3, true)) << "3 shards: an uneven split";
  for (int n : {2, 3}) {
    const std::string parts = run_shards(dir_, n, "../");
    const fs::path merged = dir_ / ("merged" + std::to_string(n));
    fs::create_directory(merged);
    const auto r = run_cli(merged, "run ../shards.toml --out out --threads 1 --merge" + parts);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(run_directory_contents(merged / "out"), expected_) << n << " shards";
  }
}

TEST_F(ExperimentShardCli, AMissingRepeatedForeignOrChangedShardIsRefusedNothingWritten) {
  const std::string parts = run_shards(dir_, 3);
  expect_refused("--out m --merge 3-1 3-3", "shard 2/3 is missing");
  expect_refused("--out m --merge 3-1 3-2 3-2 3-3", "given twice");
  run_shards(dir_, 2);
  expect_refused("--out m --merge 3-1 3-2 2-2", "a shard of 2");
  ASSERT_EQ(run_cli(dir_, "run shards.toml --threads 1 --out s12 --shard 2/3 --seed 12").exit_code, 0);
  expect_refused("--out m --merge 3-1 s12 3-3", "a shard of seed 12");
  std::string bytes = microsim::test::slurp(dir_ / "3-2" / "part-0.bin");
  bytes[bytes.size() - 1] ^= 1;  // one count changed by one
  std::ofstream(dir_ / "3-2" / "part-0.bin", std::ios::binary) << bytes;
  expect_refused("--out m --merge" + parts, "part-0.bin is missing, or not what shard.json records");
  fs::create_directory(dir_ / "a" / "out");  // a directory, but no shard's
  expect_refused("--out m --merge 3-1 a/out", "holds no shard.json");
}

TEST_F(ExperimentShardCli, BadShardValuesAreRefusedNothingWritten) {
  expect_refused("--out p --shard 0/2", "--shard (K)");
  expect_refused("--out p --shard 3/2", "--shard (K)");
  expect_refused("--out p --shard 1/0", "--shard (N)");
  expect_refused("--out p --shard 2", "not a shard K/N");
  expect_refused("--out p --shard 1/2 --merge a/out", "not with --merge");
  fs::create_directory(dir_ / "a" / "out");
  std::ofstream(dir_ / "a" / "out" / "results.json") << "{}";
  expect_refused("--out a/out --shard 1/2", "must be new or empty");
}

// The talk listing validated with its samples split over 2 shards (2 blocks): each shard exits 0 (a part holds
// no verdict), the merge exits 1 with the one-process run's directory, verdict fail, the validation rejected.
TEST_F(ExperimentShardCli, AMergeOfARejectedValidationExits1AsTheOneProcessRunDoes) {
  std::ofstream(dir_ / "talk.toml") << "name = \"talk\"\nseed = 2\n[[material]]\nname = \"m\"\nalpha = 0.3\n"
                                       "type = \"mirror\"\n[[quantity]]\nkind = \"validation\"\nmaterial = \"m\"\n"
                                       "sampler = \"heitz2018-talk\"\ntheta = [40]\nrows = 7\ndetect_tv = 0.01\n";
  const auto alone = run_cli(dir_ / "a", "run ../talk.toml --out out --threads 1");
  ASSERT_EQ(alone.exit_code, 1) << alone.err;
  for (const char* k : {"1", "2"}) {
    const auto part = run_cli(dir_, std::string("run talk.toml --threads 1 --out t-") + k + " --shard " + k + "/2");
    ASSERT_EQ(part.exit_code, 0) << part.err;
  }
  fs::create_directory(dir_ / "m");
  const auto merged = run_cli(dir_ / "m", "run ../talk.toml --out out --threads 1 --merge ../t-1 ../t-2");
  EXPECT_EQ(merged.exit_code, 1) << merged.err;
  EXPECT_NE(merged.out.find("Verdict: FAIL (rejected: "), std::string::npos) << merged.out;
  EXPECT_EQ(run_directory_contents(dir_ / "m" / "out"), run_directory_contents(dir_ / "a" / "out"));
  const auto doc = nlohmann::json::parse(microsim::test::slurp(dir_ / "m" / "out" / "results.json"));
  EXPECT_EQ(doc["results"]["verdict"], "fail");
  EXPECT_EQ(doc["results"]["rejected"].size(), 1u);
  EXPECT_GE(doc["results"]["measurements"][0]["rounds"][0]["units"].get<std::uint64_t>(), 65537u) << "2 blocks: split";
  fs::remove_all(dir_);
}

// A validation of one block (at most 65536 samples) split over 3 shards: two of them run no block and their
// parts add nothing; the merge is the one-process run.
TEST_F(ExperimentShardCli, ShardsOfNoBlockMergeAsTheOneProcessRun) {
  std::ofstream(dir_ / "small.toml") << "name = \"small\"\nseed = 2\n[[material]]\nname = \"m\"\nalpha = 0.3\n"
                                        "type = \"mirror\"\n[[quantity]]\nkind = \"validation\"\nmaterial = \"m\"\n"
                                        "sampler = \"heitz2018\"\ntheta = [40]\nrows = 7\ndetect_tv = 0.05\n";
  const auto alone = run_cli(dir_ / "a", "run ../small.toml --out out --threads 1");
  ASSERT_EQ(alone.exit_code, 0) << alone.err;
  std::string parts;
  for (const char* k : {"1", "2", "3"}) {
    const auto part = run_cli(dir_, std::string("run small.toml --threads 1 --out s-") + k + " --shard " + k + "/3");
    ASSERT_EQ(part.exit_code, 0) << part.err;
    parts += std::string(" ../s-") + k;
  }
  fs::create_directory(dir_ / "m");
  const auto merged = run_cli(dir_ / "m", "run ../small.toml --out out --threads 1 --merge" + parts);
  ASSERT_EQ(merged.exit_code, 0) << merged.err;
  EXPECT_EQ(run_directory_contents(dir_ / "m" / "out"), run_directory_contents(dir_ / "a" / "out"));
  const auto doc = nlohmann::json::parse(microsim::test::slurp(dir_ / "m" / "out" / "results.json"));
  EXPECT_LE(doc["results"]["measurements"][0]["rounds"][0]["units"].get<std::uint64_t>(), 65536u) << "one block";
  fs::remove_all(dir_);
}

}  // namespace

}  // namespace test_experiment_shard_cli
