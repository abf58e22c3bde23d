// The Smith walk with paths in SIMD lanes (WalkKernel::lanes, scatter/smith_walk_lanes.h) against the scalar
// walk (the reference), statistically: the two draw other random numbers, so they agree in distribution, not
// bit for bit. Fixed seeds; the level is 1% family-wise (Sidak over every p-value of the test); the negative
// control (the lanes walk on a surface of alpha 0.55 against the scalar walk at 0.5) is rejected by the same
// checks at a level below 1e-6.
// Per configuration and channel: the per-order albedos (orders 1, 2, 3, 4, 5+; reflected and transmitted) and
// the weight left at the order cap, each as a z-score of the difference over its standard error, summed in squares (chi-square with
// that many degrees of freedom); and the directions of orders 1, 2 and of every order, by the weighted
// homogeneity test (stats/chi2.h, Gagunashvili 2010: the same distribution over the bins).
// The kernel's sincos of 2 pi u equals cos and sin in long double to 3e-16. The exits' batch binning
// (walk_lanes::bin_escaped) equals DirectionBinning::bin_of on random directions and
// on directions at and around every row and column edge (offsets from 0 to 1e-3 bin widths).
// Also: the lanes kernel gives the same histogram for any thread count and shards, names itself in the
// measurement string, and refuses what it does not cover; every SIMD target the CPU runs agrees with the
// scalar walk.
#include "scatter/smith_walk.h"

#include "scatter/smith_walk_lanes.h"
#include "stats/binning.h"
#include "stats/chi2.h"
#include "stats/direction_binner.h"

