// End-to-end tests of `microsim surface build | stats | import`: outputs, exit codes, and that bad input
// gets exit 2, a message naming the bad value, and nothing written.
#include "cli_helpers.h"
#include "microgeom/exr_io.h"
#include "microgeom/heightfield.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <fstream>
#include <sstream>

#include <sys/wait.h>
#include <unistd.h>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_surface_cli {

namespace fs = std::filesystem;

namespace {

using microsim::test::CliRun;
using microsim::test::file_count;

CliRun run(const fs::path& dir, const std::string& args) { return microsim::test::run_cli(dir, args); }
fs::path scratch_dir(const std::string& name) { return microsim::test::scratch_dir("surface_cli", name); }

}  // namespace

TEST(SurfaceCli, BuildWritesHeightmapNormalsMeshAndJsonThenStatsReadsIt) {
  const auto dir = scratch_dir("build");
  const CliRun b = run(dir, "surface build --quiet --assembly smith --alpha 0.4,0.2 --res 256 --seed 5 --out s.exr "
                         "--normals n.exr --mesh m.obj --mesh-crop 8 --json s.json");
  ASSERT_EQ(b.exit_code, 0) << b.err;
  EXPECT_NE(b.out.find("NDF verdict: ok"), std::string::npos) << b.out;
  EXPECT_NE(b.out.find("Spearman(height, slope radius)"), std::string::npos);
  for (const char* f : {"s.exr", "n.exr", "m.obj", "s.json"}) EXPECT_TRUE(fs::exists(dir / f)) << f;
  EXPECT_EQ(file_count(dir), 4u);  // no temporaries left

  const auto field = microgeom::load_heightmap_exr(dir / "s.exr");
  EXPECT_EQ(field.resolution(), 256);
  EXPECT_EQ(field.tile_size(), 1.0);
  EXPECT_EQ(field.metadata.at("assembly"), "smith");
  EXPECT_EQ(field.metadata.at("seed"), "5");
  EXPECT_EQ(std::stod(field.metadata.at("alpha_y")), 0.2);

  std::ifstream in(dir / "s.json");
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["assembly"], "smith");
  EXPECT_TRUE(j["stats"]["ndf_within_tolerance"].get<bool>());
  EXPECT_EQ(j["stats"]["quantiles"].size(), 12u);
  EXPECT_GT(j["peak_rss_bytes"].get<double>(), 0.0);

  const CliRun s = run(dir, "surface stats s.exr --json t.json");
  ASSERT_EQ(s.exit_code, 0) << s.err;
  std::ifstream tin(dir / "t.json");
  const auto t = nlohmann::json::parse(tin);
  // stats reproduces the build's measurement from the file (alpha and reference from its attributes).
  EXPECT_EQ(t["stats"]["max_quantile_error"], j["stats"]["max_quantile_error"]);
  EXPECT_EQ(t["stats"]["coupling"]["spearman_height_slope"], j["stats"]["coupling"]["spearman_height_slope"]);
  // Against the wrong law, --check rejects (exit 1).
  EXPECT_EQ(run(dir, "surface stats s.exr --reference beckmann --check").exit_code, 1);
  EXPECT_EQ(run(dir, "surface stats s.exr --check").exit_code, 0);
  fs::remove_all(dir);
}

