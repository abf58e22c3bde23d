// Regression pins (issue 9): seeded outputs of the command line, recorded from the build before the engine
// was rewritten, must stay bit-identical: every number of the JSON reports (p-values, statistics, hits,
// masking estimates and their standard errors) compared exactly, and every channel of the histogram and
// heightmap EXRs compared by a 64-bit FNV-1a digest of its float bits.
//
// The recorded values live in tests/data/pins/CASE.json. Keys that measure the machine (seconds, rates,
// memory), name paths, or say how many threads ran are not pinned. To record them again after a deliberate
// change of numbers (say so in the closing note, with the old and new values):
//   MICROSIM_RECORD_PINS=1 build/microsim_tests --gtest_filter='*RegressionPins*'
#include "cli_helpers.h"
#include "microgeom/exr_io.h"

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

// Keys that measure the machine (times, rates, memory), name paths, or count threads.
bool is_volatile_key(const std::string& key) {
  static const std::set<std::string> named = {"threads", "output", "path", "command", "outputs", "markdown"};
  auto ends_with = [&](std::string_view suffix) { return key.ends_with(suffix); };
  return named.count(key) || ends_with("seconds") || ends_with("_bytes") || ends_with("_mib") ||
         ends_with("per_ray") || ends_with("per_second") || key.find("rss") != std::string::npos;
}

// The report without the keys that measure the machine.
json pinned_part(const json& j) {
  if (j.is_object()) {
    json out = json::object();
    for (auto it = j.begin(); it != j.end(); ++it)
      if (!is_volatile_key(it.key())) out[it.key()] = pinned_part(it.value());
    return out;
  }
  if (j.is_array()) {
    json out = json::array();
    for (const auto& v : j) out.push_back(pinned_part(v));
    return out;
  }
  return j;
}

std::string fnv1a_hex(const std::vector<float>& data) {
  std::uint64_t h = 1469598103934665603ull;
  for (float f : data) {
    std::uint32_t bits;
    std::memcpy(&bits, &f, 4);
    for (int k = 0; k < 4; ++k) {
      h ^= (bits >> (8 * k)) & 0xffu;
      h *= 1099511628211ull;
    }
  }
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

json exr_digest(const fs::path& path) {
  const auto image = microgeom::read_exr(path);
  json d = {{"width", image.width}, {"height", image.height}, {"channels", json::object()}};
  for (const auto& c : image.channels) d["channels"][c.name] = fnv1a_hex(c.data);
  return d;
}

// Every value recorded in `want` must be in `got`, equal (numbers as doubles, exactly); keys added to the
// reports later are not pinned.
void expect_contains(const json& want, const json& got, const std::string& where) {
  if (want.is_object()) {
    ASSERT_TRUE(got.is_object()) << where << " is no longer an object";
    for (auto it = want.begin(); it != want.end(); ++it) {
      ASSERT_TRUE(got.contains(it.key())) << where << "/" << it.key() << " is missing";
      expect_contains(it.value(), got[it.key()], where + "/" + it.key());
    }
  } else if (want.is_array()) {
    ASSERT_TRUE(got.is_array() && got.size() == want.size()) << where << ": array size changed";
    for (std::size_t i = 0; i < want.size(); ++i) expect_contains(want[i], got[i], where + "/" + std::to_string(i));
  } else if (want.is_number()) {
    ASSERT_TRUE(got.is_number()) << where << " is no longer a number";
    EXPECT_EQ(want.get<double>(), got.get<double>()) << where;
  } else {
    EXPECT_EQ(want, got) << where;
  }
}

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
