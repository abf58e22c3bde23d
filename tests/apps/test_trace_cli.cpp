// End-to-end tests of `microsim trace vndf --surface ellipsoid`: outputs (EXR histogram, JSON summary,
// mesh), exit codes, bad input (exit 2, a message naming the bad value, nothing written), and Ctrl-C
// (exit 130, a partial histogram written).
#include "cli_helpers.h"
#include "stats/histogram_io.h"
#include "core/random.h"
#include "validate/sample_io.h"
#include "microfacet/samplers.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include <sys/wait.h>
#include <unistd.h>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_trace_cli {

namespace fs = std::filesystem;

namespace {

using microsim::test::CliRun;
using microsim::test::file_count;
using microsim::test::slurp;

CliRun run_trace_cli(const fs::path& dir, const std::string& args) { return microsim::test::run_cli(dir, args); }
fs::path trace_cli_dir(const std::string& name) { return microsim::test::scratch_dir("trace_cli", name); }

}  // namespace

TEST(TraceCli, WritesHistogramJsonAndMesh) {
  const auto dir = trace_cli_dir("ok");
  const CliRun r = run_trace_cli(dir, "trace vndf --alpha 0.3,0.6 --theta 60 --phi 15 --rays 200000 --seed 4 --rows 15 "
                            "--out h.exr --json h.json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("distance to analytic D_v"), std::string::npos) << r.out;
  const nlohmann::json j = nlohmann::json::parse(slurp(dir / "h.json"));
  for (const char* key : {"rays", "hits", "rays_per_second", "total_variation", "noise_floor_tv", "p_value",
                          "partial", "expected_hit_fraction", "analysis"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["rays"], 200000);
  EXPECT_EQ(j["partial"], false);
  EXPECT_GT(j["p_value"].get<double>(), 0.001);  // the exact oracle (fixed seed)
  const microsim::TracedHistogram h = microsim::read_histogram_exr(dir / "h.exr");
  EXPECT_EQ(h.rays, 200000u);
  EXPECT_EQ(h.hits, j["hits"].get<std::uint64_t>());
  EXPECT_FALSE(h.partial);
  EXPECT_EQ(h.attributes.at("surface"), "ellipsoid");
  EXPECT_EQ(h.attributes.at("seed"), "4");
  EXPECT_EQ(h.attributes.at("theta"), "60");
  ASSERT_EQ(h.binnings.size(), 2u);
  EXPECT_EQ(h.binnings[0].rows(), 15);
  ASSERT_EQ(h.probability[1].size(), std::size_t(h.binnings[1].size()));  // the expected channel
  // Same seed, other thread count: the same histogram.
  const CliRun r1 = run_trace_cli(dir, "trace vndf --alpha 0.3,0.6 --theta 60 --phi 15 --rays 200000 --seed 4 --rows 15 "
                             "--threads 1 --out h1.exr");
  ASSERT_EQ(r1.exit_code, 0) << r1.err;
  EXPECT_EQ(microsim::read_histogram_exr(dir / "h1.exr").counts, h.counts);
  // A mesh level, written out.
  const CliRun m = run_trace_cli(dir, "trace vndf --alpha 0.5 --theta 30 --rays 20000 --mesh-level 2 --rows 7 --out m.exr "
                            "--mesh-out m.ply");
  ASSERT_EQ(m.exit_code, 0) << m.err;
  EXPECT_TRUE(fs::exists(dir / "m.ply"));
  EXPECT_NE(m.out.find("mesh level 2"), std::string::npos);
  EXPECT_EQ(microsim::read_histogram_exr(dir / "m.exr").attributes.at("mesh_level"), "2");
  EXPECT_EQ(file_count(dir), 5u);  // h.exr h.json h1.exr m.exr m.ply: no temporaries
  fs::remove_all(dir);
}

TEST(TraceCli, BadInputExits2AndWritesNothing) {
  const auto dir = trace_cli_dir("bad");
  const std::string ok = " --rays 1000 --out h.exr --json h.json";
  const std::pair<std::string, std::string> cases[] = {
      {"trace vndf --alpha 0 --theta 30" + ok, "--alpha"},
      {"trace vndf --alpha -0.5 --theta 30" + ok, "--alpha"},
      {"trace vndf --alpha nan --theta 30" + ok, "--alpha"},
      {"trace vndf --alpha inf --theta 30" + ok, "--alpha"},
      {"trace vndf --alpha 0.5,abc --theta 30" + ok, "abc"},
      {"trace vndf --alpha 0.5 --theta 90" + ok, "--theta 90"},
      {"trace vndf --alpha 0.5 --theta -1" + ok, "--theta"},
      {"trace vndf --alpha 0.5 --theta nan" + ok, "--theta"},
      {"trace vndf --alpha 0.5 --theta 30 --rays 0 --out h.exr", "--rays '0'"},
      {"trace vndf --alpha 0.5 --theta 30 --rays -5 --out h.exr", "--rays '-5'"},
      {"trace vndf --alpha 0.5 --theta 30 --rays 1000 --out no_such_dir/h.exr", "no_such_dir"},
      {"trace vndf --alpha 0.5 --theta 30 --rays 1000 --out h.exr --json no_such_dir/h.json", "no_such_dir"},
      {"trace vndf --alpha 0.5 --theta 30 --rays 1000 --out h.txt", "--out"},
      {"trace vndf --surface sphere --alpha 0.5 --theta 30" + ok, "sphere"},
      {"trace vndf --theta 30" + ok, "--alpha"},
      {"trace vndf --alpha 0.5 --theta 30 --mesh-out m.ply" + ok, "--mesh-out"},
      {"trace vndf --alpha 0.5 --theta 30 --mesh-level 12" + ok, "--mesh-level '12'"},
      {"trace vndf --alpha 0.5 --theta 30 --rows 16" + ok, "--rows '16'"},
  };
  for (const auto& [args, needle] : cases) {
    const CliRun r = run_trace_cli(dir, args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << args << "\nstderr: " << r.err;
    EXPECT_EQ(file_count(dir), 0u) << args;
  }
  fs::remove_all(dir);
}

// Ctrl-C during a long run: exit 130, and the histogram of the rays traced so far is written, marked
// partial (in the EXR attributes and the JSON).
TEST(TraceCli, InterruptWritesPartialHistogram) {
  const auto dir = trace_cli_dir("sigint");
  const std::string binary = microsim::test::microsim_binary();
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    if (::chdir(dir.c_str()) != 0) ::_exit(99);
    std::freopen("stdout.txt", "w", stdout);
    std::freopen("stderr.txt", "w", stderr);
    ::execl(binary.c_str(), binary.c_str(), "trace", "vndf", "--alpha", "0.5", "--theta", "40", "--rays",
            "100000000000", "--rows", "7", "--out", "h.exr", "--json", "h.json", static_cast<char*>(nullptr));
    ::_exit(98);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  ::kill(pid, SIGINT);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status)) << "killed by a signal";
  EXPECT_EQ(WEXITSTATUS(status), 130) << slurp(dir / "stderr.txt");
  const microsim::TracedHistogram h = microsim::read_histogram_exr(dir / "h.exr");
  EXPECT_TRUE(h.partial);
  EXPECT_GT(h.rays, 0u);
  EXPECT_LT(h.rays, 100000000000ull);
  const nlohmann::json j = nlohmann::json::parse(slurp(dir / "h.json"));
  EXPECT_EQ(j["partial"], true);
  EXPECT_EQ(j["rays"].get<std::uint64_t>(), h.rays);
  EXPECT_NE(slurp(dir / "stdout.txt").find("PARTIAL"), std::string::npos);
  fs::remove_all(dir);
}

// `microsim validate --against ellipsoid | HIST.exr` (the validator's front end calling compare.h): same
// verdicts and exit codes as the analytic validation; --from works too; bad combinations exit 2.
TEST(TraceCli, ValidateAgainstTracedOracle) {
  const auto dir = trace_cli_dir("against");
  const std::string cfg = " --alpha 0.3,0.6 --theta 70 --phi 20";
  const CliRun good = run_trace_cli(dir, "validate --sampler heitz2018" + cfg + " --against ellipsoid --rays 1000000 "
                                "--samples 300000 --json v.json");
  EXPECT_EQ(good.exit_code, 0) << good.out << good.err;
  const nlohmann::json j = nlohmann::json::parse(slurp(dir / "v.json"));
  for (const char* key : {"verdict", "p_value", "statistic", "dof", "samples", "against", "oracle_rays"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["verdict"], "pass");
  const CliRun bad = run_trace_cli(dir, "validate --sampler heitz2018-talk" + cfg + " --against ellipsoid --rays 1000000 "
                               "--samples 300000");
  EXPECT_EQ(bad.exit_code, 1) << bad.out << bad.err;
  // A histogram traced once, then samples from a file validated against it.
  ASSERT_EQ(run_trace_cli(dir, "trace vndf" + cfg + " --rays 1000000 --out h.exr").exit_code, 0);
  std::vector<microsim::Vec3<double>> heitz, ndf;
  const microsim::GGX<double> ggx(0.3, 0.6);
  const auto wi = microsim::direction_from_degrees(70.0, 20.0);
  microsim::CounterRng rng(77, 0);
  for (int i = 0; i < 300'000; ++i) {
    const microsim::Vec2<double> u(rng.uniform(), rng.uniform());
    heitz.push_back(microsim::sample_heitz2018(ggx, wi, u)->direction);
    ndf.push_back(microsim::sample_ndf(ggx, wi, u)->direction);
  }
  microsim::write_npy(dir / "heitz.npy", heitz, /*as_float32=*/true);
  microsim::write_npy(dir / "ndf.npy", ndf, /*as_float32=*/false);
  EXPECT_EQ(run_trace_cli(dir, "validate --from heitz.npy" + cfg + " --against h.exr").exit_code, 0);
  EXPECT_EQ(run_trace_cli(dir, "validate --from ndf.npy" + cfg + " --against h.exr").exit_code, 1);
  EXPECT_EQ(run_trace_cli(dir, "validate --sampler dupuy2023" + cfg + " --samples 300000 --against h.exr").exit_code, 0);
  // Bad combinations: exit 2 with a message.
  const std::pair<std::string, std::string> cases[] = {
      {"validate --sampler heitz2018 --alpha 0.3,0.6 --theta 71 --phi 20 --against h.exr", "made for"},
      {"validate --sampler bounded2023" + cfg + " --against h.exr", "reflected"},
      {"validate --all --against ellipsoid", "--all"},
      {"validate --sampler heitz2018" + cfg + " --against h.txt", "h.txt"},
      {"validate --sampler heitz2018" + cfg + " --against missing.exr", "missing.exr"},
      {"validate --sampler heitz2018" + cfg + " --rays 1000", "--rays"},
      {"validate --sampler heitz2018" + cfg + " --against ellipsoid --rays 0", "--rays"},
      {"validate --from heitz.npy --reflected" + cfg + " --against h.exr", "reflected"},
  };
  for (const auto& [args, needle] : cases) {
    const CliRun r = run_trace_cli(dir, args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << args << "\nstderr: " << r.err;
  }
  // A small tile's trace is not D_v (its NDF tail, its masking): against it even an exact sampler would be
  // rejected, so the comparison is refused (exit 2, the count the tile serves named, no report written), and
  // the exact ellipsoid's report states that its reference bias is nil.
  ASSERT_EQ(run_trace_cli(dir, "surface build --assembly smith --res 256 --alpha 0.3,0.6 --seed 1 --out s.exr --quiet")
                .exit_code, 0);
  ASSERT_EQ(run_trace_cli(dir, "trace vndf --surface s.exr --theta 70 --phi 20 --rays 300000 --out t.exr").exit_code, 0);
  const CliRun tile = run_trace_cli(dir, "validate --sampler heitz2018" + cfg + " --samples 300000 --against t.exr "
                                         "--json t.json");
  EXPECT_EQ(tile.exit_code, 2) << tile.out << tile.err;
  EXPECT_NE(tile.err.find("departs from D_v"), std::string::npos) << tile.err;
  EXPECT_NE(tile.err.find("it serves at most"), std::string::npos) << tile.err;
  EXPECT_FALSE(fs::exists(dir / "t.json"));
  EXPECT_EQ(j["tests"]["reference_bias"]["passed"], true) << j.dump(1).substr(0, 2000);
  EXPECT_NE(good.out.find("reference bias"), std::string::npos) << good.out;
  fs::remove_all(dir);
}

}  // namespace test_trace_cli
