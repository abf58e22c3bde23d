// Explicit heightfields in experiments:
//   - the size rule on the trade table (pure): a smaller target gets a bigger (or better matched) tile, a
//     grazing view or an anisotropic alpha a wider one, an unreachable target is reported with what is
//     reachable; a heightmap's own size gets the bias of the table row with no more correlation lengths;
//   - the surface cache: a key's surface is built once (counted), found again on disk by a second cache,
//     another alpha or seed is another key, a tampered, foreign or unreadable cache file is rebuilt;
//   - end to end on a small `smith` tile (256^2, the smallest the size rule takes for a GGX assembly): a VNDF
//     planned, run, written, read back and resumed after a cut inside a round, bit for bit, without building the
//     surface again; the run's summed rounds agree with a direct trace of the same tile, another seed (two-sample
//     chi-square, level 0.001), and not with a trace of the alpha 0.6 tile (negative control); per-order
//     scattering on the tile.
#include "experiment/heightfield_measures.h"
#include "measure/heightfield_trade.h"
#include "experiment/plan.h"
#include "experiment/run.h"
#include "experiment/run_directory.h"
#include "measure/surface_cache.h"
#include "measure/vndf.h"
#include "microgeom/exr_io.h"
#include "scratch_dir.h"
#include "stats/chi2.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <atomic>
#include <fstream>
#include <iostream>
#include <iterator>
#include <string>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_experiment_heightfield {

