// Regression pins: seeded outputs of the command line, recorded from the build before the engine
// was rewritten, must stay bit-identical: every number of the JSON reports (p-values, statistics, hits,
// masking estimates and their standard errors) compared exactly, and every channel of the histogram and
// heightmap EXRs compared by a 64-bit FNV-1a digest of its float bits.
//
// The recorded values live in tests/data/pins/CASE.json. Keys that measure the machine (seconds, rates,
// memory), name paths, or say how many threads ran are not pinned. To record them again after a deliberate
// change of numbers (say so in the closing note, with the old and new values):
//   MICROSIM_RECORD_PINS=1 build/microsim_tests --gtest_filter='*RegressionPins*'
#include "cli_helpers.h"
#include "output_digest.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <set>
#include <vector>

namespace microsim::test {
namespace {

using nlohmann::json;

// A command's arguments, run in order in one scratch directory, and the files whose contents are pinned.
struct PinCase {
  std::string name;
  std::vector<std::string> commands;
  std::vector<std::string> json_files;
  std::vector<std::string> exr_files;
};

void PrintTo(const PinCase& c, std::ostream* os) { *os << c.name; }

json run_case(const PinCase& c) {
  const fs::path dir = scratch_dir("pins", c.name);
  for (const auto& args : c.commands) {
    const CliRun r = run_cli(dir, args);
    EXPECT_EQ(r.exit_code, 0) << "microsim " << args << "\n" << r.err;
  }
  json got = {{"json", json::object()}, {"exr", json::object()}};
  for (const auto& f : c.json_files) got["json"][f] = pinned_part(json::parse(slurp(dir / f)));
  for (const auto& f : c.exr_files) got["exr"][f] = exr_digest(dir / f);
  fs::remove_all(dir);
  return got;
}

const std::vector<PinCase>& pin_cases() {
  static const std::vector<PinCase> cases = {
      {"quadric_isotropic",
       {"trace vndf --alpha 0.3 --theta 40 --phi 20 --rays 200000 --seed 7 --threads 2 --out q.exr --json q.json"},
       {"q.json"}, {"q.exr"}},
      {"quadric_anisotropic_one_thread",
       {"trace vndf --alpha 0.2,0.5 --theta 60 --phi 30 --rays 100000 --seed 3 --threads 1 --out q.exr --json q.json"},
       {"q.json"}, {"q.exr"}},
      {"ellipsoid_mesh",
       {"trace vndf --alpha 0.5 --mesh-level 4 --theta 50 --rays 100000 --seed 4 --threads 2 --out q.exr --json q.json"},
       {"q.json"}, {"q.exr"}},
      {"heightfield",
       {"surface build --assembly smith --res 256 --alpha 0.3 --seed 1 --out s.exr --json s.json --quiet",
        "trace vndf --surface s.exr --theta 30 --phi 10 --rays 200000 --seed 3 --threads 2 --out h.exr --json h.json"},
       {"s.json", "h.json"}, {"s.exr", "h.exr"}},
      {"masking",
       {"surface build --assembly sorted --res 256 --alpha 0.5 --seed 2 --out s.exr --quiet",
        "trace masking --surface s.exr --theta 60 --phi 20 --theta-l 40 --samples 200000 --vndf-rays 100000 "
        "--seed 2 --threads 2 --json m.json"},
       {"m.json"}, {"s.exr"}},
      {"validate_analytic",
       {"validate --sampler heitz2018 --alpha 0.3 --theta 40 --samples 100000 --seed 5 --json v.json"},
       {"v.json"}, {}},
      {"validate_float_anisotropic",
       {"validate --sampler dupuy2023 --float --alpha 0.2,0.5 --theta 70 --phi 30 --samples 100000 --seed 5 "
        "--json v.json"},
       {"v.json"}, {}},
      {"validate_against_ellipsoid",
       {"validate --sampler heitz2018 --alpha 0.4 --theta 50 --samples 100000 --seed 6 --against ellipsoid "
        "--rays 200000 --json v.json"},
       {"v.json"}, {}},
  };
  return cases;
}

class RegressionPins : public ::testing::TestWithParam<PinCase> {};

TEST_P(RegressionPins, SeededOutputsAreBitIdenticalToTheRecordedBuild) {
  const PinCase& c = GetParam();
  const fs::path golden = fs::path(MICROSIM_TEST_DATA) / "pins" / (c.name + ".json");
  const json got = run_case(c);
  if (std::getenv("MICROSIM_RECORD_PINS")) {
    fs::create_directories(golden.parent_path());
    std::ofstream(golden) << got.dump(1) << "\n";
    GTEST_SKIP() << "recorded " << golden;
  }
  ASSERT_TRUE(fs::exists(golden)) << golden << " was never recorded";
  expect_contains(json::parse(slurp(golden)), got, c.name);
}

// A negative control: another seed changes the pinned numbers and digests, so the comparison can fail.
TEST(RegressionPinsControl, AnotherSeedIsCaught) {
  PinCase c = pin_cases()[0];
  c.commands = {"trace vndf --alpha 0.3 --theta 40 --phi 20 --rays 200000 --seed 8 --threads 2 --out q.exr --json q.json"};
  const json got = run_case(c);
  const json want = json::parse(slurp(fs::path(MICROSIM_TEST_DATA) / "pins" / "quadric_isotropic.json"));
  EXPECT_NE(want["json"]["q.json"]["p_value"], got["json"]["q.json"]["p_value"]);
  EXPECT_NE(want["exr"]["q.exr"]["channels"]["sphere.count"], got["exr"]["q.exr"]["channels"]["sphere.count"]);
}

INSTANTIATE_TEST_SUITE_P(Cases, RegressionPins, ::testing::ValuesIn(pin_cases()),
                         [](const auto& info) { return info.param.name; });

}  // namespace
}  // namespace microsim::test
