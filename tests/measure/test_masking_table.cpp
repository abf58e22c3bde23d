// Tests of the masking table as a library call (src/measure/masking_table.h): each view is exactly the
// single steps it is made of (a surface built by microgeom, its VNDF traced and its masking estimated with
// the same seed), the cells group the realisations in the request's order, the summary statistics, and
// cancellation through RunControl (before the run, during a build, between views) with progress reported
// through RunControl's callback.
#include "measure/masking_table.h"

#include "measure/masking.h"

#include "microgeom/assembly.h"
#include "stats/binning.h"
#include "trace/heightfield_trace.h"
#include "trace/smith_prediction.h"

#include <gtest/gtest.h>

#include <cmath>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace microsim {
namespace {

MaskingTableRequest small_request() {
  MaskingTableRequest r;
  r.assemblies = {"beckmann"};
  r.alphas = {0.5};
  r.thetas = {30, 60};
  r.resolution = 64;
  r.seeds = {1, 2};
  r.samples = 2000;
  r.vndf_rays = 2000;
  r.run.threads = 2;
  return r;
}

TEST(MaskingTable, EachViewIsTheSingleStepsWithItsSeed) {
  const MaskingTableRequest r = small_request();
  const MaskingTable t = measure_masking_table(r);
  ASSERT_FALSE(t.partial);
  ASSERT_EQ(t.surfaces.size(), 2u);
  EXPECT_EQ(t.views_requested(), 4u);
  ASSERT_EQ(t.complete_views().size(), 4u);
  // The second surface's 60-degree view, recomputed step by step.
  microgeom::AssemblyParams p;
  p.assembly = "beckmann";
  p.alpha_x = p.alpha_y = 0.5;
  p.resolution = 64;
  p.seed = 2;
  const microgeom::Heightfield field = microgeom::build_assembly(p);
  const AnalyticSmith analytic = analytic_reference(field);
  const EmpiricalSmith empirical(field);
  const HeightfieldScene scene(field);
  const Vec3<double> v = direction_from_degrees(60.0, r.phi_deg);
  MaskingOptions mo;
  mo.samples = r.samples;
  mo.seed = 2;
  mo.run.threads = 1;  // any thread count: the same bits
  mo.grazing_share = r.grazing_share;
  mo.light = Vec3<double>(-v.x(), -v.y(), v.z());
  const MaskingResult m = estimate_masking(scene, analytic, empirical, v, mo);
  const std::vector<DirectionBinning> binnings = {DirectionBinning::lobe(
      GGX<double>(analytic.alpha_x(), analytic.alpha_y()), v, SampleDomain::microfacet_normal, kMaskingVndfRows)};
  TraceOptions to;
  to.rays = r.vndf_rays;
  to.seed = 2;
  const TraceResult traced = trace_vndf_heightfield(scene, v, binnings, to);
  const VndfComparison c = compare_vndf(traced.counts[0], traced.unbinned[0], binnings[0], v, analytic, empirical);

  const MaskingTableView& view = t.surfaces[1].views[1];
  EXPECT_EQ(view.seed, 2u);
  EXPECT_EQ(view.theta, 60.0);
  EXPECT_EQ(view.masking.sums, m.sums);
  EXPECT_EQ(view.masking.g1.value, m.g1.value);
  EXPECT_EQ(view.masking.leak_ratio.value, m.leak_ratio.value);
  EXPECT_EQ(view.vndf.tv_analytic, c.tv_analytic);
  EXPECT_EQ(view.vndf.tv_empirical, c.tv_empirical);
  EXPECT_EQ(view.vndf_rays, r.vndf_rays);
  EXPECT_EQ(t.surfaces[1].analytic_reference, analytic.describe());
}

TEST(MaskingTable, CellsGroupTheRealisationsInRequestOrder) {
  MaskingTableRequest r = small_request();
  r.thetas = {60, 30};
  const MaskingTable t = measure_masking_table(r);
  const std::vector<MaskingTableCell> cells = masking_table_cells(t);
  ASSERT_EQ(cells.size(), 2u);
  EXPECT_EQ(cells[0].theta, 60.0);
  EXPECT_EQ(cells[1].theta, 30.0);
  for (const auto& cell : cells) {
    ASSERT_EQ(cell.views.size(), 2u);
    EXPECT_EQ(cell.views[0]->seed, 1u);
    EXPECT_EQ(cell.views[1]->seed, 2u);
    EXPECT_EQ(cell.views[0]->theta, cell.theta);
  }
}

TEST(MaskingTable, SummaryOfRealisations) {
  const RealisationSummary s = summarise_realisations({{1.0, 0.3}, {2.0, 0.4}, {4.0, 0.0}});
  EXPECT_EQ(s.values, (std::vector<double>{1.0, 2.0, 4.0}));
  EXPECT_NEAR(s.mean, 7.0 / 3, 1e-15);
  const double sd = std::sqrt((sqr(1 - 7.0 / 3) + sqr(2 - 7.0 / 3) + sqr(4 - 7.0 / 3)) / 2);
  EXPECT_NEAR(s.sd, sd, 1e-15);
  EXPECT_NEAR(s.se_across, sd / std::sqrt(3.0), 1e-15);
  EXPECT_NEAR(s.mc_se, 0.5 / 3, 1e-15);
  EXPECT_EQ(s.min, 1.0);
  EXPECT_EQ(s.max, 4.0);
  const RealisationSummary one = summarise_realisations({{0.5, 0.1}});
  EXPECT_EQ(one.sd, 0.0);
  EXPECT_EQ(one.mc_se, 0.1);
  EXPECT_THROW(summarise_realisations({}), std::invalid_argument);
}

TEST(MaskingTable, RefusesAnEmptyOrBadRequest) {
  MaskingTableRequest r = small_request();
  r.thetas.clear();
  EXPECT_THROW(measure_masking_table(r), std::invalid_argument);
  r = small_request();
  r.thetas = {90};
  EXPECT_THROW(measure_masking_table(r), std::invalid_argument);
  r = small_request();
  r.vndf_rays = 0;
  EXPECT_THROW(measure_masking_table(r), std::invalid_argument);
  r = small_request();
  r.assemblies = {"nonsense"};
  EXPECT_THROW(measure_masking_table(r), std::invalid_argument);
}

TEST(MaskingTable, CancelledBeforeTheRunMeasuresNothing) {
  CancelToken token;
  token.cancel();
  MaskingTableRequest r = small_request();
  r.run.cancel = &token;
  const MaskingTable t = measure_masking_table(r);
  EXPECT_TRUE(t.partial);
  EXPECT_TRUE(t.surfaces.empty());
  EXPECT_TRUE(masking_table_cells(t).empty());
}

TEST(MaskingTable, CancelledDuringABuildLeavesThatSurfaceOut) {
  CancelToken token;
  MaskingTableRequest r = small_request();
  r.run.cancel = &token;
  // The second surface's build reports progress: cancel there.
  int builds_started = 0;
  r.run.progress = [&](std::string_view stage, std::uint64_t done, std::uint64_t) {
    if (stage == "build surface" && done == 0 && ++builds_started == 2) token.cancel();
  };
  const MaskingTable t = measure_masking_table(r);
  EXPECT_TRUE(t.partial);
  ASSERT_EQ(t.surfaces.size(), 1u);
  EXPECT_EQ(t.complete_views().size(), 2u);
}

TEST(MaskingTable, CancelledBetweenViewsKeepsTheCompleteViewsAndReportsProgress) {
  CancelToken token;
  MaskingTableRequest r = small_request();
  r.run.cancel = &token;
  std::mutex mutex;
  std::vector<std::uint64_t> table_progress;
  r.run.progress = [&](std::string_view stage, std::uint64_t done, std::uint64_t total) {
    std::lock_guard lock(mutex);
    if (stage == "masking table") {
      EXPECT_EQ(total, 4u);
      table_progress.push_back(done);
    }
  };
  std::vector<double> seen;
  const MaskingTable t = measure_masking_table(r, [&](const MaskingTableView& v) {
    seen.push_back(v.theta);
    token.cancel();  // after the first view
  });
  EXPECT_TRUE(t.partial);
  ASSERT_EQ(t.surfaces.size(), 1u);
  ASSERT_EQ(t.surfaces[0].views.size(), 1u);
  EXPECT_FALSE(t.surfaces[0].views[0].partial);
  EXPECT_EQ(seen, (std::vector<double>{30}));
  EXPECT_EQ(table_progress, (std::vector<std::uint64_t>{1}));
  const std::vector<MaskingTableCell> cells = masking_table_cells(t);
  ASSERT_EQ(cells.size(), 1u);
  EXPECT_EQ(cells[0].theta, 30.0);
}

}  // namespace
}  // namespace microsim