namespace heightfield_experiment_test {

using namespace microsim;
using namespace microsim::experiment;
using microsim::test::scratch_dir;

// ---- the size rule ---------------------------------------------------------------------------------------------

SurfaceSize size_for(double target, double theta = 30, double anisotropy = 1, bool scattering = false) {
  return choose_surface_size(builtin_trade_table(), {target, anisotropy, theta, scattering, 256});
}

TEST(HeightfieldTrade, TheBuiltinTableIsTheDocsData) {
  const TradeTable& t = builtin_trade_table();
  EXPECT_EQ(t.rows.size(), 10u);
  EXPECT_EQ(t.grazing_theta_deg, 60);
  EXPECT_EQ(t.grazing_min_tiles, 64);
  EXPECT_EQ(t.scattering_min_tiles, 64);
  EXPECT_DOUBLE_EQ(t.rows[5].bias(), 0.0456);  // joint 256^2: as independent triangles outside its own bins
  EXPECT_NE(t.source.find("surfaces.md"), std::string::npos);  // the page that first measured it
}

TEST(HeightfieldTrade, ASmallerTargetGetsABiggerOrBetterMatchedTile) {
  // 1/4 of the target: 0.125 admits radial 256^2 (NDF TV 0.1035); 0.075 needs radial 512^2 (0.0536);
  // 0.0125 radial 2048^2 (0.0119, 6.7 CPU s: joint 512^2's 0.0228 does not fit); 0.005 only joint 4096^2
  // (0.0029 as independent triangles; radial 4096^2 is 0.0067).
  const SurfaceSize coarse = size_for(0.5), finer = size_for(0.3), fine = size_for(0.05), finest = size_for(0.02);
  ASSERT_TRUE(coarse.found && finer.found && fine.found && finest.found);
  EXPECT_EQ(coarse.resolution, 256);
  EXPECT_EQ(coarse.ndf_match, "radial");
  EXPECT_DOUBLE_EQ(coarse.bias, 0.1035);
  EXPECT_EQ(finer.resolution, 512);
  EXPECT_EQ(finer.ndf_match, "radial");
  EXPECT_EQ(fine.resolution, 2048);
  EXPECT_EQ(fine.ndf_match, "radial");
  EXPECT_EQ(finest.resolution, 4096);
  EXPECT_EQ(finest.ndf_match, "joint");
  EXPECT_LE(finest.bias, kBiasShare * 0.02);
  EXPECT_NE(finer.reason.find("radial 512^2"), std::string::npos) << finer.reason;  // the row used
  EXPECT_NE(finer.reason.find("5.36e-02"), std::string::npos) << finer.reason;      // its bias
}

TEST(HeightfieldTrade, GrazingViewsAndAnisotropyNeedMore) {
  // Beyond 60 deg at least 64 correlation lengths: 1024^2 at l = 16, though 256^2 meets the bias at 30 deg.
  EXPECT_EQ(size_for(0.5, 75).resolution, 1024);
  // Per-order scattering: at least 64 l at any view.
  EXPECT_EQ(size_for(0.5, 30, 1, true).resolution, 1024);
  EXPECT_NE(size_for(0.5, 30, 1, true).reason.find("per-order scattering"), std::string::npos);
  // 1:4: twice the bias (sqrt 4): radial 256^2 (0.207) no longer fits 0.125, 512^2 (0.107) does.
  const SurfaceSize aniso = size_for(0.5, 30, 4);
  EXPECT_EQ(aniso.resolution, 512);
  EXPECT_DOUBLE_EQ(aniso.bias, 2 * 0.0536);
}

TEST(HeightfieldTrade, AnUnreachableTargetIsReportedWithWhatIsReachable) {
  const SurfaceSize none = size_for(1e-4);
  EXPECT_FALSE(none.found);
  EXPECT_NE(none.reason.find("no tile up to 4096^2"), std::string::npos) << none.reason;
  EXPECT_NE(none.reason.find("1.16e-02"), std::string::npos) << none.reason;  // joint 4096^2: 0.0029 / 0.25
  // Negative control: the smallest reachable target is reached.
  EXPECT_TRUE(size_for(0.01161).found);
  EXPECT_THROW(size_for(0), std::invalid_argument);
}

TEST(HeightfieldTrade, AHeightmapsBiasComesFromTheRowWithNoMoreCorrelationLengths) {
  const TradeTable& t = builtin_trade_table();
  const auto exact = predicted_bias(t, 1024, 16, "radial", 1);
  ASSERT_TRUE(exact);
  EXPECT_DOUBLE_EQ(exact->bias, 0.0316);
  const auto between = predicted_bias(t, 1024, 12, "joint", 1);  // 85 l: the 64 l row (1024^2 joint)
  ASSERT_TRUE(between);
  EXPECT_DOUBLE_EQ(between->bias, 0.0114);
  EXPECT_FALSE(predicted_bias(t, 256, 32, "radial", 1));  // 8 l: narrower than every row
}

TEST(HeightfieldTrade, MalformedTablesAreNamed) {
  const auto message = [](const char* text) {
    try {
      trade_table_from_json(nlohmann::json::parse(text));
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message(R"({"source": "x"})").find("'rows'"), std::string::npos);
  EXPECT_NE(message(R"({"source": "x", "rows": [{"ndf_match": "iaaft", "resolution": 256, "corr_cells": 16,
      "bias_tv": 0.1, "iid_noise_tv": 0.04, "build_cpu_seconds": 1}]})").find("rows[0].ndf_match"), std::string::npos);
  EXPECT_NE(message(R"({"source": "x", "rows": [{"ndf_match": "radial", "resolution": 256}]})").find("corr_cells"),
            std::string::npos);
}

// ---- the cache -------------------------------------------------------------------------------------------------

SurfaceKey small_key() {  // a 64^2 tile: builds in milliseconds
  SurfaceKey k;
  k.resolution = 64;
  k.corr_cells = 4;
  k.alpha_x = k.alpha_y = 0.4;
  k.seed = 3;
  return k;
}

TEST(SurfaceCache, AnotherAlphaOrSeedIsAnotherKey) {
  SurfaceKey a = small_key(), b = small_key(), c = small_key();
  b.alpha_y = 0.41;
  c.seed = 4;
  EXPECT_NE(surface_key_hash(a), surface_key_hash(b));
  EXPECT_NE(surface_key_hash(a), surface_key_hash(c));
  EXPECT_EQ(surface_key_hash(a), surface_key_hash(small_key()));
  EXPECT_EQ(canonical_surface_key(a),
            "assembly=smith;ndf=ggx;alpha=0.40000000000000002,0.40000000000000002;resolution=64;corr_cells=4;"
            "ndf_match=radial;seed=3;builder=1");
}