#include <boost/math/distributions/chi_squared.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace microsim {
namespace walk_lanes_test {  // named: the unity build puts this file beside others with the same helpers

const Material kGold = Material::conductor({{0.18, 3.4}, {0.42, 2.35}, {1.37, 1.77}});

ScatterOptions options(const Vec3<double>& wi, const Material& m, std::uint64_t paths, std::uint64_t seed, int max_order = 100) {
  ScatterOptions o;
  o.wi = wi;
  o.material = m;
  o.paths = paths;
  o.seed = seed;
  o.rows = 8;
  o.max_order = max_order;
  return o;
}

// The p-value of z^2 summed over the per-order albedos and the unfinished weight of every channel.
double albedo_p(const ScatterHistogram& a, const ScatterHistogram& b) {
  double stat = 0;
  int dof = 0;
  auto add = [&](Estimate x, Estimate y) {
    const double se2 = x.standard_error * x.standard_error + y.standard_error * y.standard_error;
    if (se2 > 0) {
      stat += (x.value - y.value) * (x.value - y.value) / se2;
      ++dof;
    } else if (x.value != y.value) {
      stat += 1e300;
    }
  };
  for (int c = 0; c < a.channels(); ++c) {
    for (int k = 0; k < kScatterOrderBins; ++k) {
      for (const ScatterSide side : {ScatterSide::reflected, ScatterSide::transmitted}) add(a.albedo(c, k, side), b.albedo(c, k, side));
    }
    add(a.unfinished(c), b.unfinished(c));
  }
  if (dof == 0) return stat > 0 ? 0.0 : 1.0;
  return boost::math::cdf(boost::math::complement(boost::math::chi_squared(dof), stat));
}

// The weighted homogeneity p-value of the directions of the orders [first, last] of channel c.
double directions_p(const ScatterHistogram& a, const ScatterHistogram& b, int c, int first, int last) {
  std::vector<double> wa(a.bins(), 0.0), sa(a.bins(), 0.0), wb(b.bins(), 0.0), sb(b.bins(), 0.0);
  for (int k = first; k <= last; ++k) {
    for (std::size_t i = 0; i < a.bins(); ++i) {
      wa[i] += a.histogram(c, k).weight(i);
      sa[i] += a.histogram(c, k).weight_squared(i);
      wb[i] += b.histogram(c, k).weight(i);
      sb[i] += b.histogram(c, k).weight_squared(i);
    }
  }
  return weighted_homogeneity(wa, sa, wb, sb).p_value;
}

// Every p-value comparing the lanes walk on `lanes_surface` with the scalar walk on `surface`.
std::vector<double> agreement_p_values(const SmithMicrosurface& surface, const SmithMicrosurface& lanes_surface,
                                       const ScatterOptions& o) {
  ScatterOptions other = o;
  other.seed = o.seed + 1000;
  const ScatterHistogram scalar = smith_walk_scatter(surface, o, WalkKernel::scalar);
  const ScatterHistogram lanes = smith_walk_scatter(lanes_surface, other, WalkKernel::lanes);
  std::vector<double> p{albedo_p(scalar, lanes)};
  for (int c = 0; c < o.material.channels(); ++c) {
    p.push_back(directions_p(scalar, lanes, c, 0, 0));
    p.push_back(directions_p(scalar, lanes, c, 1, 1));
    p.push_back(directions_p(scalar, lanes, c, 0, kScatterOrderBins - 1));
  }
  return p;
}

struct Case {
  SmithMicrosurface surface;
  Material material;
  double theta, phi;
  int max_order = 100;
};

const std::vector<Case>& cases() {
  static const std::vector<Case> c{
      {{NdfKind::ggx, 0.5, 0.5}, Material::mirror(), 60, 0},
      {{NdfKind::ggx, 0.1, 0.1}, Material::mirror(), 85, 20},
      {{NdfKind::ggx, 1.5, 1.5}, Material::mirror(), 20, 0, 3},
      {{NdfKind::ggx, 0.3, 1.0}, kGold, 70, 35},
      {{NdfKind::ggx, 2.0, 0.6}, kGold, 0.5, 0},
      {{NdfKind::ggx, 0.5, 0.5}, Material::dielectric(1.5), 60, 0},
      {{NdfKind::ggx, 0.8, 0.3}, Material::dielectric(1.5), 130, 40},
      {{NdfKind::ggx, 0.2, 0.2}, Material::dielectric(1.1), 95, 0, 4},
  };
  return c;
}

TEST(SmithWalkLanes, AgreesWithTheScalarWalkStatistically) {
  std::vector<double> all;
  std::vector<std::string> names;
  for (const Case& c : cases()) {
    const ScatterOptions o = options(direction_from_degrees(c.theta, c.phi), c.material, 100000, 7, c.max_order);
    for (double p : agreement_p_values(c.surface, c.surface, o)) {
      all.push_back(p);
      names.push_back(describe(c.surface) + " " + c.material.describe() + " theta " + std::to_string(c.theta));
    }
  }
  const double level = sidak_significance(0.01, int(all.size()));
  for (std::size_t i = 0; i < all.size(); ++i) EXPECT_GE(all[i], level) << names[i];
}

// Every SIMD target this CPU runs (the lanes kernel dispatches as the binner does: Highway's choice is global),
// on a mirror and a dielectric, at the same family-wise level.
TEST(SmithWalkLanes, EveryTargetAgreesWithTheScalarWalk) {
  std::vector<double> all;
  std::vector<std::string> names;
  for (const std::string& target : direction_binner_targets()) {
    use_direction_binner_target(target);
    for (const std::size_t i : {std::size_t(0), std::size_t(5)}) {
      const Case& c = cases()[i];
      const ScatterOptions o = options(direction_from_degrees(c.theta, c.phi), c.material, 50000, 17, c.max_order);
      for (double p : agreement_p_values(c.surface, c.surface, o)) {
        all.push_back(p);
        names.push_back(target + " " + c.material.describe() + " " + smith_walk_lanes_target());
      }
    }
  }
  use_direction_binner_target("");
  const double level = sidak_significance(0.01, int(all.size()));
  for (std::size_t i = 0; i < all.size(); ++i) EXPECT_GE(all[i], level) << names[i];
}

TEST(SmithWalkLanes, NegativeControlAWrongAlphaIsRejected) {
  const ScatterOptions o = options(direction_from_degrees(60.0, 0.0), Material::mirror(), 100000, 7);
  const std::vector<double> p =
      agreement_p_values({NdfKind::ggx, 0.5, 0.5}, {NdfKind::ggx, 0.55, 0.55}, o);
  EXPECT_LT(*std::min_element(p.begin(), p.end()), 1e-6);
}

TEST(SmithWalkLanes, ThreadsAndShardsDoNotChangeTheResult) {
  const SmithMicrosurface s{NdfKind::ggx, 0.4, 0.7};
  for (const auto& [wi, material] : {std::pair{direction_from_degrees(50.0, 10.0), kGold},
                                     std::pair{direction_from_degrees(130.0, 10.0), Material::dielectric(1.5)}}) {
    ScatterOptions o = options(wi, material, 5 * kPathsPerBlock + 17, 3);
    o.run.threads = 1;
    const ScatterHistogram one = smith_walk_scatter(s, o, WalkKernel::lanes);
    o.run.threads = 2;
    EXPECT_TRUE(smith_walk_scatter(s, o, WalkKernel::lanes) == one) << material.describe();
    ScatterOptions first = o, second = o;
    first.blocks = BlockRange{0, 2};
    second.blocks = BlockRange{2, 6};
    ScatterHistogram merged = smith_walk_scatter(s, first, WalkKernel::lanes);
    merged.merge(smith_walk_scatter(s, second, WalkKernel::lanes));
    merged.provenance.blocks = one.provenance.blocks;
    EXPECT_TRUE(merged == one) << material.describe();
    // Negative control: another seed is another run.
    o.seed = 4;
    EXPECT_FALSE(smith_walk_scatter(s, o, WalkKernel::lanes) == one) << material.describe();
    EXPECT_NE(one.provenance.measurement.find("kernel=lanes"), std::string::npos);
    EXPECT_EQ(smith_walk_scatter(s, o, WalkKernel::scalar).provenance.measurement.find("kernel="), std::string::npos);
  }
}

TEST(SmithWalkLanes, BatchBinningOfTheExitsIsBinOf) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> normal;
  for (const int rows : {1, 4, 8, 16, 250}) {
    const DirectionBinning b = DirectionBinning::hemispheres(rows);
    const FastDirectionBinner fast(b);
    std::vector<walk_lanes::LaneEnd> ends;
    auto add = [&](const Vec3<double>& w, int kind = 0) { ends.push_back({kind, 1, w.x(), w.y(), w.z()}); };
    for (int i = 0; i < 20000; ++i) add(Vec3<double>(normal(rng), normal(rng), normal(rng)).normalized(), i % 50 == 0 ? 1 : 0);
    const double dz = (b.z_max() - b.z_min()) / b.rows(), dphi = 2 * kPi<double> / b.cols();
    auto add_param = [&](double z, double phi) {
      const double zz = std::clamp(z, -1.0, 1.0), r = std::sqrt(1 - zz * zz);
      add(Vec3<double>(r * std::cos(phi), r * std::sin(phi), zz));
    };
    for (const double offset : {0.0, 1e-15, -1e-15, 1e-9, -1e-9, 1e-7, -1e-7, 1e-6, -1e-6, 1e-5, -1e-5, 1e-3, -1e-3}) {
      for (int k = 0; k <= b.rows(); ++k) add_param(b.z_max() - (k + offset) * dz, 0.3 + offset);
      for (int j = 0; j < b.cols(); ++j) add_param(0.37 - 0.2 * (j % 5), (j + offset) * dphi);
    }
    std::vector<int> bins(ends.size());
    walk_lanes::bin_escaped(fast, ends.data(), int(ends.size()), bins.data());
    for (std::size_t i = 0; i < ends.size(); ++i) {
      const Vec3<double> w(ends[i].x, ends[i].y, ends[i].z);
      ASSERT_EQ(bins[i], ends[i].kind == 0 ? b.bin_of(w).value_or(-1) : -1) << "rows " << rows << " w " << w.transpose();
    }
  }
}

