// An albedo table on explicit surfaces in experiments (issue 12; src/experiment/surface_albedo.h):
//   - the size rule: the target turned into an absolute bias at the table's smallest albedo picks the trade
//     table's tile (every alpha the same size, 64 correlation lengths wide); a target no tile meets, or a
//     heightmap (one alpha), is not runnable, says why and builds nothing;
//   - the run meets its target on the tiles the plan built (not built again); each cell's E1, what is still on
//     the surface and what the tracer lost add up to the mirror's 1;
//   - the rule's claim, measured: the smith tile's E1, traced with many paths, is within the bias the rule
//     allows (kBiasShare x target x E_min) plus 3 standard errors of Smith's analytic E1 (Walter et al. 2007
//     with Smith masking, by quadrature), at every cell; negative control: the analytic E1 of another alpha
//     (1.0) is outside it.
#include "experiment/heightfield_measures.h"
#include "experiment/plan.h"
#include "experiment/run.h"
#include "experiment/surface_albedo.h"
#include "experiment/surface_cache.h"
#include "scatter/albedo_table.h"
#include "microgeom/exr_io.h"
#include "scratch_dir.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <string>

namespace surface_albedo_test {

using namespace microsim;
using namespace microsim::experiment;

ExperimentSpec tile_albedo_spec(double target, const std::string& surface = "smith") {
  return parse_spec_toml(fmt::format(R"(
seed = 5
[[material]]
name = "m"
alphas = [0.5]
type = "mirror"
[[quantity]]
kind = "albedo"
material = "m"
surface = "{}"
orders = "single"
mus = 2
target_relative_error = {}
)", surface, target), "tile_albedo.toml");
}

ExperimentPlan plan_on(const ExperimentSpec& spec, SurfaceCache& cache) {
  PlanOptions o;
  o.pilot_paths = 1024;
  o.run.threads = 2;
  o.surfaces = &cache;
  return plan_experiment(spec, o);
}

// The analytic single-scattering table of the spec's mirror at `alpha` (tolerance 1e-9 per cell).
AlbedoTable analytic_e1(int mus, double alpha) {
  AlbedoTableRequest r;
  r.alphas = {alpha};
  r.mus = mus;
  r.tolerance = 1e-9;
  return albedo_table(r);
}

TEST(ExperimentSurfaceAlbedo, TheTileMeetsTheBiasRuleAndTheTableAgreesWithSmithsSingleScattering) {
  const double target = 0.2;
  const ExperimentSpec spec = tile_albedo_spec(target);
  SurfaceCache cache;
  const ExperimentPlan plan = plan_on(spec, cache);
  const Decision& d = plan.decisions.at(0);
  ASSERT_TRUE(d.runnable) << d.not_runnable;
  EXPECT_EQ(d.model.model, Model::heightfield);
  EXPECT_EQ(d.surface.resolution, 1024) << "64 correlation lengths of 16 cells: the width rule";
  EXPECT_EQ(d.order_cap, 1);
  EXPECT_EQ(cache.builds(), 1u);
  EXPECT_NE(d.surface.reason.find("smallest targeted albedo"), std::string::npos) << d.surface.reason;
  const AlbedoTable exact = analytic_e1(2, 0.5);
  const double e_min = std::min(exact.cell("E1", 0, 0).value, exact.cell("E1", 0, 1).value);
  EXPECT_LE(d.surface.bias, kBiasShare * target * e_min);

  RunOptions o;
  o.run.threads = 2;
  o.surfaces = &cache;
  const ExperimentResults r = run_experiment(spec, plan, o);
  const MeasurementResult& m = r.measurements.at(0);
  EXPECT_TRUE(m.met);
  EXPECT_EQ(cache.builds(), 1u) << "the plan's tile, not built again";
  const auto& q = m.values.at("quantities");
  for (std::size_t j = 0; j < 2; ++j) {
    const double sum = q.at("E1").at("value")[0][j].get<double>() + q.at("unfinished").at("value")[0][j].get<double>() +
                       q.at("lost").at("value")[0][j].get<double>();
    EXPECT_NEAR(sum, 1.0, 1e-9) << "mu " << j;
  }

  // The rule's claim, with many more paths on the same tile (another seed).
  AlbedoTableRequest direct = surface_albedo_request(spec, d, 200'000, d.order_cap, 77, RunControl{2, nullptr, {}});
  const std::optional<AlbedoCells> cells = surface_albedo_cells_of(direct, {0, 2}, d.surface, cache);
  ASSERT_TRUE(cells);
  const AlbedoTable traced = albedo_table_from_cells(direct, *cells, 0);
  const AlbedoTable rougher = analytic_e1(2, 1.0);
  const double allowed = kBiasShare * target * e_min;
  bool control_outside = false;
  for (std::size_t j = 0; j < 2; ++j) {
    const Estimate e1 = traced.cell("E1", 0, j);
    const double exact_e1 = exact.cell("E1", 0, j).value;
    EXPECT_LE(std::abs(e1.value - exact_e1), allowed + 3 * e1.standard_error) << "mu " << traced.mus[j];
    control_outside = control_outside ||
                      std::abs(e1.value - rougher.cell("E1", 0, j).value) > allowed + 3 * e1.standard_error;
    std::cout << fmt::format("mu {:.3f}: tile E1 {:.4f} +- {:.4f}, Smith {:.4f} (alpha 1.0: {:.4f}), allowed {:.4f}\n",
                             traced.mus[j], e1.value, e1.standard_error, exact_e1, rougher.cell("E1", 0, j).value, allowed);
  }
  EXPECT_TRUE(control_outside) << "the analytic E1 of alpha 1.0 must fall outside the allowance";
}

TEST(ExperimentSurfaceAlbedo, ATightTargetOrAHeightmapIsNotRunnableAndBuildsNothing) {
  SurfaceCache cache;
  const ExperimentPlan tight = plan_on(tile_albedo_spec(0.001), cache);
  EXPECT_FALSE(tight.decisions.at(0).runnable);
  EXPECT_NE(tight.decisions[0].not_runnable.find("no tile up to 4096^2"), std::string::npos) << tight.decisions[0].not_runnable;
  const auto dir = microsim::test::scratch_dir("experiment_surface_albedo", "heightmap");
  SurfaceKey key;
  key.resolution = 256;
  key.alpha_x = key.alpha_y = 0.5;
  microgeom::save_heightmap_exr(dir / "tile.exr", microgeom::build_assembly(assembly_params(key)));
  const ExperimentPlan heightmap = plan_on(tile_albedo_spec(0.2, (dir / "tile.exr").string()), cache);
  EXPECT_FALSE(heightmap.decisions.at(0).runnable);
  EXPECT_NE(heightmap.decisions[0].not_runnable.find("a tile per alpha"), std::string::npos);
  EXPECT_EQ(cache.builds(), 0u);
  const ExperimentResults r = run_experiment(tile_albedo_spec(0.001), tight, RunOptions{});
  EXPECT_FALSE(r.measurements.at(0).ran);
}

}  // namespace surface_albedo_test
