// End to end: `microsim validate --from DUMP --model smith-walk` on a renderer-style dump of a Smith
// multiple-scattering glass (GGX alpha 1, eta 1.5; the random walk of Heitz et al. 2016 used as a sampler:
// direction and weight per path, the paths it loses dropped and counted) at 85 deg and from inside at 120 deg:
// the correct walk passes, the walk that keeps its height after a refraction is rejected (R and T wrong while
// R + T stays 1), at the level 0.01 with fixed seeds; bad usage is exit 2.
#include "cli_helpers.h"

#include "scatter/smith_walk.h"
#include "validate/sample_io.h"

#include <fmt/core.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <string>

namespace microsim::test {
namespace {

// A dump of `paths` walks from theta (degrees, phi 0), as rows x,y,z,weight; returns the dropped count.
// `fireflies`: that many rows (spread over the dump) get their weight times 1e4.
std::uint64_t write_walk_dump(const fs::path& path, double theta, detail::WalkFault fault, std::uint64_t seed,
                              int fireflies = 0) {
  ScatterOptions o;
  const double t = theta * kPi<double> / 180;
  o.wi = Vec3<double>(std::sin(t), 0, std::cos(t));
  o.material = Material::dielectric(1.5);
  o.paths = 200'000;
  o.seed = seed;
  WalkSamples s = detail::smith_walk_samples(SmithMicrosurface{NdfKind::ggx, 1.0, 1.0}, o, fault);
  const std::size_t row = 3 + std::size_t(s.channels), rows = s.rows.size() / row;
  for (int k = 0; k < fireflies; ++k) s.rows[(std::size_t(k) * rows / std::size_t(fireflies) + 10) * row + 3] *= 1e4;
  write_npy_table(path, s.rows, 3 + std::size_t(s.channels), true);
  return s.dropped;
}

std::string walk_args(const fs::path& dump, double theta, std::uint64_t dropped) {
  return fmt::format("validate --from '{}' --model smith-walk --material dielectric:1.5 --alpha 1 --theta {} "
                     "--columns x,y,z,weight --dropped {} --json v.json",
                     dump.string(), theta, dropped);
}

TEST(WalkValidationCli, ACorrectSmithGlassPassesAndTheStaleHeightWalkIsRejected) {
  const fs::path dir = scratch_dir("walk_validation", "glass");
  for (const double theta : {85.0, 120.0}) {
    const fs::path good = dir / "good.npy", stale = dir / "stale.npy";
    const std::uint64_t d_good = write_walk_dump(good, theta, detail::WalkFault::none, 11);
    const std::uint64_t d_stale = write_walk_dump(stale, theta, detail::WalkFault::keep_height_on_refraction, 11);
    const CliRun ok = run_cli(dir, walk_args(good, theta, d_good));
    EXPECT_EQ(ok.exit_code, 0) << theta << "\n" << ok.out << ok.err;
    const nlohmann::json j = nlohmann::json::parse(slurp(dir / "v.json"));
    EXPECT_EQ(j["verdict"], "pass");
    EXPECT_NEAR(j["albedo_reflected"]["dump"]["value"].get<double>() + j["albedo_transmitted"]["dump"]["value"].get<double>(),
                1.0, 1e-3) << "a dielectric walk conserves energy";
    const CliRun bad = run_cli(dir, walk_args(stale, theta, d_stale));
    EXPECT_EQ(bad.exit_code, 1) << theta << "\n" << bad.out << bad.err;
    EXPECT_NE(bad.out.find("REJECTED"), std::string::npos) << bad.out;
    const nlohmann::json b = nlohmann::json::parse(slurp(dir / "v.json"));
    EXPECT_NEAR(b["albedo_reflected"]["dump"]["value"].get<double>() + b["albedo_transmitted"]["dump"]["value"].get<double>(),
                1.0, 1e-3) << "the stale height conserves energy too";
  }
  fs::remove_all(dir);
}

// Three rows of a correct dump with weights 1e4 times too large raise the albedo and its standard error together
// (z stays near sqrt(3)): the row holding the weights' spread is named and the dump rejected.
TEST(WalkValidationCli, FirefliesAreRejectedNamingTheRow) {
  const fs::path dir = scratch_dir("walk_validation", "fireflies");
  const fs::path dump = dir / "fireflies.npy";
  const std::uint64_t dropped = write_walk_dump(dump, 85.0, detail::WalkFault::none, 11, 3);
  const CliRun r = run_cli(dir, walk_args(dump, 85.0, dropped));
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_NE(r.out.find("a firefly"), std::string::npos) << r.out;
  const nlohmann::json j = nlohmann::json::parse(slurp(dir / "v.json"));
  EXPECT_EQ(j["verdict"], "fail");
  EXPECT_GT(j["dominant_weight"]["share"].get<double>(), 0.1);
  EXPECT_EQ(j["failures"].size(), 1u) << "the albedo tests alone pass the fireflies: " << j["failures"].dump();
  fs::remove_all(dir);
}

TEST(WalkValidationCli, BadUsageIsExit2) {
  const fs::path dir = scratch_dir("walk_validation", "usage");
  const fs::path dump = dir / "d.npy";
  write_walk_dump(dump, 60, detail::WalkFault::none, 3);
  const std::string from = fmt::format("validate --from '{}' ", dump.string());
  const std::pair<std::string, std::string> cases[] = {
      {from + "--model smith-walk --alpha 1 --theta 60 --columns x,y,z,weight", "needs --material"},
      {from + "--model phong --material dielectric:1.5 --alpha 1 --theta 60", "--model phong"},
      {from + "--model smith-walk --material dielectric:1.5 --alpha 1 --theta 60 --bsdf mirror", "--bsdf"},
      {from + "--model smith-walk --material mirror --alpha 1 --theta 120 --columns x,y,z,weight", "--theta 120"},
      {from + "--material dielectric:1.5 --alpha 1 --theta 60", "apply to --model smith-walk"},
      {"validate --model smith-walk --material mirror --alpha 1 --theta 60", "--from"},
  };
  for (const auto& [args, message] : cases) {
    const CliRun r = run_cli(dir, args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << args << "\n" << r.err;
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace microsim::test