TEST(SmithWalkLanes, SinCosOfTwoPiUAreExactToRounding) {
  std::mt19937_64 rng(3);
  std::vector<double> u;
  for (int i = 0; i < 100000; ++i) u.push_back(double(rng() >> 11) * 0x1.0p-53);
  for (int k = 0; k < 8; ++k) {
    for (const double e : {0.0, 0x1.0p-53, -0x1.0p-53, 1e-9, -1e-9}) u.push_back(std::clamp(k / 8.0 + e, 0.0, 1 - 0x1.0p-53));
  }
  std::vector<double> c(u.size()), s(u.size());
  const std::size_t done = walk_lanes::sincos_two_pi(u.data(), u.size(), c.data(), s.data());
  ASSERT_GT(done, u.size() - 64);
  for (std::size_t i = 0; i < done; ++i) {
    // In long double: 2 pi u rounded to double would itself be off by up to 4.4e-16.
    const long double phi = 2 * 3.141592653589793238462643383279503L * (long double)u[i];
    ASSERT_NEAR(c[i], double(std::cos(phi)), 3e-16) << "u " << u[i];
    ASSERT_NEAR(s[i], double(std::sin(phi)), 3e-16) << "u " << u[i];
  }
}

TEST(SmithWalkLanes, RefusesWhatItDoesNotCover) {
  const ScatterOptions mirror = options(direction_from_degrees(30.0, 0.0), Material::mirror(), 100, 1);
  const ScatterOptions glass = options(direction_from_degrees(150.0, 0.0), Material::dielectric(1.5), 100, 1);
  const ScatterOptions white = options(direction_from_degrees(30.0, 0.0), Material::lambertian(0.8), 100, 1);
  const SmithMicrosurface ggx{NdfKind::ggx, 0.5, 0.5};
  EXPECT_TRUE(smith_walk_lanes_support(ggx, mirror));
  EXPECT_TRUE(smith_walk_lanes_support(ggx, glass));
  EXPECT_FALSE(smith_walk_lanes_support(ggx, white));
  EXPECT_THROW(smith_walk_scatter(ggx, white, WalkKernel::lanes), std::invalid_argument);
  EXPECT_THROW(smith_walk_scatter(ggx, options(direction_from_degrees(150.0, 0.0), Material::mirror(), 100, 1), WalkKernel::lanes),
               std::invalid_argument);
  EXPECT_THROW(smith_walk_scatter({NdfKind::beckmann, 0.5, 0.5}, mirror, WalkKernel::lanes), std::invalid_argument);
  EXPECT_THROW(smith_walk_scatter({NdfKind::ggx, 0.5, 0.5, HeightDistribution::gaussian}, mirror, WalkKernel::lanes),
               std::invalid_argument);
}

}  // namespace walk_lanes_test
}  // namespace microsim
