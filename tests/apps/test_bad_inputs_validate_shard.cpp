// Bad-input table for `validate --shard K/N`, `stability --shard K/N` and the merge of their
// parts: a shard of what is not drawn (--from) or would be traced whole by every shard (--against
// ellipsoid), without --json, with --plot or --failures-only, or malformed; a part whose provenance or exact
// tallies are damaged. Each must exit 2 naming the bad value, and write nothing.
#include "cli_helpers.h"

#include <nlohmann/json.hpp>

#include <fstream>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_bad_inputs_validate_shard {

namespace {

using microsim::test::BadInputCase;
namespace fs = std::filesystem;

// Three shards of a validation (4 blocks), two of a stability sweep and a file of samples, made once per
// build of the tests.
const fs::path& fixture_dir() {
  static const fs::path dir = microsim::test::shared_fixture_dir("bad_validate_shard", [](const fs::path& d) {
    for (int k = 1; k <= 3; ++k)
      EXPECT_EQ(microsim::test::run_cli(d, "validate --sampler heitz2018 --alpha 0.3 --theta 30 --samples 200000 --shard " +
                                               std::to_string(k) + "/3 --json p" + std::to_string(k) + ".json")
                    .exit_code,
                0);
    for (int k = 1; k <= 2; ++k)
      EXPECT_EQ(microsim::test::run_cli(d, "stability --random-u 2 --shard " + std::to_string(k) + "/2 --json s" +
                                               std::to_string(k) + ".json")
                    .exit_code,
                0);
    std::ofstream(d / "in.txt") << "0 0 1\n0.1 0 0.99498743710662\n";
  });
  return dir;
}

void copy_fixtures(const fs::path& dir) {
  for (const char* name : {"p1.json", "p2.json", "p3.json", "s1.json", "s2.json", "in.txt"})
    fs::copy_file(fixture_dir() / name, dir / name);
}

// The fixtures, with part `name`'s JSON changed by `edit`.
std::function<void(const fs::path&)> part_with(std::string name, std::function<void(nlohmann::json&)> edit) {
  return [name, edit](const fs::path& dir) {
    copy_fixtures(dir);
    nlohmann::json j = nlohmann::json::parse(microsim::test::slurp(dir / name));
    edit(j);
    std::ofstream(dir / name) << j.dump(1) << "\n";
  };
}

const std::string kValidateShardable = "validate --sampler heitz2018 --alpha 0.3 --theta 30 --samples 200000 ";
const std::string kMergeValidateParts = "merge p1.json p2.json p3.json --json m.json";
const std::string kMergeStabilityParts = "merge s1.json s2.json --json m.json";

std::vector<BadInputCase> validate_shard_cases() {
  return {
      {"shard_with_from", "validate --from in.txt --alpha 0.3 --theta 30 --shard 1/2 --json q.json", 2,
       "--shard 1/2 with --from", copy_fixtures},
      {"shard_against_ellipsoid", kValidateShardable + "--against ellipsoid --shard 1/2 --json q.json", 2,
       "--shard 1/2 with --against ellipsoid", copy_fixtures},
      {"shard_without_json", kValidateShardable + "--shard 1/2", 2, "--shard 1/2: needs --json", copy_fixtures},
      {"shard_with_plot", kValidateShardable + "--shard 1/2 --plot f.svg --json q.json", 2, "--shard 1/2 with --plot",
       copy_fixtures},
      {"shard_zero", kValidateShardable + "--shard 0/3 --json q.json", 2, "--shard (K) '0'", copy_fixtures},
      {"shard_more_than_blocks", kValidateShardable + "--shard 1/5 --json q.json", 2, "'5'", copy_fixtures},
      {"shard_not_a_fraction", kValidateShardable + "--shard a/b --json q.json", 2, "--shard", copy_fixtures},
      {"all_shard_without_json", "validate --all --shard 1/2", 2, "--shard 1/2: needs --json", copy_fixtures},
      {"stability_shard_without_json", "stability --shard 1/2", 2, "--shard 1/2: needs --json", copy_fixtures},
      {"stability_shard_zero", "stability --shard 0/2 --json q.json", 2, "--shard (K) '0'", copy_fixtures},
      {"stability_shard_more_than_blocks", "stability --shard 1/834 --json q.json", 2, "'834'", copy_fixtures},
      {"stability_shard_failures_only", "stability --shard 1/2 --failures-only --json q.json", 2,
       "--shard 1/2 with --failures-only", copy_fixtures},
      {"tallies_short", kMergeValidateParts, 2, "tallies is not an array of 1",
       part_with("p2.json", [](nlohmann::json& j) { j["tallies"].erase(0); })},
      {"checks_not_exact", kMergeValidateParts, 2, "tallies/0/checks/0/mean",
       part_with("p2.json", [](nlohmann::json& j) { j["tallies"][0]["checks"][0]["mean"] = 0.5; })},
      {"checks_of_other_blocks", kMergeValidateParts, 2, "tallies/0/checks is not an array of the checks of 1 blocks",
       part_with("p2.json", [](nlohmann::json& j) { j["tallies"][0]["checks"].push_back(j["tallies"][0]["checks"][0]); })},
      {"sampler_unknown", kMergeValidateParts, 2, "'nope' is not a sampler of this build",
       part_with("p2.json", [](nlohmann::json& j) { j["provenance"]["parameters"]["sampler"] = "nope"; })},
      {"block_size_other", kMergeValidateParts, 2, "provenance/parameters/block_size",
       part_with("p2.json", [](nlohmann::json& j) { j["provenance"]["parameters"]["block_size"] = 4096; })},
      {"validate_blocks_beyond_run", kMergeValidateParts, 2, "provenance/blocks",
       part_with("p2.json", [](nlohmann::json& j) { j["provenance"]["blocks"] = {1, 9}; })},
      {"validate_with_surface", kMergeValidateParts + " --surface s.exr", 2, "--surface applies to heightfield parts", copy_fixtures},
      {"stability_row_unknown", kMergeStabilityParts, 2, "rows/0 is no (subject, regime)",
       part_with("s2.json", [](nlohmann::json& j) { j["rows"][0]["subject"] = "GGX::E"; })},
      {"stability_real_not_exact", kMergeStabilityParts, 2, "rows/1/cond_claimed",
       part_with("s2.json", [](nlohmann::json& j) { j["rows"][1]["cond_claimed"] = "nan"; })},
      {"stability_subjects_other", kMergeStabilityParts, 2, "provenance/parameters/subjects",
       part_with("s1.json", [](nlohmann::json& j) { j["provenance"]["parameters"]["subjects"].erase(0); })},
      {"stability_with_out", kMergeStabilityParts + " --out m.exr", 2, "--out 'm.exr'", copy_fixtures},
  };
}

class BadValidateShardInput : public ::testing::TestWithParam<BadInputCase> {};

TEST_P(BadValidateShardInput, ExitsTwoNamingTheValueAndWritesNothing) {
  microsim::test::expect_bad_input(GetParam(), "bad_validate_shard");
}

INSTANTIATE_TEST_SUITE_P(Cases, BadValidateShardInput, ::testing::ValuesIn(validate_shard_cases()),
                         [](const auto& info) { return info.param.name; });

}  // namespace

}  // namespace test_bad_inputs_validate_shard
