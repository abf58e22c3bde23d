// `microsim plot HIST.exr --out FIG.svg`: the figure of a traced histogram, and bad input (exit 2,
// nothing written).
#include "cli_helpers.h"

#include <gtest/gtest.h>

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
