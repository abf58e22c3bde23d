// End to end: `microsim scatter --model smith-walk` and `microsim scatter --surface SURF.exr`
// write exactly the histogram of the library call with the same options (the CLI adds nothing to the
// measurement), shards merge into the single run bit for bit, the JSON says what each geometric hemisphere
// holds (for light from inside a dielectric the upper one is the transmitted light), a traced mirror
// surface conserves its energy, and compare-scattering takes the surface and the walk side by side.
// --walk-kernel lanes runs the lanes kernel (its histogram, bit for bit), agrees with the scalar walk on the
// albedo, and its parts do not merge with the scalar walk's.
#include "binary_path.h"
#include "cli_helpers.h"

#include "microgeom/assembly.h"
#include "microgeom/heightfield.h"
#include "scatter/smith_walk.h"
#include "scatter/surface_scatter.h"
#include "stats/scatter_io.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <string>

namespace microsim::test {
namespace {

using json = nlohmann::json;

Vec3<double> view(double theta_deg, double phi_deg = 0) {
  const double t = theta_deg * kPi<double> / 180, p = phi_deg * kPi<double> / 180;
  return {std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t)};
}

microgeom::Heightfield small_surface() {
  microgeom::AssemblyParams p;
  p.assembly = "smith";
  p.alpha_x = p.alpha_y = 0.5;
  p.resolution = 64;
  p.seed = 3;
  return microgeom::build_assembly(p);
}

class ScatterCli : public ::testing::Test {
protected:
  void SetUp() override {
    dir = scratch_dir("scatter_cli", ::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  void TearDown() override { fs::remove_all(dir); }
  fs::path dir;
};

TEST_F(ScatterCli, SmithWalkWritesTheLibraryHistogram) {
  const CliRun r = run_cli(dir, "scatter --model smith-walk --alpha 0.5 --theta 60 --phi 20 --material dielectric:1.5 "
                                "--rays 20000 --rows 4 --seed 9 --threads 2 --out w.exr --json w.json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ScatterOptions o;
  o.wi = view(60, 20);
  o.material = Material::dielectric(1.5);
  o.paths = 20000;
  o.rows = 4;
  o.seed = 9;
  const ScatterHistogram expected = smith_walk_scatter({NdfKind::ggx, 0.5, 0.5}, o);
  const ScatterFile f = read_scatter_exr(dir / "w.exr");
  ASSERT_EQ(f.kind, ScatterFileKind::histogram);
  EXPECT_EQ(f.histogram, expected);
  EXPECT_EQ(f.notes.at("model"), "smith-walk");
  const json j = json::parse(slurp(dir / "w.json"));
  EXPECT_EQ(j["hemispheres"]["upper"], "reflected");
  EXPECT_EQ(j["hemispheres"]["lower"], "transmitted");
  // A dielectric conserves energy path by path: every path leaves (or is still inside at the cap).
  EXPECT_NEAR(j["channels"][0]["energy"]["value"].get<double>(), 1.0, 1e-12);
  EXPECT_GT(j["channels"][0]["albedo"]["total"]["lower"]["value"].get<double>(), 0.5);
  EXPECT_NE(r.out.find("upper (R)"), std::string::npos) << r.out;
}

TEST_F(ScatterCli, LightFromInsideIsTransmittedIntoTheUpperHemisphere) {
  const CliRun r = run_cli(dir, "scatter --model smith-walk --ndf beckmann --alpha 0.3 --theta 150 --material "
                                "dielectric:1.5 --rays 8192 --rows 4 --out w.exr --json w.json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const json j = json::parse(slurp(dir / "w.json"));
  EXPECT_EQ(j["hemispheres"]["upper"], "transmitted");
  EXPECT_EQ(j["hemispheres"]["lower"], "reflected");
  EXPECT_NE(r.out.find("upper (T)"), std::string::npos) << r.out;
  // 30 degrees from the normal inside eta 1.5: most light gets out (Fresnel about 4% per smooth crossing).
  EXPECT_GT(j["channels"][0]["albedo"]["total"]["upper"]["value"].get<double>(), 0.6);
}

TEST_F(ScatterCli, WalkShardsMergeIntoTheSingleRun) {
  const std::string run = "scatter --model smith-walk --alpha 0.3,0.6 --theta 45 --material 'conductor:0.2,3.9;0.5,2.4' "
                          "--rays 30000 --rows 3 --seed 4 ";  // 8 blocks of 4096 paths
  ASSERT_EQ(run_cli(dir, run + "--out whole.exr").exit_code, 0);
  for (int k = 1; k <= 3; ++k) {
    const CliRun r = run_cli(dir, run + "--shard " + std::to_string(k) + "/3 --out p" + std::to_string(k) + ".json");
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  const CliRun m = run_cli(dir, "merge p3.json p1.json p2.json --out merged.exr");
  ASSERT_EQ(m.exit_code, 0) << m.err;
  const ScatterFile whole = read_scatter_exr(dir / "whole.exr"), merged = read_scatter_exr(dir / "merged.exr");
  EXPECT_EQ(merged.histogram, whole.histogram);
  EXPECT_EQ(merged.notes, whole.notes);
  EXPECT_EQ(whole.histogram.channels(), 2);
}

TEST_F(ScatterCli, WalkKernelLanesRunsTheLanesWalk) {
  const std::string run = "scatter --model smith-walk --alpha 0.4,0.7 --theta 70 --material conductor:0.2,3.9 "
                          "--rays 16384 --rows 2 --seed 5 ";  // 4 blocks of 4096 paths
  const CliRun lanes = run_cli(dir, run + "--walk-kernel lanes --out l.exr --json l.json");
  ASSERT_EQ(lanes.exit_code, 0) << lanes.err;
  ASSERT_EQ(run_cli(dir, run + "--out s.exr --json s.json").exit_code, 0);  // the default: scalar
  ScatterOptions o;
  o.wi = view(70);
  o.material = Material::conductor({{0.2, 3.9}});
  o.paths = 16384;
  o.rows = 2;
  o.seed = 5;
  const SmithMicrosurface surface{NdfKind::ggx, 0.4, 0.7};
  const ScatterFile l = read_scatter_exr(dir / "l.exr"), s = read_scatter_exr(dir / "s.exr");
  // The CLI's walk is the library's, bit for bit, also when the CLI is the sanitizer gate's -O1 instrumented
  // build and this test is a Release build (the kernel is compiled without FMA contraction).
  EXPECT_EQ(l.histogram, smith_walk_scatter(surface, o, WalkKernel::lanes));
  EXPECT_EQ(s.histogram, smith_walk_scatter(surface, o));
  EXPECT_EQ(l.notes.at("walk_kernel"), "lanes");
  EXPECT_EQ(s.notes.at("walk_kernel"), "scalar");
  EXPECT_NE(l.histogram.provenance.measurement, s.histogram.provenance.measurement);
  // Other random streams, the same walk: the total albedos differ and agree within 4 standard errors of the
  // difference (fixed seed; a false alarm has probability 6e-5).
  const json jl = json::parse(slurp(dir / "l.json")), js = json::parse(slurp(dir / "s.json"));
  EXPECT_EQ(jl["notes"]["walk_kernel"], "lanes");
  const json &el = jl["channels"][0]["albedo"]["total"]["both"], &es = js["channels"][0]["albedo"]["total"]["both"];
  const double difference = el["value"].get<double>() - es["value"].get<double>();
  const double error = std::hypot(el["standard_error"].get<double>(), es["standard_error"].get<double>());
  EXPECT_NE(difference, 0.0);
  EXPECT_LT(std::abs(difference), 4 * error) << difference << " +- " << error;
  // The lanes run's shards merge into it bit for bit; the parts of the two kernels are parts of different runs:
  // merge refuses them (exit 2), naming the kernel.
  ASSERT_EQ(run_cli(dir, run + "--walk-kernel lanes --shard 1/2 --out l1.json").exit_code, 0);
  ASSERT_EQ(run_cli(dir, run + "--walk-kernel lanes --shard 2/2 --out p2.json").exit_code, 0);
  ASSERT_EQ(run_cli(dir, "merge p2.json l1.json --out lm.exr").exit_code, 0);
  const ScatterFile merged = read_scatter_exr(dir / "lm.exr");
  EXPECT_EQ(merged.histogram, l.histogram);
  EXPECT_EQ(merged.notes, l.notes);
  ASSERT_EQ(run_cli(dir, run + "--shard 1/2 --out p1.json").exit_code, 0);
  const CliRun m = run_cli(dir, "merge p1.json p2.json --out m.exr");
  EXPECT_EQ(m.exit_code, 2) << m.err;
  EXPECT_NE(m.err.find("walk_kernel 'lanes' vs 'scalar'"), std::string::npos) << m.err;
  EXPECT_FALSE(fs::exists(dir / "m.exr"));
}

TEST_F(ScatterCli, SurfaceWritesTheLibraryHistogramAndConservesAMirrorsEnergy) {
  const microgeom::Heightfield field = small_surface();
  microgeom::save_heightmap_exr(dir / "s.exr", field);
  const CliRun r = run_cli(dir, "scatter --surface s.exr --theta 70 --rays 12000 --rows 4 --seed 2 --out h.exr --json h.json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ScatterOptions o;
  o.wi = view(70);
  o.paths = 12000;
  o.rows = 4;
  o.seed = 2;
  const ScatterFile f = read_scatter_exr(dir / "h.exr");
  EXPECT_EQ(f.histogram, scatter_on_surface(microgeom::load_heightmap_exr(dir / "s.exr"), o));
  EXPECT_EQ(f.notes.at("model"), "surface");
  EXPECT_EQ(f.notes.at("surface_assembly"), "smith");
  EXPECT_EQ(f.notes.at("alpha"), field.metadata.at("alpha_x") + "," + field.metadata.at("alpha_y"));
  const json j = json::parse(slurp(dir / "h.json"));
  const json& c = j["channels"][0];
  // The furnace: a mirror surface sends every path out upward, none is lost, none leaks below.
  EXPECT_EQ(c["lost"]["value"].get<double>(), 0.0);
  EXPECT_EQ(c["albedo"]["total"]["lower"]["value"].get<double>(), 0.0);
  EXPECT_NEAR(c["albedo"]["total"]["upper"]["value"].get<double>() + c["unfinished"]["value"].get<double>(), 1.0, 1e-12);
  EXPECT_GT(c["albedo"]["order2"]["upper"]["value"].get<double>(), 0.01);  // multiple scattering at 70 degrees
  EXPECT_NE(r.err.find("bounces traced"), std::string::npos) << r.err;
}

TEST_F(ScatterCli, SurfaceAndWalkCompareSideBySide) {
  microgeom::save_heightmap_exr(dir / "s.exr", small_surface());
  ASSERT_EQ(run_cli(dir, "scatter --surface s.exr --theta 30 --rays 8192 --rows 3 --out s_h.exr").exit_code, 0);
  ASSERT_EQ(run_cli(dir, "scatter --model smith-walk --alpha 0.5 --theta 30 --rays 8192 --rows 3 --out w.exr").exit_code, 0);
  const CliRun r = run_cli(dir, "compare-scattering s_h.exr w.exr --analytic --orders 1,total --json c.json");
  // Two measurements and the analytic expectation of the surface's own notes: a verdict (0 or 1), never bad input.
  EXPECT_TRUE(r.exit_code == 0 || r.exit_code == 1) << r.exit_code << r.err;
  const json j = json::parse(slurp(dir / "c.json"));
  EXPECT_FALSE(j.empty());
}

}  // namespace
}  // namespace microsim::test