TEST(SurfaceCache, ASecondMeasurementOnTheSameKeyDoesNotRebuild) {
  const auto dir = scratch_dir("surface_cache", "reuse") / "surfaces";
  SurfaceCache cache(dir);
  const microgeom::Heightfield& first = cache.surface_for(small_key());
  const microgeom::Heightfield& again = cache.surface_for(small_key());
  EXPECT_EQ(&first, &again);
  EXPECT_EQ(cache.builds(), 1u);
  EXPECT_TRUE(std::filesystem::exists(cache.path_for(small_key())));
  SurfaceKey other = small_key();
  other.seed = 4;
  cache.surface_for(other);
  EXPECT_EQ(cache.builds(), 2u);
  // A resumed run: another cache on the same directory reads the file, builds nothing.
  SurfaceCache resumed(dir);
  const microgeom::Heightfield& read = resumed.surface_for(small_key());
  EXPECT_EQ(resumed.builds(), 0u);
  EXPECT_EQ(read.heights(), first.heights());
  ASSERT_EQ(resumed.events().size(), 1u);
  EXPECT_EQ(resumed.events()[0].rfind("read ", 0), 0u) << resumed.events()[0];
}

TEST(SurfaceCache, ATamperedForeignOrUnreadableFileIsRebuilt) {
  const auto dir = scratch_dir("surface_cache", "tamper") / "surfaces";
  SurfaceKey other = small_key();
  other.seed = 4;
  std::vector<float> original;
  {
    SurfaceCache cache(dir);
    original = cache.surface_for(small_key()).heights();
    cache.surface_for(other);
  }
  const auto path = SurfaceCache(dir).path_for(small_key());
  const auto rebuilt_because = [&](const std::string& why) {
    SurfaceCache cache(dir);
    const microgeom::Heightfield& h = cache.surface_for(small_key());
    EXPECT_EQ(cache.builds(), 1u) << why;
    EXPECT_EQ(h.heights(), original) << why;
    ASSERT_FALSE(cache.events().empty());
    EXPECT_NE(cache.events()[0].find(why), std::string::npos) << cache.events()[0];
  };
  // One height changed, the attributes kept.
  microgeom::ExrImage image = microgeom::read_exr(path);
  image.find("height")->data[17] += 0.01f;
  microgeom::write_exr(path, image);
  rebuilt_because("heights changed");
  // Another key's file copied over it.
  std::filesystem::copy_file(SurfaceCache(dir).path_for(other), path, std::filesystem::copy_options::overwrite_existing);
  rebuilt_because("another surface");
  // Not an EXR at all.
  std::ofstream(path, std::ios::trunc) << "not an image";
  rebuilt_because("cannot be read");
  // Negative control: the rebuilt file is used as it is.
  SurfaceCache cache(dir);
  cache.surface_for(small_key());
  EXPECT_EQ(cache.builds(), 0u);
}

// ---- end to end --------------------------------------------------------------------------------------------------

// A spec of one quantity at theta 40 on `surface` (an assembly, or a heightmap's path).
ExperimentSpec smith_spec(const std::string& kind, double target, const std::string& surface = "smith") {
  return parse_spec_toml(fmt::format(R"(
seed = 7
[[material]]
name = "m"
alphas = [0.5]
type = "mirror"
[[quantity]]
kind = "{}"
material = "m"
surface = "{}"
theta = [40]
{}
target_tv = {}
)", kind, surface, kind == "vndf" ? "rows = 7" : "orders = \"all\"", target), "smith.toml");
}

ExperimentPlan small_plan(const ExperimentSpec& spec, SurfaceCache& cache) {
  PlanOptions o;
  o.pilot_rays = 1 << 14;
  o.cap_pilot_paths = 1 << 13;
  o.run.threads = 2;
  o.surfaces = &cache;
  return plan_experiment(spec, o);
}

