// Bad-input table for `trace masking --shard K/N` and the merge of masking parts: a shard
// with --vndf-rays or --table (the alternative, trace vndf --surface S --shard K/N, is named), without
// --json, or malformed; a masking part whose provenance or exact sums are damaged. Each must exit 2 naming
// the bad value, and write nothing.
#include "cli_helpers.h"

#include <nlohmann/json.hpp>

#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_bad_inputs_masking_shard {

namespace {

using microsim::test::BadInputCase;
namespace fs = std::filesystem;

// A surface and the three shards of a masking run on it (25 blocks), made once per build of the tests.
const fs::path& fixture_dir() {
  static const fs::path dir = microsim::test::shared_fixture_dir("bad_masking_shard", [](const fs::path& d) {
    EXPECT_EQ(microsim::test::run_cli(d, "surface build --assembly sorted --res 256 --alpha 0.5 --seed 2 --out s.exr --quiet")
                  .exit_code,
              0);
    for (int k = 1; k <= 3; ++k)
      EXPECT_EQ(microsim::test::run_cli(d, "trace masking --surface s.exr --theta 60 --samples 100000 --seed 7 --shard " +
                                               std::to_string(k) + "/3 --json p" + std::to_string(k) + ".json")
                    .exit_code,
                0);
  });
  return dir;
}

void copy_fixtures(const fs::path& dir) {
  for (const char* name : {"s.exr", "p1.json", "p2.json", "p3.json"}) fs::copy_file(fixture_dir() / name, dir / name);
}

// The fixtures, with part 2's JSON changed by `edit`.
std::function<void(const fs::path&)> part2_with(std::function<void(nlohmann::json&)> edit) {
  return [edit](const fs::path& dir) {
    copy_fixtures(dir);
    nlohmann::json j = nlohmann::json::parse(microsim::test::slurp(dir / "p2.json"));
    edit(j);
    std::ofstream(dir / "p2.json") << j.dump(2) << "\n";
  };
}

const std::string kTraceMasking = "trace masking --surface s.exr --theta 60 --samples 100000 --seed 7 ";
const std::string kMergeMaskingParts = "merge p1.json p2.json p3.json --json m.json";

std::vector<BadInputCase> masking_shard_cases() {
  return {
      {"shard_with_vndf_rays", kTraceMasking + "--shard 1/3 --vndf-rays 1000 --json q.json", 2,
       "trace vndf --surface s.exr --shard K/N", copy_fixtures},
      {"shard_with_table", "trace masking --table --res 256 --shard 1/3 --json q.json", 2,
       "trace vndf --surface S --shard K/N", copy_fixtures},
      {"shard_without_json", kTraceMasking + "--shard 1/3", 2, "--shard 1/3: needs --json", copy_fixtures},
      {"shard_zero", kTraceMasking + "--shard 0/3 --json q.json", 2, "--shard (K) '0'", copy_fixtures},
      {"shard_beyond", kTraceMasking + "--shard 4/3 --json q.json", 2, "--shard", copy_fixtures},
      {"shard_more_than_blocks", kTraceMasking + "--shard 1/26 --json q.json", 2, "'26'", copy_fixtures},
      {"shard_not_a_fraction", kTraceMasking + "--shard a/b --json q.json", 2, "--shard", copy_fixtures},
      {"sum_not_hex", kMergeMaskingParts, 2, "sums/g1/x",
       part2_with([](nlohmann::json& j) { j["sums"]["g1"]["x"] = "0x12"; })},
      {"sum_missing", kMergeMaskingParts, 2, "sums/mirror/pred_analytic is missing",
       part2_with([](nlohmann::json& j) { j["sums"]["mirror"].erase("pred_analytic"); })},
      {"count_negative", kMergeMaskingParts, 2, "sums/samples is not a count",
       part2_with([](nlohmann::json& j) { j["sums"]["samples"] = -5; })},
      {"bins_short", kMergeMaskingParts, 2, "sums/normal is not an array of 10 bins",
       part2_with([](nlohmann::json& j) { j["sums"]["normal"].erase(0); })},
      {"blocks_beyond_run", kMergeMaskingParts, 2, "provenance/blocks",
       part2_with([](nlohmann::json& j) { j["provenance"]["blocks"] = {9, 99}; })},
      {"producer_other", kMergeMaskingParts, 2, "part 'p2.json': not a trace masking report",
       part2_with([](nlohmann::json& j) { j["provenance"]["producer"] = "trace vndf"; })},
      {"geometry_unknown", kMergeMaskingParts, 2, "provenance/parameters/geometry",
       part2_with([](nlohmann::json& j) { j["provenance"]["parameters"]["geometry"] = "voxels"; })},
      {"not_json", kMergeMaskingParts, 2, "part 'p2.json': not a JSON file",
       [](const fs::path& dir) {
         copy_fixtures(dir);
         std::ofstream(dir / "p2.json") << "{\"provenance\": ";
       }},
      {"surface_missing", kMergeMaskingParts + " --surface gone.exr", 2, "--surface 'gone.exr': no such file", copy_fixtures},
  };
}

class BadMaskingShardInput : public ::testing::TestWithParam<BadInputCase> {};

TEST_P(BadMaskingShardInput, ExitsTwoNamingTheValueAndWritesNothing) {
  microsim::test::expect_bad_input(GetParam(), "bad_masking_shard");
}

INSTANTIATE_TEST_SUITE_P(Cases, BadMaskingShardInput, ::testing::ValuesIn(masking_shard_cases()),
                         [](const auto& info) { return info.param.name; });

}  // namespace

}  // namespace test_bad_inputs_masking_shard
