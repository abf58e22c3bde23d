// Tests of the joint NDF matching (microgeom/ndf_match.h): the lobe bins agree with trace vndf's
// (stats/binning.h), their reference probabilities with the cubature of the analytic VNDF seen from the
// normal, and a `--ndf-match joint` tile meets the reference law bin by bin far below the noise of as many
// independent triangles, where the radial construction (the negative control) does not; reproducible
// whatever the thread count, with the radial law and the height-slope coupling kept.
#include "microgeom/assembly.h"
#include "microgeom/ndf_match.h"
#include "microgeom/surface_stats.h"
#include "stats/binning.h"

#include "core/random.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <numeric>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_ndf_match {

using namespace microgeom;

namespace {

AssemblyParams joint_params(const std::string& name, NdfMatch match, std::uint64_t seed = 1, double ax = 0.3,
                            double ay = 0.3) {
  AssemblyParams p;
  p.assembly = name;
  p.resolution = 256;
  p.alpha_x = ax;
  p.alpha_y = ay;
  p.seed = seed;
  p.ndf_match = match;
  return p;
}

SurfaceStats stats_of(const Heightfield& f, const AssemblyParams& p) {
  StatsOptions o;
  o.reference = find_assembly(p.assembly)->reference;
  o.alpha_x = p.alpha_x;
  o.alpha_y = p.alpha_y;
  o.tolerance = tolerance_for(o.reference, p.resolution, default_corr_cells(p.resolution));
  return measure_surface(f, o);
}

}  // namespace

TEST(NdfMatch, NamesRoundTrip) {
  for (const NdfMatch m : {NdfMatch::radial, NdfMatch::joint}) EXPECT_EQ(ndf_match_from_string(to_string(m)), m);
  EXPECT_FALSE(ndf_match_from_string("angular").has_value());
  EXPECT_FALSE(ndf_match_from_string("").has_value());
}

// The lobe bin of a normalised slope is the bin trace vndf puts the triangle's normal in.
TEST(NdfMatch, LobeBinsAreThoseOfTraceVndf) {
  const double ax = 0.2, ay = 0.5;
  const LobeNdfBins bins(kDefaultLobeRows);
  const auto binning = microsim::DirectionBinning::lobe(microsim::GGX<double>(ax, ay), {0, 0, 1},
                                                        microsim::SampleDomain::microfacet_normal, kDefaultLobeRows);
  ASSERT_EQ(bins.size(), binning.size());
  microsim::CounterRng rng(7, 0);
  int checked = 0;
  for (int k = 0; k < 20000; ++k) {
    const double r = std::tan(1.5 * rng.uniform()), phi = 6.283185307179586 * rng.uniform();
    const double ux = r * std::cos(phi), uy = r * std::sin(phi);
    const microsim::Vec3<double> m(-ux * ax, -uy * ay, 1.0);  // normal of slope (ux ax, uy ay)
    const auto b = binning.bin_of(m);
    ASSERT_TRUE(b.has_value());
    EXPECT_EQ(bins.bin_of(ux, uy), *b) << ux << " " << uy;
    ++checked;
  }
  EXPECT_EQ(checked, 20000);
}

// Seen from the normal, the reference probabilities of the lobe bins are the analytic VNDF's (GGX, the
// clamped cosine z / pi in the lobe parameter space), computed independently by the binning's cubature.
TEST(NdfMatch, LobeBinProbabilitiesMatchTheCubatureOfTheAnalyticVndf) {
  const int rows = 7;
  const microsim::GGX<double> ggx(0.3, 0.3);
  const auto binning = microsim::DirectionBinning::lobe(ggx, {0, 0, 1}, microsim::SampleDomain::microfacet_normal, rows);
  const std::vector<double> cubature = binning.integrate([&](const microsim::Vec3<double>& m) {
    return ggx.D(m) * std::max(0.0, m.z());  // the VNDF seen from +z: D(m) <m, z>
  });
  const std::vector<double> p = LobeNdfBins(rows).probabilities(NdfKind::ggx);
  ASSERT_EQ(p.size(), cubature.size());
  for (std::size_t b = 0; b < p.size(); ++b) EXPECT_NEAR(p[b], cubature[b], 1e-6) << b;
  EXPECT_NEAR(std::accumulate(p.begin(), p.end(), 0.0), 1.0, 1e-12);
  const std::vector<double> pb = LobeNdfBins(rows).probabilities(NdfKind::beckmann);
  EXPECT_NEAR(std::accumulate(pb.begin(), pb.end(), 0.0), 1.0, 1e-12);
  EXPECT_NEAR(reference_radius_partial_mean(NdfKind::ggx, INFINITY), std::acos(0.0), 1e-15);  // E[r] = pi/2
}

