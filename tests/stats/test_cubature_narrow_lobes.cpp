// Mass the sphere cubature's rule never sees: a lobe narrow around a pole lies in a corner of every cell of
// the end rows, and a strip 1e-4 wide along a bin's edge lies between the rule's outermost nodes and the
// edge. Both made correct VNDF samplers fail at extreme anisotropy and grazing views (samples in bins of
// expected probability 0). A cell whose rule saw nothing where the pdf is positive at a focus point or just
// inside its edges is now split (cubature.cpp, BinCubature::blind). Fixed seeds; level 0.01.
#include "stats/binning.h"
#include "microfacet/samplers_impl.h"
#include "validate/validate.h"

#include <gtest/gtest.h>

#include <cmath>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_cubature_narrow_lobes {

using namespace microsim;

namespace {

const SamplerInfo& sampler(const char* name) {
  const SamplerInfo* s = find_sampler(name);
  if (!s) throw std::runtime_error(name);
  return *s;
}

// The sphere-bin cubature of the visible normals as prepare_reference (validate.cpp) runs it.
double sphere_total_of_visible_normals(const GGX<double>& ggx, const Vec3<double>& wi) {
  auto pdf = [ggx, wi](const Vec3<double>& m) { return ggx.visible_normal_pdf(wi, m); };
  const auto lobe = DirectionBinning::lobe(ggx, wi, SampleDomain::microfacet_normal, 31);
  IntegrationOptions o;
  o.focus = lobe.lattice_directions(4096);
  o.z_breaks = {0.0};
  o.second_pass_total_error = 1e-5;
  o.second_pass_focus = lobe.visible_edge_directions(192, 64);
  return DirectionBinning::sphere(31).integrate(pdf, o).total;
}

}  // namespace

TEST(CubatureNarrowLobes, VisibleNormalsNearThePoleAreFound) {
  // alpha (1e-4, 0.1) seen at 89.99 deg: 8e-4 of the visible normals lie within 2e-3 rad of the pole, in
  // every top-row cell, inside the rule's first Kronrod node (theta 1.5e-3), where the rule sees only
  // invisible normals (density 0) and no focus point lies. Without the blind-cell split: 0.99923.
  const double total = sphere_total_of_visible_normals(GGX<double>(1e-4, 0.1), direction_from_degrees(89.99, 0.0));
  EXPECT_NEAR(total, 1.0, 1e-6);
}

TEST(CubatureNarrowLobes, VisibleNormalsAlongABinEdgeAreFound) {
  // alpha (0.1, 1e-4) seen at 89.99 deg along y: the visible strip is about 1e-4 wide along phi = 0, a bin
  // edge; in the last column it lies between the edge and the rule's outermost nodes (4.3e-4 away), where
  // the only focus points are invisible normals. Without the blind-cell split: 0.99942.
  const double total = sphere_total_of_visible_normals(GGX<double>(0.1, 1e-4), direction_from_degrees(89.99, 90.0));
  EXPECT_NEAR(total, 1.0, 1e-6);
}

// Anisotropy 1000:1 seen at 89.99 deg, both orientations: the cap at the pole (alpha (1e-4, 0.1): 8e-4 of
// the visible normals within 2e-3 rad of it) and the strip along phi = 0 (alpha (0.1, 1e-4) seen along y:
// the visible half of the strip, 1e-4 wide, lies in the last column).
TEST(CubatureNarrowLobes, ExtremeAnisotropyAtGrazingViewsPassesAndTheNegativeControlIsRejected) {
  struct Case {
    GGX<double> ggx;
    double phi;
  };
  for (const Case& c : {Case{GGX<double>(1e-4, 0.1), 0.0}, Case{GGX<double>(0.1, 1e-4), 90.0}}) {
    const Vec3<double> wi = direction_from_degrees(89.99, c.phi).normalized();
    const auto ref = claimed_reference(sampler("heitz2018"), c.ggx, wi, 31);
    EXPECT_LT(std::abs(1 - ref->sphere_probability.total), 2e-6) << ref->sphere_probability.total;
    ValidationOptions o;  // 1e6 samples, double, level 0.01
    for (std::uint64_t seed : {1, 2}) {
      o.seed = seed;
      const ValidationReport r = validate_sampler(sampler("heitz2018"), c.ggx, wi, o, ref);
      EXPECT_TRUE(r.passed) << "phi " << c.phi << " seed " << seed << ": sphere p " << r.chi2("sphere").p_value;
    }
    o.seed = 1;
    EXPECT_FALSE(validate_sampler(sampler("heitz2018-talk"), c.ggx, wi, o).passed) << "phi " << c.phi;
  }
}

}  // namespace test_cubature_narrow_lobes
