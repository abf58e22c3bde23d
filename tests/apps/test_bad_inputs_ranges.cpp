// The supported ranges of the surface builder and of the traced quadric.
// Outside them the command refuses before any work (exit 2, the message names the bad value and what
// would work, nothing written); at their edges it works (the build meets its own NDF check).
#include "cli_helpers.h"

#include "microgeom/assembly.h"
#include "microgeom/surface_stats.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_bad_inputs_ranges {

namespace {

using microsim::test::BadInputCase;

std::vector<BadInputCase> range_cases() {
  std::vector<BadInputCase> cases;
  // Too few texels for the GGX assemblies' fixed 3% bounds (--res 64 failed its own check).
  for (const char* a : {"smith", "mixture", "sorted", "spikes"})
    for (int n : {16, 64, 128})
      cases.push_back({std::string(a) + "_res" + std::to_string(n),
                       "surface build --quiet --assembly " + std::string(a) + " --alpha 0.5 --res " +
                           std::to_string(n) + " --out s.exr --json s.json",
                       2, "resolution " + std::to_string(n) + " cannot meet its NDF check: use resolution >= 256"});
  // Anisotropy beyond 1:4 (alpha 0.005,2 failed for every assembly at 64 and 256); the message
  // suggests a supported pair keeping the rougher axis.
  for (const char* a : {"smith", "beckmann", "mixture", "sorted", "spikes"}) {
    cases.push_back({std::string(a) + "_alpha_0_005_2", "surface build --assembly " + std::string(a) +
                                                            " --alpha 0.005,2 --res 256 --out s.exr",
                     2, "alpha (0.005, 2): anisotropy 1:400 cannot meet the NDF check at any resolution: use max/min "
                        "alpha <= 4, e.g. alpha (0.5, 2)"});
  }
  cases.push_back({"smith_alpha_2_0_1", "surface build --assembly smith --alpha 2,0.1 --res 1024 --out s.exr", 2,
                   "alpha (2, 0.1): anisotropy 1:20 cannot meet the NDF check at any resolution: use max/min alpha <= "
                   "4, e.g. alpha (2, 0.5)"});
  // Correlation lengths whose grid bias or few patches miss the check.
  cases.push_back({"smith_corr2_res512", "surface build --assembly smith --alpha 0.5 --res 512 --corr-cells 2 --out s.exr",
                   2, "correlation length 2 cells at resolution 512 cannot meet the NDF check: use 4..32 cells"});
  cases.push_back({"beckmann_corr3_res1024",
                   "surface build --assembly beckmann --alpha 0.5 --res 1024 --corr-cells 3 --out s.exr", 2,
                   "correlation length 3 cells at resolution 1024 cannot meet the NDF check: use 8..128 cells"});
  cases.push_back({"sorted_corr32_res256",
                   "surface build --assembly sorted --alpha 0.5 --res 256 --corr-cells 32 --out s.exr", 2,
                   "correlation length 32 cells at resolution 256 cannot meet the NDF check for sorted: use 4..16"});
  // Defect 9: the traced quadric beyond its verified 1:1000 (the message names the pair).
  cases.push_back({"trace_quadric_1em4_1", "trace vndf --alpha 1e-4,1 --theta 60 --rays 1000 --out h.exr --json h.json",
                   2, "0.0001"});
  cases.push_back({"validate_against_quadric_1em4_1",
                   "validate --sampler heitz2018 --alpha 1e-4,1 --theta 60 --samples 200000 --against ellipsoid --json v.json",
                   2, "0.0001"});
  return cases;
}

class RangeBadInput : public ::testing::TestWithParam<BadInputCase> {};

TEST_P(RangeBadInput, RefusedBeforeAnyWork) { microsim::test::expect_bad_input(GetParam(), "ranges"); }

INSTANTIATE_TEST_SUITE_P(Ranges, RangeBadInput, ::testing::ValuesIn(range_cases()),
                         [](const auto& info) { return info.param.name; });

// The edges of the supported range work: the smallest allowed resolution (256 for the GGX assemblies, 16
// for beckmann) at the largest allowed anisotropy, both orientations, and the smallest allowed
// correlation length at 512, build and meet their own NDF check through the command line (fixed seed 1;
// the library test below covers 3 seeds).
TEST(RangeEdges, SmallestAllowedBuildsPassTheirNdfCheck) {
  const auto dir = microsim::test::scratch_dir("ranges", "edges");
  const std::vector<std::string> builds = {
      "--assembly smith --alpha 0.5,2 --res 256",      "--assembly mixture --alpha 2,0.5 --res 256",
      "--assembly sorted --alpha 0.5 --res 256",       "--assembly spikes --alpha 0.5,2 --res 256",
      "--assembly beckmann --alpha 0.5,2 --res 16",    "--assembly smith --alpha 0.5 --res 512 --corr-cells 4",
      "--assembly beckmann --alpha 0.005 --res 32",    "--assembly smith --alpha 2 --res 256 --corr-cells 4"};
  for (const std::string& b : builds) {
    const auto r = microsim::test::run_cli(dir, "surface build --quiet " + b + " --seed 1 --out s.exr");
    EXPECT_EQ(r.exit_code, 0) << b << "\n" << r.err;
    EXPECT_NE(r.out.find("NDF verdict: ok"), std::string::npos) << b;
    EXPECT_TRUE(std::filesystem::exists(dir / "s.exr")) << b;
    std::filesystem::remove(dir / "s.exr");
  }
  // --unsupported builds outside the range; the NDF check still decides (here: it fails, nothing written).
  const auto r = microsim::test::run_cli(dir, "surface build --quiet --assembly smith --alpha 0.5 --res 64 "
                                              "--unsupported --out s.exr");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("misses its ggx NDF"), std::string::npos) << r.err;
  EXPECT_EQ(microsim::test::file_count(dir), 0u);
  std::filesystem::remove_all(dir);
}