ExperimentResults run_on(const ExperimentSpec& spec, const ExperimentPlan& plan, SurfaceCache& cache, RunControl run,
                         double cost = 1, const ExperimentResults* resume = nullptr) {
  RunOptions o;
  o.run = std::move(run);
  o.surfaces = &cache;
  o.cost_factor = cost;
  o.resume = resume;
  return run_experiment(spec, plan, o);
}

// The values and errors of a run, without its timings.
nlohmann::json measured(const ExperimentResults& results) {
  nlohmann::json out = nlohmann::json::array();
  for (const MeasurementResult& m : results.measurements) {
    nlohmann::json rounds = nlohmann::json::array();
    for (const RoundRecord& r : m.rounds) rounds.push_back({r.units, r.seed, r.achieved, r.partial});
    out.push_back({{"values", m.values}, {"rounds", rounds}, {"achieved", m.achieved}, {"units", m.units}, {"met", m.met}});
  }
  return out;
}

// Cancels once the stage has done `fraction` of its first call.
struct CancelPart {
  CancelToken token;
  RunControl control(const std::string& stage, double fraction) {
    RunControl run;
    run.threads = 2;
    run.cancel = &token;
    run.progress = [this, stage, fraction](std::string_view s, std::uint64_t done, std::uint64_t total) {
      if (s == stage && double(done) >= fraction * double(total)) token.cancel();
    };
    return run;
  }
};

TEST(ExperimentHeightfield, AnAssemblyVndfRunsWritesAndResumesWithoutRedoingWork) {
  const auto dir = scratch_dir("experiment_heightfield", "vndf");
  const ExperimentSpec spec = smith_spec("vndf", 0.42);  // 1/4 of it: 0.105, above radial 256^2's 0.1035
  SurfaceCache cache(dir / "surfaces");
  const ExperimentPlan plan = small_plan(spec, cache);
  ASSERT_EQ(plan.decisions.size(), 1u);
  const Decision& d = plan.decisions[0];
  ASSERT_TRUE(d.runnable) << d.not_runnable;
  EXPECT_EQ(d.model.model, Model::heightfield);
  EXPECT_EQ(d.surface.resolution, 256);
  EXPECT_EQ(d.surface.ndf_match, "radial");
  EXPECT_DOUBLE_EQ(d.surface.bias, 0.1035);
  EXPECT_GT(d.predicted_seconds, 0);
  EXPECT_EQ(cache.builds(), 1u);  // the plan built it (its pilot traced it)

  // The whole run (at 200x the planned rays: a round of many blocks), on the plan's cache: nothing rebuilt.
  const ExperimentResults whole = run_on(spec, plan, cache, RunControl{2, nullptr, {}}, 200);
  EXPECT_EQ(cache.builds(), 1u);
  ASSERT_TRUE(whole.measurements[0].met);
  const MeasurementResult& w = whole.measurements[0];
  EXPECT_GT(w.units, 50000u);
  ASSERT_TRUE(w.values.contains("heightfield"));

  // Cut at 40% of its round, written to DIR, read back as a rerun finds it, resumed with a new cache on DIR.
  CancelPart cancel;
  const ExperimentResults cut = run_on(spec, plan, cache, cancel.control("trace vndf (heightfield)", 0.4), 200);
  ASSERT_TRUE(cut.partial);
  ASSERT_TRUE(cut.measurements[0].rounds.back().partial);
  EXPECT_LT(cut.measurements[0].units, w.units);
  write_run_directory(dir, spec, plan, cut, {"test", "test", spec.seed, {}});
  {  // the report states the tile, where it is cached and its predicted bias
    std::ifstream page(dir / "index.html");
    const std::string html((std::istreambuf_iterator<char>(page)), std::istreambuf_iterator<char>());
    EXPECT_NE(html.find("surfaces/" + d.surface.hash + ".exr"), std::string::npos);
    EXPECT_NE(html.find("predicted bias (TV) 0.1035"), std::string::npos);
  }
  const std::optional<PreviousRun> previous = load_previous_run(dir, spec, spec.seed, input_digests(spec));
  ASSERT_TRUE(previous);
  ASSERT_TRUE(previous->plan.decisions[0].surface.hash == d.surface.hash);
  SurfaceCache again(dir / "surfaces");
  const ExperimentResults resumed = run_on(spec, previous->plan, again, RunControl{1, nullptr, {}}, 200, &previous->results);
  EXPECT_FALSE(resumed.partial);
  EXPECT_EQ(again.builds(), 0u);  // read from DIR/surfaces
  EXPECT_EQ(measured(resumed).dump(), measured(whole).dump());
  // A finished run run again: kept as it is (nothing traced, nothing built).
  SurfaceCache third(dir / "surfaces");
  const ExperimentResults kept = run_on(spec, previous->plan, third, RunControl{1, nullptr, {}}, 200, &resumed);
  EXPECT_EQ(third.events().size(), 0u);
  EXPECT_EQ(measured(kept).dump(), measured(whole).dump());
}

