// Tests of the heightfield assemblies (microgeom/assembly.h): validation, reproducibility (seed, thread
// count), the measured NDF of every assembly within its stated tolerance, negative controls that must
// fail that check, and the structural property that distinguishes each assembly.
#include "microgeom/assembly.h"
#include "microgeom/surface_stats.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_assembly {

using namespace microgeom;

namespace {

AssemblyParams params(const std::string& name, int n = 128, double ax = 0.3, double ay = 0.3, std::uint64_t seed = 1) {
  AssemblyParams p;
  p.assembly = name;
  p.resolution = n;
  p.alpha_x = ax;
  p.alpha_y = ay;
  p.seed = seed;
  return p;
}

SurfaceStats stats_of(const Heightfield& f, const AssemblyParams& p, std::optional<NdfKind> ref = {},
                      double alpha_factor = 1.0) {
  const AssemblyInfo* info = find_assembly(p.assembly);
  StatsOptions o;
  o.reference = ref ? *ref : info->reference;
  o.alpha_x = p.alpha_x * alpha_factor;
  o.alpha_y = p.alpha_y * alpha_factor;
  const double l = p.corr_cells == 0 ? default_corr_cells(p.resolution) : p.corr_cells;
  o.tolerance = tolerance_for(o.reference, p.resolution, l);
  return measure_surface(f, o);
}

std::string message_of(const AssemblyParams& p) {
  try {
    validate(p);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(valid)";
}

}  // namespace

TEST(Assembly, RegistryNamesAreUniqueAndDescribed) {
  std::set<std::string> names;
  for (const auto& a : assembly_registry()) {
    EXPECT_TRUE(names.insert(a.name).second) << a.name;
    EXPECT_GT(a.summary.size(), 40u) << a.name;
    EXPECT_EQ(find_assembly(a.name), &a);
  }
  for (const char* n : {"smith", "beckmann", "mixture", "sorted", "spikes"}) EXPECT_TRUE(names.count(n)) << n;
  EXPECT_EQ(find_assembly("nope"), nullptr);
  EXPECT_EQ(find_assembly("beckmann")->reference, NdfKind::beckmann);
}

TEST(Assembly, ValidationNamesTheBadValue) {
  EXPECT_EQ(message_of(params("smith")), "(valid)");
  EXPECT_NE(message_of(params("smiht")).find("'smiht'"), std::string::npos);
  EXPECT_NE(message_of(params("smith", 100)).find("resolution 100"), std::string::npos);
  EXPECT_NE(message_of(params("smith", 8)).find("resolution 8"), std::string::npos);
  EXPECT_NE(message_of(params("smith", 16384)).find("16384"), std::string::npos);
  EXPECT_NE(message_of(params("smith", 128, 2.5)).find("alpha 2.5"), std::string::npos);
  EXPECT_NE(message_of(params("smith", 128, 0.3, 0.001)).find("alpha 0.001"), std::string::npos);
  EXPECT_NE(message_of(params("smith", 128, std::nan(""))).find("alpha nan"), std::string::npos);
  auto p = params("smith");
  p.corr_cells = 17;  // > N/8 = 16
  EXPECT_NE(message_of(p).find("17"), std::string::npos);
  p.corr_cells = 1;
  EXPECT_NE(message_of(p).find("correlation length 1"), std::string::npos);
  p = params("smith");
  p.tile_size = 0;
  EXPECT_NE(message_of(p).find("tile size 0"), std::string::npos);
  p = params("smith");
  p.iterations = -1;
  EXPECT_NE(message_of(p).find("iterations -1"), std::string::npos);
  EXPECT_THROW(build_assembly(params("smith", 100)), std::invalid_argument);
}

TEST(Assembly, SameSeedSameSurfaceWhateverTheThreadCount) {
  for (const char* name : {"smith", "beckmann", "mixture", "sorted"}) {
    const auto p = params(name, 64);
    const Heightfield a = build_assembly(p);
    Heightfield b;
    {
      tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
      b = build_assembly(p);
    }
    EXPECT_EQ(a.heights(), b.heights()) << name;
    const Heightfield c = build_assembly(params(name, 64, 0.3, 0.3, 2));
    EXPECT_NE(a.heights(), c.heights()) << name;
    EXPECT_EQ(a.metadata.at("assembly"), name);
    EXPECT_EQ(a.metadata.at("seed"), "1");
  }
}

TEST(Assembly, HeightsHaveMeanZeroAndScaleWithTheTile) {
  auto p = params("smith", 64);
  const Heightfield a = build_assembly(p);
  EXPECT_NEAR(a.mean_height(), 0.0, 1e-6 * (a.max_height() - a.min_height()));
  p.tile_size = 4.0;
  const Heightfield b = build_assembly(p);
  for (std::size_t k = 0; k < a.heights().size(); ++k)
    ASSERT_NEAR(b.heights()[k], 4.0f * a.heights()[k], 1e-5f * std::fabs(b.heights()[k]) + 1e-9f);
}

// Every assembly, isotropic and anisotropic: the measured NDF is within the stated tolerance of the
// assembly's reference (the same check that fails `surface build`).
TEST(Assembly, EveryAssemblyMeetsItsNdfTolerance) {
  for (const auto& info : assembly_registry())
    for (auto [ax, ay] : {std::pair{0.3, 0.3}, std::pair{0.15, 0.6}}) {
      const auto p = params(info.name, 256, ax, ay, 3);
      BuildReport report;
      const Heightfield f = build_assembly(p, &report);
      const SurfaceStats st = stats_of(f, p);
      EXPECT_TRUE(st.ndf_within_tolerance) << info.name << " alpha " << ax << "," << ay << ": " << st.ndf_verdict;
      if (info.reference == NdfKind::ggx) {
        // The slope matching converges: the re-integrated slopes are their own rank-matched version to 1e-2.
        ASSERT_FALSE(report.residuals.empty());
        EXPECT_LT(report.residuals.back(), 1e-2) << info.name;
        EXPECT_LT(st.max_quantile_error, 0.02) << info.name;  // measured <= 1% at N = 256
      }
    }
}

// Negative controls: the NDF check must reject a surface against the wrong law or the wrong roughness.
TEST(Assembly, NdfCheckRejectsWrongReferencesAndRoughness) {
  const auto ggx = params("smith", 256);
  const Heightfield g = build_assembly(ggx);
  EXPECT_FALSE(stats_of(g, ggx, NdfKind::beckmann).ndf_within_tolerance);
  EXPECT_FALSE(stats_of(g, ggx, {}, 1.05).ndf_within_tolerance);  // 5% off in alpha
  auto p = params("beckmann", 512);
  p.corr_cells = 4;  // 128 correlation lengths per tile: a tight Beckmann tolerance
  const Heightfield b = build_assembly(p);
  EXPECT_TRUE(stats_of(b, p).ndf_within_tolerance) << stats_of(b, p).ndf_verdict;
  EXPECT_FALSE(stats_of(b, p, NdfKind::ggx).ndf_within_tolerance);
  EXPECT_FALSE(stats_of(b, p, {}, 1.1).ndf_within_tolerance);
  // Anisotropy: checked with the axes swapped, the surface fails.
  auto an = params("smith", 256, 0.15, 0.6);
  const Heightfield a = build_assembly(an);
  auto swapped = an;
  std::swap(swapped.alpha_x, swapped.alpha_y);
  EXPECT_FALSE(stats_of(a, swapped).ndf_within_tolerance);
  // Too few iterations: the start field is far from GGX.
  auto one = params("smith", 128);
  one.iterations = 1;
  EXPECT_FALSE(stats_of(build_assembly(one), one).ndf_within_tolerance);
}

TEST(Assembly, BeckmannSlopesHaveSecondMomentAlphaSquaredOverTwoPerAxis) {
  const auto p = params("beckmann", 128, 0.2, 0.5);
  const SurfaceStats st = stats_of(build_assembly(p), p);
  // Random phases with fixed amplitudes: the realised per-axis moments are those of the spectrum.
  EXPECT_NEAR(st.normalised_second_moment_x, 0.5, 2e-3);
  EXPECT_NEAR(st.normalised_second_moment_y, 0.5, 2e-3);
}

// What distinguishes the assemblies (same NDF): where the steep facets sit, and how roughness is spread.
TEST(Assembly, HeightSlopeCouplingDistinguishesTheAssemblies) {
  const auto ps = params("smith", 256);
  const SurfaceStats smith = stats_of(build_assembly(ps), ps);
  EXPECT_LT(std::fabs(smith.spearman_height_slope), 0.15);  // measured 0.01-0.07

  const auto pso = params("sorted", 256);
  const Heightfield sorted = build_assembly(pso);
  const SurfaceStats so = stats_of(sorted, pso);
  EXPECT_LT(so.spearman_height_slope, -0.4);
  EXPECT_LT(so.steepest_1pct_height_z, -2.0);

  const auto psp = params("spikes", 256);
  const Heightfield spikes = build_assembly(psp);
  for (std::size_t k = 0; k < sorted.heights().size(); ++k) ASSERT_EQ(spikes.heights()[k], -sorted.heights()[k]);
  const SurfaceStats sp = stats_of(spikes, psp);
  EXPECT_NEAR(sp.spearman_height_slope, -so.spearman_height_slope, 1e-3);
  EXPECT_GT(sp.steepest_1pct_height_z, 2.0);
}

TEST(Assembly, MixtureSpreadsRoughnessOverPatches) {
  // Median normalised slope radius per block of 8 l cells (the patch size): nearly constant for smith,
  // widely spread for the mixture (patch roughness 1/sqrt(E), E ~ Exp(1)).
  auto spread = [](const Heightfield& f, double ax, int block) {
    const int n = f.resolution(), blocks = n / block;
    std::vector<double> logs;
    for (int bj = 0; bj < blocks; ++bj)
      for (int bi = 0; bi < blocks; ++bi) {
        std::vector<double> r;
        for (int j = bj * block; j < (bj + 1) * block; ++j)
          for (int i = bi * block; i < (bi + 1) * block; ++i)
            for (int t = 0; t < 2; ++t) r.push_back(f.triangle_slope(i, j, t).norm() / ax);
        std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
        logs.push_back(std::log(r[r.size() / 2]));
      }
    double m = 0, v = 0;
    for (double x : logs) m += x;
    m /= logs.size();
    for (double x : logs) v += (x - m) * (x - m);
    return std::sqrt(v / logs.size());
  };
  auto pm = params("mixture", 256);
  pm.corr_cells = 4;  // patches of 32 cells: 8 x 8 patches
  auto psm = pm;
  psm.assembly = "smith";
  const double mixture = spread(build_assembly(pm), 0.3, 32);
  const double smith = spread(build_assembly(psm), 0.3, 32);
  EXPECT_GT(mixture, 2.5 * smith) << "mixture " << mixture << " smith " << smith;
}

TEST(Assembly, RadixSortMatchesAStableSortByTheUpperHalf) {
  std::vector<std::uint64_t> keys(100000), scratch;
  std::uint64_t state = 12345;
  for (std::size_t k = 0; k < keys.size(); ++k) {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    const std::uint32_t value = std::uint32_t(state >> 33) % 5000u * 859433u;  // many ties, all bit ranges
    keys[k] = (std::uint64_t(value) << 32) | std::uint32_t(k);
  }
  auto expected = keys;
  std::sort(expected.begin(), expected.end());  // (value, index): the stable order
  microgeom::detail::radix_sort_by_high32(keys, scratch);
  EXPECT_EQ(keys, expected);
  std::vector<std::uint64_t> empty;
  microgeom::detail::radix_sort_by_high32(empty, scratch);
  EXPECT_TRUE(empty.empty());
}

}  // namespace test_assembly