// The library rule (microgeom::check_supported_range) at its edges, over 3 seeds: every assembly at the
// smallest allowed resolution with the largest allowed anisotropy meets its NDF check; one step outside
// is refused with a typed error.
TEST(RangeEdges, LibraryRuleEdgesMeetTheNdfCheckOverSeeds) {
  using namespace microgeom;
  for (const AssemblyInfo& info : assembly_registry()) {
    for (std::uint64_t seed : {1u, 2u, 3u}) {
      AssemblyParams p;
      p.assembly = info.name;
      p.resolution = info.reference == NdfKind::ggx ? kMinGgxCheckedResolution : 16;
      p.alpha_x = 0.5;
      p.alpha_y = 0.5 * kMaxCheckedAnisotropy;
      p.seed = seed;
      ASSERT_NO_THROW(check_supported_range(p)) << info.name;
      const Heightfield f = build_assembly(p);
      StatsOptions so;
      so.reference = info.reference;
      so.alpha_x = p.alpha_x;
      so.alpha_y = p.alpha_y;
      so.tolerance = tolerance_for(info.reference, p.resolution, default_corr_cells(p.resolution));
      const SurfaceStats st = measure_surface(f, so);
      EXPECT_TRUE(st.ndf_within_tolerance) << info.name << " seed " << seed << ": " << st.ndf_verdict;
    }
    AssemblyParams outside;
    outside.assembly = info.name;
    outside.resolution = info.reference == NdfKind::ggx ? kMinGgxCheckedResolution / 2 : 16;
    outside.alpha_x = 0.5;
    outside.alpha_y = info.reference == NdfKind::ggx ? 0.5 : 0.5 * kMaxCheckedAnisotropy * 1.01;
    EXPECT_THROW(check_supported_range(outside), OutsideSupportedRange) << info.name;
  }
  AssemblyParams l2;
  l2.resolution = 512;
  l2.corr_cells = 2;
  EXPECT_THROW(check_supported_range(l2), OutsideSupportedRange);
  l2.corr_cells = min_checked_corr_cells(512);
  EXPECT_NO_THROW(check_supported_range(l2));
}

}  // namespace

}  // namespace test_bad_inputs_ranges