// Two-sample chi-square (stats/chi2.h) of the run's summed counts against a direct trace, lobe binning.
double homogeneity_p(const TracedHistogram& run, const TracedHistogram& direct) {
  const std::size_t k = run.binnings.size() - 1;
  const std::vector<double> a(run.counts[k].begin(), run.counts[k].end()), b(direct.counts[k].begin(), direct.counts[k].end());
  return two_sample_homogeneity(a, b).p_value;
}

TEST(ExperimentHeightfield, TheRunsRoundsAgreeWithADirectTraceOfTheTileAndNotOfAnother) {
  const ExperimentSpec spec = smith_spec("vndf", 0.42);
  SurfaceCache cache;
  const ExperimentPlan plan = small_plan(spec, cache);
  const ExperimentResults r = run_on(spec, plan, cache, RunControl{2, nullptr, {}}, 200);
  const MeasurementResult& m = r.measurements[0];
  ASSERT_TRUE(m.met);
  const Decision& d = plan.decisions[0];
  // The same tile from the cache (not built again), traced directly with another seed and as many rays.
  const microgeom::Heightfield& field = cache.surface_for(surface_key(d.surface, d.alpha));
  EXPECT_EQ(cache.builds(), 1u);
  VndfRequest direct;
  direct.theta_deg = 40;
  direct.rays = m.units;
  direct.seed = 991;
  direct.rows = 7;
  const double same = homogeneity_p(m.histogram, measure_heightfield_vndf(field, "direct", direct).histogram);
  EXPECT_GT(same, 1e-3) << "the run's histogram is not the tile's VNDF (level 0.001)";
  // Negative control: the tile of alpha 0.6 (same seed, size), as many rays: rejected.
  SurfaceKey rougher = surface_key(d.surface, d.alpha);
  rougher.alpha_x = rougher.alpha_y = 0.6;
  const double other = homogeneity_p(m.histogram, measure_heightfield_vndf(cache.surface_for(rougher), "other", direct).histogram);
  EXPECT_LT(other, 1e-6);
  std::cout << "rays " << m.units << ": p same tile " << same << ", p alpha 0.6 tile " << other << "\n";
}

// A 256^2 smith tile (alpha 0.5, l 16, radial) written as a heightmap.
std::string small_heightmap(const std::filesystem::path& dir) {
  SurfaceKey key;
  key.resolution = 256;
  key.corr_cells = 16;
  key.seed = 2;
  microgeom::save_heightmap_exr(dir / "tile.exr", microgeom::build_assembly(assembly_params(key)));
  return (dir / "tile.exr").string();
}