// A joint tile meets the lobe bins far below the noise of as many independent triangles (< 1/4 of it); the
// radial tile of the same seed (negative control) is above that noise. Both meet the NDF check, and the
// joint tile keeps the height-slope coupling near the radial one: Spearman(|h|, s) was measured larger by up
// to 0.067 at N = 256 (smith seed 1: 0.283 against 0.216) and by -0.004..+0.025 at N = 1024 (seeds 1-3), so
// the bound here is +0.08 (docs/reference/surfaces.md, section 8).
TEST(NdfMatch, JointTileMeetsTheLobeBinsWhereTheRadialOneDoesNot) {
  for (const char* name : {"smith", "beckmann", "sorted"}) {
    const AssemblyParams pj = joint_params(name, NdfMatch::joint), pr = joint_params(name, NdfMatch::radial);
    const SurfaceStats joint = stats_of(build_assembly(pj), pj), radial = stats_of(build_assembly(pr), pr);
    EXPECT_LT(joint.lobe.total_variation, 0.25 * joint.lobe.iid_noise_tv) << name;
    EXPECT_GT(radial.lobe.total_variation, radial.lobe.iid_noise_tv) << name;
    EXPECT_TRUE(joint.ndf_within_tolerance) << name << ": " << joint.ndf_verdict;
    EXPECT_LT(joint.max_angular_bin_error, 0.5 * radial.max_angular_bin_error) << name;
    EXPECT_LT(joint.spearman_extremity_slope, radial.spearman_extremity_slope + 0.08) << name;
  }
}

TEST(NdfMatch, JointTileIsAnisotropicAndSameBitsWhateverTheThreadCount) {
  const AssemblyParams p = joint_params("smith", NdfMatch::joint, 3, 0.2, 0.4);
  const Heightfield a = build_assembly(p);
  Heightfield b = a;
  {
    tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
    b = build_assembly(p);
  }
  EXPECT_EQ(a.heights(), b.heights());
  EXPECT_EQ(a.metadata.at("ndf_match"), "joint");
  // Anisotropic 1:2 at 256^2 the lobe TV was measured at 0.30 of the noise of independent triangles (1.35%
  // against 4.55%; the radial tile of that seed: 3.2x that noise), hence a bound of 0.5 here.
  const SurfaceStats st = stats_of(a, p);
  EXPECT_LT(st.lobe.total_variation, 0.5 * st.lobe.iid_noise_tv);
  const AssemblyParams pr = joint_params("smith", NdfMatch::radial, 3, 0.2, 0.4);
  EXPECT_GT(stats_of(build_assembly(pr), pr).lobe.total_variation, st.lobe.iid_noise_tv);  // negative control
  EXPECT_TRUE(st.ndf_within_tolerance) << st.ndf_verdict;
}

// The refinement never raises its discrepancy, and stops within its sweeps.
TEST(NdfMatch, RefinementLowersTheDiscrepancy) {
  BuildReport report;
  const AssemblyParams p = joint_params("smith", NdfMatch::joint, 2);
  build_assembly(p, &report);
  EXPECT_GT(report.refine_sweeps, 0);
  EXPECT_LE(report.refine_sweeps, NdfRefineOptions{}.max_sweeps);
  EXPECT_GT(report.refine_moves, 0u);
  EXPECT_LT(report.refine_objective_after, 0.1 * report.refine_objective_before);
}

}  // namespace test_ndf_match