TEST(SurfaceCli, BadInputExitsTwoNamingTheValueAndWritesNothing) {
  const auto dir = scratch_dir("bad");
  struct Case {
    std::string args, needle;
  };
  const std::vector<Case> cases = {
      {"surface build --assembly smith --alpha 0.5 --res 100 --out x.exr", "--res '100': not a power of two"},
      {"surface build --assembly smith --alpha 2.5 --res 64 --out x.exr", "alpha 2.5"},
      {"surface build --assembly smith --alpha 0.5,-1 --res 64 --out x.exr", "'-1': outside"},
      {"surface build --assembly smith --alpha abc --res 64 --out x.exr", "'abc'"},
      {"surface build --assembly smoth --alpha 0.5 --res 64 --out x.exr", "'smoth'"},
      {"surface build --assembly smith --alpha 0.5 --res 64 --tile-size 0 --out x.exr", "--tile-size '0': outside (0, inf]"},
      {"surface build --assembly smith --alpha 0.5 --res 256 --out nodir/x.exr", "nodir"},
      {"surface build --assembly smith --alpha 0.5 --res 256 --out x.exr --mesh x.xyz", "x.xyz"},
      // A build that misses its NDF (one slope-matching iteration) is an error, not a warning.
      {"surface build --quiet --assembly smith --alpha 0.5 --res 256 --iterations 1 --out x.exr --json x.json",
       "misses its ggx NDF"},
      {"surface stats missing.exr", "missing.exr"},
      {"surface import missing.exr --tile-size 1 --out y.exr", "missing.exr"},
  };
  for (const auto& c : cases) {
    const CliRun r = run(dir, c.args);
    EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.needle), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_EQ(file_count(dir), 0u) << c.args;
  }

  // Heightmaps with NaN, wrong channels, no tile size, and tile size <= 0 on import.
  microgeom::ExrImage nan;
  nan.width = nan.height = 16;
  nan.add_channel("height").data[17] = std::numeric_limits<float>::quiet_NaN();
  microgeom::write_exr(dir / "nan.exr", nan);
  microgeom::ExrImage rgb;
  rgb.width = rgb.height = 16;
  rgb.add_channel("R");
  rgb.add_channel("G");
  microgeom::write_exr(dir / "rg.exr", rgb);
  microgeom::ExrImage plain;
  plain.width = plain.height = 16;
  plain.add_channel("height");
  microgeom::write_exr(dir / "plain.exr", plain);
  const std::vector<Case> file_cases = {
      {"surface stats nan.exr --tile-size 1", "x=1, y=1"},
      {"surface stats rg.exr --tile-size 1", "found 'G', 'R'"},
      {"surface stats plain.exr", "--tile-size"},
      {"surface stats plain.exr --tile-size -2", "-2"},
      {"surface stats plain.exr --tile-size 1 --reference gauss", "'gauss'"},
      {"surface import plain.exr --tile-size 0 --out y.exr", "tile-size 0"},
      {"surface import nan.exr --tile-size 1 --out y.exr", "non-finite"},
  };
  for (const auto& c : file_cases) {
    const CliRun r = run(dir, c.args);
    EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.needle), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_EQ(file_count(dir), 3u) << c.args;
  }
  fs::remove_all(dir);
}

TEST(SurfaceCli, ImportedHeightmapIsStudiedLikeABuiltOne) {
  const auto dir = scratch_dir("import");
  // An "external" measured surface: channel Y, no microsim attributes.
  microgeom::ExrImage ext;
  ext.width = ext.height = 32;
  auto& y = ext.add_channel("Y");
  for (int j = 0; j < 32; ++j)
    for (int i = 0; i < 32; ++i) y.data[j * 32 + i] = float(std::sin(2 * M_PI * i / 32) * std::cos(2 * M_PI * 2 * j / 32));
  microgeom::write_exr(dir / "ext.exr", ext);
  const CliRun im = run(dir, "surface import ext.exr --tile-size 0.5 --out imp.exr");
  ASSERT_EQ(im.exit_code, 0) << im.err;
  const auto f = microgeom::load_heightmap_exr(dir / "imp.exr");
  EXPECT_EQ(f.tile_size(), 0.5);
  EXPECT_EQ(f.metadata.at("assembly"), "imported");
  EXPECT_EQ(f.heights(), y.data);
  const CliRun st = run(dir, "surface stats imp.exr --mesh imp.ply");
  EXPECT_EQ(st.exit_code, 0) << st.err;
  EXPECT_NE(st.out.find("(fitted)"), std::string::npos) << st.out;  // no alpha attribute: fitted
  EXPECT_TRUE(fs::exists(dir / "imp.ply"));
  fs::remove_all(dir);
}

// The help names the assemblies on the --assembly line and points down to their descriptions, which the
// footer prints after the options.
TEST(SurfaceCli, BuildHelpPointsToTheAssembliesBelow) {
  const auto dir = scratch_dir("help");
  const CliRun h = run(dir, "surface build --help");
  ASSERT_EQ(h.exit_code, 0) << h.err;
  EXPECT_EQ(h.out.find("see above"), std::string::npos) << h.out;
  const std::size_t option = h.out.find("assembly name: smith"), listed = h.out.find("Assemblies (");
  ASSERT_NE(option, std::string::npos) << h.out;
  EXPECT_NE(h.out.find("described under \"Assemblies\" below", option), std::string::npos) << h.out;
  EXPECT_LT(option, listed) << h.out;
  fs::remove_all(dir);
}

}  // namespace test_surface_cli
