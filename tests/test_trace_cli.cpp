// End-to-end tests of `microsim trace vndf --surface ellipsoid`: outputs (EXR histogram, JSON summary,
// mesh), exit codes, bad input (exit 2, a message naming the bad value, nothing written), and Ctrl-C
// (exit 130, a partial histogram written).
#include "microsim/histogram_io.h"

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

namespace fs = std::filesystem;

namespace {

struct CliRun {
  int exit_code;
  std::string out, err;
};

std::string slurp(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

CliRun run(const fs::path& dir, const std::string& args) {
  const std::string cmd = "cd '" + dir.string() + "' && '" + MICROSIM_BINARY + "' " + args + " > ../" +
                          dir.filename().string() + ".stdout 2> ../" + dir.filename().string() + ".stderr";
  const int status = std::system(cmd.c_str());
  const fs::path out = dir.parent_path() / (dir.filename().string() + ".stdout");
  const fs::path err = dir.parent_path() / (dir.filename().string() + ".stderr");
  CliRun r{WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(out), slurp(err)};
  fs::remove(out);
  fs::remove(err);
  return r;
}

fs::path scratch_dir(const std::string& name) {
  auto dir = fs::temp_directory_path() / ("microsim_trace_cli_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::size_t file_count(const fs::path& dir) {
  std::size_t n = 0;
  for ([[maybe_unused]] auto& e : fs::directory_iterator(dir)) ++n;
  return n;
}

}  // namespace

TEST(TraceCli, WritesHistogramJsonAndMesh) {
  const auto dir = scratch_dir("ok");
  const CliRun r = run(dir, "trace vndf --alpha 0.3,0.6 --theta 60 --phi 15 --rays 200000 --seed 4 --rows 15 "
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
  const CliRun r1 = run(dir, "trace vndf --alpha 0.3,0.6 --theta 60 --phi 15 --rays 200000 --seed 4 --rows 15 "
                             "--threads 1 --out h1.exr");
  ASSERT_EQ(r1.exit_code, 0) << r1.err;
  EXPECT_EQ(microsim::read_histogram_exr(dir / "h1.exr").counts, h.counts);
  // A mesh level, written out.
  const CliRun m = run(dir, "trace vndf --alpha 0.5 --theta 30 --rays 20000 --mesh-level 2 --rows 7 --out m.exr "
                            "--mesh-out m.ply");
  ASSERT_EQ(m.exit_code, 0) << m.err;
  EXPECT_TRUE(fs::exists(dir / "m.ply"));
  EXPECT_NE(m.out.find("mesh level 2"), std::string::npos);
  EXPECT_EQ(microsim::read_histogram_exr(dir / "m.exr").attributes.at("mesh_level"), "2");
  EXPECT_EQ(file_count(dir), 5u);  // h.exr h.json h1.exr m.exr m.ply: no temporaries
  fs::remove_all(dir);
}

TEST(TraceCli, BadInputExits2AndWritesNothing) {
  const auto dir = scratch_dir("bad");
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
      {"trace vndf --alpha 0.5 --theta 30 --rays 0 --out h.exr", "--rays 0"},
      {"trace vndf --alpha 0.5 --theta 30 --rays -5 --out h.exr", "--rays -5"},
      {"trace vndf --alpha 0.5 --theta 30 --rays 1000 --out no_such_dir/h.exr", "no_such_dir"},
      {"trace vndf --alpha 0.5 --theta 30 --rays 1000 --out h.exr --json no_such_dir/h.json", "no_such_dir"},
      {"trace vndf --alpha 0.5 --theta 30 --rays 1000 --out h.txt", "--out"},
      {"trace vndf --surface sphere --alpha 0.5 --theta 30" + ok, "sphere"},
      {"trace vndf --theta 30" + ok, "--alpha"},
      {"trace vndf --alpha 0.5 --theta 30 --mesh-out m.ply" + ok, "--mesh-out"},
      {"trace vndf --alpha 0.5 --theta 30 --mesh-level 12" + ok, "--mesh-level 12"},
      {"trace vndf --alpha 0.5 --theta 30 --rows 16" + ok, "--rows 16"},
  };
  for (const auto& [args, needle] : cases) {
    const CliRun r = run(dir, args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << args << "\nstderr: " << r.err;
    EXPECT_EQ(file_count(dir), 0u) << args;
  }
  fs::remove_all(dir);
}

// Ctrl-C during a long run: exit 130, and the histogram of the rays traced so far is written, marked
// partial (in the EXR attributes and the JSON).
TEST(TraceCli, InterruptWritesPartialHistogram) {
  const auto dir = scratch_dir("sigint");
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    if (::chdir(dir.c_str()) != 0) ::_exit(99);
    std::freopen("stdout.txt", "w", stdout);
    std::freopen("stderr.txt", "w", stderr);
    ::execl(MICROSIM_BINARY, MICROSIM_BINARY, "trace", "vndf", "--alpha", "0.5", "--theta", "40", "--rays",
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
