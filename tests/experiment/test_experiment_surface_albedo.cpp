// An albedo table on explicit surfaces in experiments (src/experiment/surface_albedo.h):
//   - the size rule: the target turned into an absolute bias at the table's smallest albedo picks the trade
//     table's tile (every alpha the same size, 64 correlation lengths wide); a target no tile meets, or a
//     heightmap (one alpha), is not runnable, says why and builds nothing;
//   - the run meets its target on the tiles the plan built (not built again); each cell's E1, what is still on
//     the surface and what the tracer lost add up to the mirror's 1;
//   - the rule's claim, measured: the smith tile's E1, traced with many paths, is within the bias the rule
//     allows (kBiasShare x target x E_min) plus 3 standard errors of Smith's analytic E1 (Walter et al. 2007
//     with Smith masking, by quadrature), at every cell; negative control: the analytic E1 of another alpha
//     (1.0) is outside it;
//   - a validation against the tile's traced visible normals (two-sample chi-square): a correct VNDF sampler
//     and a dump of it pass at the planned count, a dump of another alpha's VNDF is rejected, samplers and dumps
//     that do not claim the visible normals are not runnable.
#include "experiment/heightfield_measures.h"
#include "experiment/plan.h"
#include "experiment/run.h"
#include "experiment/surface_albedo.h"
#include "measure/surface_cache.h"
#include "scatter/albedo_table.h"
#include "core/random.h"
#include "microfacet/samplers.h"
#include "validate/sample_io.h"
#include "microgeom/exr_io.h"
#include "scratch_dir.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <utility>
#include <vector>
#include <iostream>
#include <string>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_experiment_surface_albedo {

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

// ---- a validation against a tile's traced visible normals ------------------------------------------------------

namespace surface_validation_test {

using namespace microsim;
using namespace microsim::experiment;

// heitz2018 (or a dump, pdf `pdf`) at alpha 0.5, theta 40, against smith's tile, detecting TV 0.2.
ExperimentSpec tile_validation_spec(const std::string& what, const std::string& pdf = "vndf") {
  const std::string source = what.ends_with(".npy") ? fmt::format("dump = \"{}\"\npdf = \"{}\"", what, pdf)
                                                    : fmt::format("sampler = \"{}\"", what);
  return parse_spec_toml(fmt::format(R"(
seed = 8
[[material]]
name = "m"
alpha = 0.5
type = "mirror"
[[quantity]]
kind = "validation"
material = "m"
surface = "smith"
{}
theta = [40]
rows = 7
detect_tv = 0.2
)", source), "tile_validation.toml");
}

// `n` samples of heitz2018 at `alpha` for the view of tile_validation_spec, as an NPY dump.
std::string heitz_dump(const std::filesystem::path& path, double alpha, std::uint64_t n) {
  const GGX<double> ggx(alpha, alpha);
  const Vec3<double> wi = direction_from_degrees(40.0, 0.0);
  CounterRng rng(5, 0);
  std::vector<Vec3<double>> normals;
  for (std::uint64_t i = 0; i < n; ++i) normals.push_back(sample_heitz2018(ggx, wi, Vec2<double>(rng.uniform(), rng.uniform()))->direction);
  write_npy(path, normals, /*as_float32=*/false);
  return path.string();
}

const MeasurementResult& run_one(const ExperimentSpec& spec, const ExperimentPlan& plan, SurfaceCache& cache,
                                 ExperimentResults& out) {
  RunOptions o;
  o.run.threads = 2;
  o.surfaces = &cache;
  out = run_experiment(spec, plan, o);
  return out.measurements.at(0);
}

// A correct VNDF sampler passes at the planned count, on the tile the size rule picks for TV 0.2 (bias <= 0.05);
// a dump of the alpha 1.0 VNDF declared as alpha 0.5's is rejected (negative control), a dump of alpha 0.5's
// passes; a sampler or a dump that does not claim the visible normals is not runnable and says why.
TEST(ExperimentSurfaceValidation, ATracedTileValidatesVndfSamplersAndDumps) {
  SurfaceCache cache;
  const ExperimentSpec spec = tile_validation_spec("heitz2018");
  const ExperimentPlan plan = surface_albedo_test::plan_on(spec, cache);
  const Decision& d = plan.decisions.at(0);
  ASSERT_TRUE(d.runnable) << d.not_runnable;
  EXPECT_EQ(d.model.model, Model::heightfield);
  EXPECT_LE(d.surface.bias, kBiasShare * 0.2);
  EXPECT_NE(d.count_reason.find("two-sample"), std::string::npos) << d.count_reason;
  ExperimentResults r;
  const MeasurementResult& m = run_one(spec, plan, cache, r);
  EXPECT_TRUE(m.met);
  const nlohmann::json& v = m.values.at("validation");
  EXPECT_EQ(v.at("verdict"), "pass") << v.dump().substr(0, 600);
  EXPECT_NE(v.at("reference").get<std::string>().find("rays traced on assembly smith"), std::string::npos);
  EXPECT_EQ(cache.builds(), 1u) << "the plan's tile";

  const auto dir = microsim::test::scratch_dir("experiment_surface_validation", "dumps");
  const std::uint64_t n = d.units;
  for (const auto& [alpha, verdict] : {std::pair{0.5, "pass"}, std::pair{1.0, "fail"}}) {
    const ExperimentSpec dump = tile_validation_spec(heitz_dump(dir / fmt::format("heitz{}.npy", alpha), alpha, n));
    const ExperimentPlan dump_plan = surface_albedo_test::plan_on(dump, cache);
    ASSERT_TRUE(dump_plan.decisions.at(0).runnable) << dump_plan.decisions[0].not_runnable;
    ExperimentResults dr;
    EXPECT_EQ(run_one(dump, dump_plan, cache, dr).values.at("validation").at("verdict"), verdict) << "alpha " << alpha;
  }
  const ExperimentPlan ndf = surface_albedo_test::plan_on(tile_validation_spec("ndf"), cache);
  EXPECT_FALSE(ndf.decisions.at(0).runnable);
  EXPECT_NE(ndf.decisions[0].not_runnable.find("does not claim the visible normals"), std::string::npos);
  const ExperimentPlan other_pdf =
      surface_albedo_test::plan_on(tile_validation_spec(heitz_dump(dir / "n.npy", 0.5, 10), "ndf"), cache);
  EXPECT_FALSE(other_pdf.decisions.at(0).runnable);
  EXPECT_NE(other_pdf.decisions[0].not_runnable.find("pdf vndf only"), std::string::npos);
}

}  // namespace surface_validation_test

}  // namespace test_experiment_surface_albedo