TEST(ExperimentHeightfield, PerOrderScatteringOnATileRuns) {
  // On a heightmap (its own size: 256^2; an assembly's per-order scattering gets at least 64 l, 1024^2,
  // as HeightfieldTrade.GrazingViewsAndAnisotropyNeedMore checks).
  const ExperimentSpec spec = smith_spec("scattering", 0.42, small_heightmap(scratch_dir("experiment_heightfield", "scatter")));
  SurfaceCache cache;
  const ExperimentPlan plan = small_plan(spec, cache);
  ASSERT_TRUE(plan.decisions[0].runnable) << plan.decisions[0].not_runnable;
  EXPECT_EQ(plan.decisions[0].surface.resolution, 256);
  EXPECT_GE(plan.decisions[0].order_cap, 4);
  const ExperimentResults r = run_on(spec, plan, cache, RunControl{2, nullptr, {}});
  const MeasurementResult& m = r.measurements[0];
  EXPECT_TRUE(m.met);
  EXPECT_EQ(cache.builds(), 0u);
  ASSERT_TRUE(m.values.contains("scattering"));
  // A lossless mirror: what leaves plus what is still on the surface is all of it.
  const double albedo = m.values["scattering"]["albedo"]["value"].get<double>();
  const double unfinished = m.values["scattering"]["unfinished"]["value"].get<double>();
  EXPECT_NEAR(albedo + unfinished, 1.0, 1e-9);
  EXPECT_GT(m.values["scattering"]["orders"][1]["albedo"]["value"].get<double>(), 0.01);  // order 2 seen
}

TEST(ExperimentHeightfield, AnUnreachableTargetIsNotRunnableAndBuildsNothing) {
  const ExperimentSpec spec = smith_spec("vndf", 1e-4);
  SurfaceCache cache;
  const ExperimentPlan plan = small_plan(spec, cache);
  EXPECT_FALSE(plan.decisions[0].runnable);
  EXPECT_NE(plan.decisions[0].not_runnable.find("no tile up to 4096^2"), std::string::npos) << plan.decisions[0].not_runnable;
  EXPECT_EQ(cache.builds(), 0u);
  const ExperimentResults r = run_on(spec, plan, cache, RunControl{2, nullptr, {}});
  EXPECT_FALSE(r.measurements[0].ran);
}

TEST(ExperimentHeightfield, AHeightmapKeepsItsSizeAndStatesTheBiasTheTablePredicts) {
  const auto dir = scratch_dir("experiment_heightfield", "heightmap");
  const std::string tile = small_heightmap(dir);
  const ExperimentSpec spec = parse_spec_toml(fmt::format(R"(
[[material]]
name = "m"
alphas = [0.5]
type = "mirror"
[[quantity]]
kind = "vndf"
material = "m"
surface = "{}"
theta = [30]
rows = 7
target_tv = 0.1
)", tile), (dir / "spec.toml").string());
  SurfaceCache cache;
  const ExperimentPlan plan = small_plan(spec, cache);
  const Decision& d = plan.decisions[0];
  ASSERT_TRUE(d.runnable) << d.not_runnable;
  EXPECT_EQ(d.surface.kind, "heightmap");
  EXPECT_EQ(d.surface.resolution, 256);
  EXPECT_DOUBLE_EQ(d.surface.bias, 0.1035);
  EXPECT_NE(d.surface.reason.find("ABOVE"), std::string::npos) << d.surface.reason;  // 0.1035 > 0.25 x 0.1
  EXPECT_EQ(cache.builds(), 0u);
}

TEST(ExperimentHeightfield, AHeightmapThatCannotBeReadIsBadInputNamingTheKey) {
  const auto dir = scratch_dir("experiment_heightfield", "bad_heightmap");
  std::ofstream(dir / "tile.exr") << "not an image";
  const ExperimentSpec spec = smith_spec("vndf", 0.1, (dir / "tile.exr").string());
  SurfaceCache cache;
  try {
    small_plan(spec, cache);
    FAIL() << "planned";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("quantity[0].surface: ", 0), 0u) << e.what();
  }
}

}  // namespace heightfield_experiment_test

}  // namespace test_experiment_heightfield
