// Tests of `microsim trace masking` (apps/cmd_trace_masking.cpp): a small run end to end, and bad input
// (view outside [0, 90), samples <= 0, a heightmap with NaN or with the wrong channels, tile size <= 0,
// a missing file, an unwritable --json) giving exit 2 and nothing written.
#include "binary_path.h"
#include "microgeom/exr_io.h"
#include "microgeom/heightfield.h"
#include "core/random.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>
#include <sys/wait.h>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_masking_cli {

namespace {

namespace fs = std::filesystem;

int run(const std::string& args) {
  const std::string cmd = microsim::test::microsim_binary() + " " + args + " > /dev/null 2>&1";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

class MaskingCli : public ::testing::Test {
protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("microsim_masking_cli_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    // A small periodic surface: a few integer-wavenumber sinusoids.
    const int n = 32;
    std::vector<float> z(std::size_t(n) * n);
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        z[std::size_t(j) * n + i] = float(0.02 * std::sin(2 * M_PI * (2 * i + j) / n) + 0.01 * std::cos(2 * M_PI * (i - 3 * j) / n));
    microgeom::Heightfield f(n, 1.0, z);
    good_ = (dir_ / "good.exr").string();
    microgeom::save_heightmap_exr(good_, f);
    // No tile-size attribute: needs --tile-size.
    microgeom::ExrImage bare;
    bare.width = bare.height = n;
    bare.channels.push_back({"height", z});
    bare_ = (dir_ / "bare.exr").string();
    microgeom::write_exr(bare_, bare);
    microgeom::ExrImage nan = bare;
    nan.channels[0].data[17] = std::nanf("");
    nan.attributes["microsim.tile_size"] = "1";
    nan_ = (dir_ / "nan.exr").string();
    microgeom::write_exr(nan_, nan);
    microgeom::ExrImage rg;
    rg.width = rg.height = n;
    rg.channels.push_back({"R", z});
    rg.channels.push_back({"G", z});
    rg.attributes["microsim.tile_size"] = "1";
    rg_ = (dir_ / "rg.exr").string();
    microgeom::write_exr(rg_, rg);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
  std::string good_, bare_, nan_, rg_;
};

TEST_F(MaskingCli, SmallRunWritesJson) {
  const fs::path json = dir_ / "out.json";
  ASSERT_EQ(run("trace masking --surface " + good_ + " --theta 60 --phi 20 --samples 4000 --theta-l 40 --vndf-rays 4000 --json " +
                json.string()),
            0);
  std::ifstream in(json);
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["masking"]["samples"], 4000);
  EXPECT_FALSE(j["leak_test"]["failed"].get<bool>());
  EXPECT_TRUE(j["masking"].contains("g2_mirror"));
  EXPECT_TRUE(j["masking"].contains("g2_pair"));
  EXPECT_EQ(j["masking"]["g1_given_normal"].size(), 10u);
  EXPECT_NEAR(j["masking"]["g1_near_grazing"]["share"].get<double>(), 0.02, 0.005);
  EXPECT_GT(j["masking"]["g1_near_grazing"]["angle_m_v_deg_min"].get<double>(),
            j["masking"]["g1_given_normal"][0]["angle_m_v_deg_min"].get<double>());
  EXPECT_EQ(j["vndf"]["comparisons"].size(), 2u);
  EXPECT_EQ(j["surface"]["analytic_reference"]["source"], "fitted");  // no assembly metadata
  // Same seed, same result (the JSON holds the estimates to full precision).
  const fs::path json2 = dir_ / "out2.json";
  ASSERT_EQ(run("trace masking --surface " + good_ + " --theta 60 --phi 20 --samples 4000 --threads 1 --json " + json2.string()), 0);
  std::ifstream in2(json2);
  const auto j2 = nlohmann::json::parse(in2);
  EXPECT_EQ(j["masking"]["g1"], j2["masking"]["g1"]);
  EXPECT_EQ(j["masking"]["g1_given_height"], j2["masking"]["g1_given_height"]);
}

// --seeds: each cell holds one value per realisation, their mean and spread; the realisation of seed 2
// inside a multi-seed table is the same as a table of seed 2 alone (same surface, same samples).
TEST_F(MaskingCli, TableWithSeveralSeeds) {
  const std::string common = "trace masking --table --assemblies beckmann --alphas 0.5 --thetas 60 --res 64 "
                             "--samples 2000 --vndf-rays 2000";
  const fs::path many = dir_ / "many.json", one = dir_ / "one.json";
  ASSERT_EQ(run(common + " --seeds 1,2,3 --json " + many.string()), 0);
  ASSERT_EQ(run(common + " --seed 2 --json " + one.string()), 0);
  std::ifstream in(many), in1(one);
  const auto j = nlohmann::json::parse(in), j1 = nlohmann::json::parse(in1);
  ASSERT_EQ(j["cells"].size(), 1u);
  const auto& c = j["cells"][0];
  EXPECT_EQ(c["realisations"], 3);
  EXPECT_EQ(j["surfaces"].size(), 3u);
  const auto& f = c["facing_ratio"];
  const auto values = f["values"].get<std::vector<double>>();
  ASSERT_EQ(values.size(), 3u);
  EXPECT_NEAR(f["mean"].get<double>(), (values[0] + values[1] + values[2]) / 3, 1e-12);
  double ss = 0;
  for (double x : values) ss += (x - f["mean"].get<double>()) * (x - f["mean"].get<double>());
  EXPECT_NEAR(f["se_across"].get<double>(), std::sqrt(ss / 2 / 3), 1e-12);
  EXPECT_GT(f["mc_se"].get<double>(), 0.0);
  EXPECT_EQ(values[1], j1["cells"][0]["facing_ratio"]["values"][0].get<double>());
  EXPECT_EQ(j1["cells"][0]["facing_ratio"]["sd_across"].get<double>(), 0.0);
  EXPECT_TRUE(c.contains("near_grazing_ratio"));
}

TEST_F(MaskingCli, BadInputExitsTwoAndWritesNothing) {
  const fs::path json = dir_ / "bad.json";
  const std::string out = " --json " + json.string();
  EXPECT_EQ(run("trace masking --surface " + good_ + " --theta 90" + out), 2);
  EXPECT_EQ(run("trace masking --surface " + good_ + " --theta -1" + out), 2);
  EXPECT_EQ(run("trace masking --surface " + good_ + " --theta nan" + out), 2);
  EXPECT_EQ(run("trace masking --surface " + good_ + " --theta 30 --samples 0" + out), 2);
  EXPECT_EQ(run("trace masking --surface " + good_ + " --theta 30 --samples -5" + out), 2);
  EXPECT_EQ(run("trace masking --surface " + good_ + " --theta 30 --theta-l 95" + out), 2);
  EXPECT_EQ(run("trace masking --surface " + good_ + " --theta 30 --geometry quads" + out), 2);
  EXPECT_EQ(run("trace masking --surface " + (dir_ / "missing.exr").string() + " --theta 30" + out), 2);
  EXPECT_EQ(run("trace masking --surface " + nan_ + " --theta 30" + out), 2);
  EXPECT_EQ(run("trace masking --surface " + rg_ + " --theta 30" + out), 2);
  EXPECT_EQ(run("trace masking --surface " + bare_ + " --theta 30" + out), 2);  // no tile size anywhere
  EXPECT_EQ(run("trace masking --surface " + bare_ + " --theta 30 --tile-size 0" + out), 2);
  EXPECT_EQ(run("trace masking --surface " + bare_ + " --theta 30 --tile-size -1" + out), 2);
  EXPECT_EQ(run("trace masking --theta 30" + out), 2);  // no surface
  EXPECT_EQ(run("trace masking --table --alphas 3" + out), 2);
  EXPECT_EQ(run("trace masking --table --assemblies nonsense" + out), 2);
  EXPECT_EQ(run("trace masking --table --res 100" + out), 2);
  EXPECT_EQ(run("trace masking --table --seeds 1,x" + out), 2);
  EXPECT_EQ(run("trace masking --table --seeds 1,1" + out), 2);
  EXPECT_EQ(run("trace masking --table --seeds -3" + out), 2);
  EXPECT_EQ(run("trace masking --table --grazing-share 0.5" + out), 2);
  EXPECT_EQ(run("trace masking --surface " + good_ + " --theta 30 --grazing-share 0" + out), 2);
  EXPECT_FALSE(fs::exists(json));
  EXPECT_EQ(run("trace masking --surface " + good_ + " --theta 30 --json " + (dir_ / "no" / "such" / "dir.json").string()), 2);
  // Nothing else was left in the directory (no temporaries).
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir_)) files += e.is_regular_file();
  EXPECT_EQ(files, 4);
  // The import path works with an explicit tile size.
  EXPECT_EQ(run("trace masking --surface " + bare_ + " --theta 30 --tile-size 2 --samples 1000"), 0);
  EXPECT_EQ(run("trace masking --help"), 0);
}

}  // namespace

}  // namespace test_masking_cli
