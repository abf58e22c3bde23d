// `microsim plot HIST.exr --out FIG.svg`: the figure of a traced histogram, and bad input (exit 2,
// nothing written).
#include "cli_helpers.h"

#include <gtest/gtest.h>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_plot_cli {

using namespace microsim::test;

TEST(PlotCli, DrawsATracedHistogramAndRejectsBadInput) {
  const auto dir = scratch_dir("plot_cli", "ok");
  ASSERT_EQ(run_cli(dir, "trace vndf --alpha 0.3 --theta 60 --rays 100000 --rows 15 --out h.exr").exit_code, 0);
  const CliRun ok = run_cli(dir, "plot h.exr --out f.svg");
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  const std::string svg = slurp(dir / "f.svg");
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  EXPECT_NE(svg.find("traced ellipsoid (quadric): alpha 0.3,0.3, theta 60 deg"), std::string::npos);
  EXPECT_NE(svg.find("sphere bins: analytic D_v"), std::string::npos);
  EXPECT_NE(svg.find("lobe bins: analytic D_v"), std::string::npos);
  EXPECT_EQ(file_count(dir), 2u);

  // Not .svg, a missing directory, a missing or non-histogram input: exit 2, nothing written.
  const CliRun png = run_cli(dir, "plot h.exr --out f.png");
  EXPECT_EQ(png.exit_code, 2);
  EXPECT_NE(png.err.find("f.png"), std::string::npos) << png.err;
  EXPECT_EQ(run_cli(dir, "plot h.exr --out no/such/dir/f.svg").exit_code, 2);
  const CliRun missing = run_cli(dir, "plot missing.exr --out g.svg");
  EXPECT_EQ(missing.exit_code, 2);
  EXPECT_NE(missing.err.find("missing.exr"), std::string::npos) << missing.err;
  const CliRun not_histogram = run_cli(dir, "plot f.svg --out g.svg");
  EXPECT_EQ(not_histogram.exit_code, 2);
  EXPECT_EQ(file_count(dir), 2u);
  fs::remove_all(dir);
}

// A scattering result of `microsim scatter` is drawn as its lobes, one row per order and a panel per channel.
TEST(PlotCli, DrawsAScatterResultByOrder) {
  const auto dir = scratch_dir("plot_cli", "scatter");
  const CliRun walk = run_cli(dir, "scatter --model smith-walk --alpha 0.5 --theta 60 --material dielectric:1.5 "
                                   "--rays 20000 --rows 6 --out s.exr");
  ASSERT_EQ(walk.exit_code, 0) << walk.err;
  const CliRun ok = run_cli(dir, "plot s.exr --out s.svg");
  ASSERT_EQ(ok.exit_code, 0) << ok.err;
  const std::string svg = slurp(dir / "s.svg");
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  for (const char* text : {"scattering: weight per launched path by order", "s.exr: 20000 paths", "order1", "order5plus",
                           "total", "material dielectric"})
    EXPECT_NE(svg.find(text), std::string::npos) << text;
  ASSERT_EQ(run_cli(dir, "scatter --model analytic --alpha 0.5 --theta 60 --rows 6 --out a.exr").exit_code, 0);
  const CliRun expectation = run_cli(dir, "plot a.exr --out a.svg");
  ASSERT_EQ(expectation.exit_code, 0) << expectation.err;
  const std::string a = slurp(dir / "a.svg");
  EXPECT_NE(a.find("order1"), std::string::npos);
  EXPECT_EQ(a.find("order2"), std::string::npos) << "an expectation has order 1 only";
  fs::remove_all(dir);
}

}  // namespace test_plot_cli
