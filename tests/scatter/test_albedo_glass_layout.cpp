// A rough dielectric's table over Cycles' index axis (scatter/albedo_glass_layout.h): the registry and the
// index parametrisation both ways (the generator's ior_from_F0(t^4), the reader's z = sqrt(|ior - 1| /
// (ior + 1))); a small table of the same code path written in Cycles' text form, read back the way Cycles
// stores it (data[z][y][x], a blank line between z slices) and three nodes checked against an independent
// quadrature over outgoing directions of Walter et al. 2007's BSDF (eq. 20-22, the height-correlated G2 of
// Heitz 2014 eq. 99 for both lobes, as Cycles evaluates it), written here; and two limits with closed forms:
// at ior -> 1 (Cycles' first index node) the refraction does not bend, so E_T = E[G2 / G1] = (1 + Lambda) /
// (1 + 2 Lambda) and E_R = 0, from both sides; on a near-smooth surface at normal incidence E_R = F0 = t^4.
// The published tables read back the same way, three nodes of each against the independent quadrature.
// The grade of such a table (scatter/albedo_glass_grade.h) on the small grid: the table as Cycles stores it
// (6 decimals), read back from the text Cycles prints and from the CSV microsim writes, passes and is within
// its rounding; one node moved by 1e-3 is flagged (the negative control); a table with the noise of N samples
// of weights in [0, 1] is within the noise of N and beyond that of 100 N; malformed files are refused.
//
// The Smith walk's reflected / transmitted split on Cycles' rough-glass nodes (scatter/albedo_glass_walk.h).
// Order 1 of the walk (Heitz et al. 2016) is single scattering with the Smith microsurface's own masking: at
// nodes of both layouts its E1_R and E1_T agree with the analytic single scattering of that masking
// (single_scattering_albedo, RefractionMasking::smith_microsurface, as `albedo --model analytic --material
// dielectric:ETA`) within 4 standard errors plus the quadrature's estimate (two-sided level 6e-5 per check).
// Negative control: Cycles' own masking (the reflection form for both lobes, RefractionMasking::height_correlated)
// is more than 4 standard errors from the walk's E1_T at some node, so the comparison would see the wrong model.
// Every node of a small layout (4 x 4 x 4, the same code path) loses nothing: E + unfinished = 1, E_R + E_T = E,
// E1_R + E1_T = E1 <= E; its node is glass_walk_node's bit for bit, whatever the thread count.
#include "scatter/albedo_glass_grade.h"
#include "scatter/albedo_glass_layout.h"
#include "scatter/albedo_glass_walk.h"
#include "scatter/albedo_table.h"

#include "microfacet/ggx.h"
#include "microfacet/material.h"

#include <boost/math/quadrature/gauss.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace microsim {
namespace {

TEST(AlbedoGlassLayout, TheRegistryHoldsCyclesGlassTablesAndTheirIndexAxis) {
  ASSERT_EQ(glass_layout_names(), "cycles-glass, cycles-glass-inv");
  const GlassLayout* g = find_glass_layout("cycles-glass");
  const GlassLayout* inv = find_glass_layout("cycles-glass-inv");
  ASSERT_TRUE(g && inv);
  EXPECT_EQ(find_glass_layout("cycles"), nullptr);
  EXPECT_FALSE(g->inverse);
  EXPECT_TRUE(inv->inverse);
  EXPECT_EQ(g->quantity, "ggx_glass_E");
  EXPECT_EQ(inv->quantity, "ggx_glass_inv_E");
  EXPECT_EQ(g->roughness_nodes * g->mu_nodes * g->index_nodes, 4096);
  EXPECT_DOUBLE_EQ(glass_layout_index_coordinate(0, 16), 1e-4);
  EXPECT_DOUBLE_EQ(glass_layout_index_coordinate(15, 16), 0.99);  // the reader puts node 15 at 1
  EXPECT_NEAR(glass_layout_ior(glass_layout_index_coordinate(15, 16)), 99.50251256, 1e-6);
  EXPECT_DOUBLE_EQ(glass_layout_coordinate(0, 16), 1e-4);
  for (int k = 1; k < 15; ++k) {  // the reader's z of the generator's ior is the node's coordinate
    const double ior = glass_layout_ior(glass_layout_index_coordinate(k, 16));
    EXPECT_NEAR(std::sqrt(std::abs(ior - 1) / (ior + 1)), k / 15.0, 1e-12) << k;
    EXPECT_NEAR(std::pow((ior - 1) / (ior + 1), 2), std::pow(k / 15.0, 4), 1e-12) << "F0 = t^4";
  }
  EXPECT_NEAR(glass_layout_ior(5 / 15.0), 1.25, 1e-12);
}

// ---- the independent quadrature -----------------------------------------------------------------------------

struct Lobes {
  double reflected = 0, transmitted = 0;
};

// Walter et al. 2007 eq. 22, relative index eta = n_transmitted / n_incident, c = |wi.h|.
double fresnel(double c, double eta) {
  const double g2 = eta * eta - 1 + c * c;
  if (g2 <= 0) return 1;
  const double g = std::sqrt(g2), a = (g - c) / (g + c), b = (c * (g + c) - 1) / (c * (g - c) + 1);
  return 0.5 * a * a * (1 + b * b);
}

// E_R and E_T of light arriving at mu on a GGX dielectric, eta the relative index of the far side, as
// integrals over the facet normal h (not the visible-normal square the library integrates over): with
// wo = reflect or refract(wi, h), f |cos o| dwo = F_or_(1 - F) |wi.h| D(h) G2(wi, wo) / mu dh (Walter eq. 20
// and 21 with their Jacobians eq. 14 and 17), G2 = 1 / (1 + Lambda(wi) + Lambda(wo)); tensor Gauss-Legendre
// in (theta_h, phi_h), phi over [0, pi] doubled. Its error: up to 3e-6 where total internal reflection cuts
// the integrand (light from inside; against the same rule on 300 points and 40 pieces), else below 1e-8.
Lobes independent_glass(double alpha, double mu, double eta) {
  const double a2 = alpha * alpha, si = std::sqrt(1 - mu * mu);
  const auto lambda = [&](double c) { return (-1 + std::sqrt(1 + a2 * (1 - c * c) / (c * c))) / 2; };
  const auto lobes = [&](double theta, double phi) {
    const double hx = std::sin(theta) * std::cos(phi), hz = std::cos(theta);  // wi has no y: h.y drops out
    const double c = si * hx + mu * hz, t2 = std::pow(std::tan(theta), 2);
    Lobes l;
    if (!(c > 0)) return l;
    const double d = 1 / (std::numbers::pi * a2 * std::pow(hz, 4) * std::pow(1 + t2 / a2, 2));
    const double f = fresnel(c, eta), common = c * d / mu * std::sin(theta);
    const double rz = 2 * c * hz - mu;  // the reflection's z
    if (rz > 0) l.reflected = f * common / (1 + lambda(mu) + lambda(rz));
    const double ct2 = 1 - (1 - c * c) / (eta * eta);
    if (ct2 <= 0) return l;  // total internal reflection
    const double tz = -mu / eta + (c / eta - std::sqrt(ct2)) * hz;  // the refraction's z
    if (tz < 0) l.transmitted = (1 - f) * common / (1 + lambda(mu) + lambda(-tz));
    return l;
  };
  using Rule = boost::math::quadrature::gauss<double, 99>;  // odd: its first abscissa is 0
  Lobes r;
  const int pieces = 12;
  for (int i = 0; i < pieces; ++i)
    for (int j = 0; j < pieces; ++j) {
      const double t0 = std::numbers::pi / 2 * i / pieces, t1 = std::numbers::pi / 2 * (i + 1) / pieces;
      const double p0 = std::numbers::pi * j / pieces, p1 = std::numbers::pi * (j + 1) / pieces;
      for (std::size_t a = 0; a < Rule::abscissa().size(); ++a)
        for (int sa : {1, -1}) {
          if (a == 0 && sa < 0) continue;  // an odd rule's middle node once
          const double t = (t0 + t1) / 2 + sa * (t1 - t0) / 2 * Rule::abscissa()[a];
          const double wt = (t1 - t0) / 2 * Rule::weights()[a];
          for (std::size_t b = 0; b < Rule::abscissa().size(); ++b)
            for (int sb : {1, -1}) {
              if (b == 0 && sb < 0) continue;
              const double p = (p0 + p1) / 2 + sb * (p1 - p0) / 2 * Rule::abscissa()[b];
              const Lobes l = lobes(t, p);
              const double w = 2 * wt * (p1 - p0) / 2 * Rule::weights()[b];
              r.reflected += w * l.reflected;
              r.transmitted += w * l.transmitted;
            }
        }
    }
  return r;
}

// ---- a small table of the layout's code path ----------------------------------------------------------------

GlassLayout small_glass(bool inverse) {
  GlassLayout l = *find_glass_layout(inverse ? "cycles-glass-inv" : "cycles-glass");
  l.roughness_nodes = 4;  // r = 1e-4, 1/3, 2/3, 1
  l.mu_nodes = 3;         // mu = 1e-4, 1/2, 1
  l.index_nodes = 3;      // t = 1e-4, 1/2, 0.99: ior 1 + 2e-8, 5/3, 99.5
  return l;
}

// Cycles' text: z slices separated by a blank line, each y rows of x comma-separated values.
std::vector<std::vector<std::vector<double>>> read_cycles_text(const std::string& text) {
  std::vector<std::vector<std::vector<double>>> slices(1);
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    if (line.empty()) {
      slices.emplace_back();
      continue;
    }
    std::vector<double> row;
    std::istringstream fields(line);
    for (std::string f; std::getline(fields, f, ',');) row.push_back(std::stod(f));
    slices.back().push_back(row);
  }
  return slices;
}

// E_T at ior 1: G2 / G1 with wo = -wi, (1 + Lambda) / (1 + 2 Lambda), Lambda of GGX (Heitz 2014 eq. 86).
double eta_one(double alpha, double mu) {
  const double lambda = (-1 + std::sqrt(1 + alpha * alpha * (1 - mu * mu) / (mu * mu))) / 2;
  return (1 + lambda) / (1 + 2 * lambda);
}

TEST(AlbedoGlassLayout, TableReadAsCyclesReadsItMatchesAnIndependentQuadratureAndItsLimits) {
  for (const bool inverse : {false, true}) {
    const std::optional<GlassLayoutTable> t = glass_layout_table(small_glass(inverse), 1e-7, {}, false);
    ASSERT_TRUE(t.has_value());
    const auto table = read_cycles_text(glass_layout_encoded(*t));
    ASSERT_EQ(table.size(), 3u);
    for (const auto& slice : table) {
      ASSERT_EQ(slice.size(), 3u);
      for (const auto& row : slice) ASSERT_EQ(row.size(), 4u);
    }
    for (const auto& [x, y, z] : {std::array{2, 1, 1}, std::array{3, 1, 1}, std::array{3, 1, 2}}) {
      const double r = x / 3.0, mu = y / 2.0, tz = z == 2 ? 0.99 : z / 2.0;
      const double ior = (1 + tz * tz) / (1 - tz * tz);
      const Lobes e = independent_glass(r * r, mu, inverse ? 1 / ior : ior);
      EXPECT_NEAR(table[std::size_t(z)][std::size_t(y)][std::size_t(x)], e.reflected + e.transmitted, 5e-6)
          << x << " " << y << " " << z << (inverse ? " inside" : "");
      const SingleScatteringAlbedo& c = t->cells[t->index(std::size_t(x), std::size_t(y), std::size_t(z))];
      EXPECT_NEAR(c.reflected.value, e.reflected, 5e-6);
      EXPECT_NEAR(c.transmitted.value, e.transmitted, 5e-6);
    }
    for (std::size_t x = 1; x < 4; ++x)
      for (std::size_t y = 1; y < 3; ++y) {  // ior 1 + 2e-8, 1 in Cycles' floats: no reflection, no bending
        const SingleScatteringAlbedo& c = t->cells[t->index(x, y, 0)];
        EXPECT_EQ(c.reflected.value, 0.0);
        EXPECT_NEAR(c.transmitted.value, eta_one(t->alphas[x], t->mus[y]), 1e-15) << x << " " << y;
        if (inverse || x + y != 4) continue;  // two views suffice
        // The quadrature just beside it, at ior 1.0001 from outside, tends to the same.
        const SingleScatteringAlbedo near = single_scattering_albedo(
            GGX<double>(t->alphas[x]), Material::dielectric(1.0001), 0, albedo_view(t->mus[y], false), 1e-8,
            RefractionMasking::height_correlated);
        EXPECT_LT(near.reflected.value, 1e-5);
        EXPECT_NEAR(near.transmitted.value, eta_one(t->alphas[x], t->mus[y]), 1e-4) << x << " " << y;
      }
    for (std::size_t z = 1; z < 3; ++z) {  // alpha 1e-4 at normal incidence: a smooth interface's Fresnel
      // F0 = t^4; from inside at ior 99.5 F rises from F0 to 1 within the critical angle 0.01 rad, so facets
      // tilted by ~1e-4 see F larger by ~(1e-4 / 0.01)^2 (1 - F0) = 4e-6.
      const double f0 = std::pow(t->index_coordinates[z], 4);
      EXPECT_NEAR(t->cells[t->index(0, 2, z)].reflected.value, f0, z == 2 && inverse ? 1e-5 : 1e-6) << z;
      EXPECT_NEAR(t->cells[t->index(0, 2, z)].total().value, 1, 1e-6) << z;
    }
  }
}

// The published tables (docs/data/layout-cycles-glass{,-inv}.txt, scripts/glass_tables.py) read as Cycles
// reads its own: 16 slices of 16 x 16, node (x, y, z) at r = x / 15, mu = y / 15, ior of t = z / 15.
TEST(AlbedoGlassLayout, PublishedTablesReadAsCyclesReadsThem) {
  const std::filesystem::path data = std::filesystem::path(MICROSIM_TEST_DATA) / ".." / ".." / "docs" / "data";
  for (const bool inverse : {false, true}) {
    std::ifstream in(data / (inverse ? "layout-cycles-glass-inv.txt" : "layout-cycles-glass.txt"));
    std::ostringstream text;
    text << in.rdbuf();
    const auto table = read_cycles_text(text.str());
    ASSERT_EQ(table.size(), 16u);
    for (const auto& slice : table) ASSERT_EQ(slice.size(), 16u);
    // The last two, light from inside below the critical angle (total internal reflection on most facets), are
    // nodes where Cycles' own shipped ggx_glass_inv_E differs (0.8589 and 0.6661; records/energy-tables.md).
    for (const auto& [x, y, z] : {std::array{10, 8, 5}, std::array{15, 12, 9}, std::array{6, 4, 12},
                                  std::array{8, 2, 8}, std::array{15, 2, 8}}) {
      const double r = x / 15.0, mu = y / 15.0, t = z / 15.0, ior = (1 + t * t) / (1 - t * t);
      const Lobes e = independent_glass(r * r, mu, inverse ? 1 / ior : ior);
      EXPECT_NEAR(table[std::size_t(z)][std::size_t(y)][std::size_t(x)], e.reflected + e.transmitted, 5e-6)
          << x << " " << y << " " << z << (inverse ? " inside" : "");
    }
  }
}

// ---- the grade of a glass table --------------------------------------------------------------------------------

const GlassLayoutTable& graded_reference(bool inverse) {
  static const GlassLayoutTable outside = *glass_layout_table(small_glass(false), 1e-5, {}, false);
  static const GlassLayoutTable inside = *glass_layout_table(small_glass(true), 1e-5, {}, false);
  return inverse ? inside : outside;
}

TEST(AlbedoGlassGrade, TheTableAsCyclesStoresItPassesAndOnePlantedNodeIsFlagged) {
  for (const bool inverse : {false, true}) {
    const GlassLayoutTable& t = graded_reference(inverse);
    const std::vector<double> text = glass_values_from_text(glass_layout_encoded(t), t.layout);
    const std::vector<double> csv = glass_values_from_csv(glass_layout_csv(t), t.layout);
    ASSERT_EQ(text.size(), 36u);
    for (std::size_t k = 0; k < text.size(); ++k) {
      EXPECT_NEAR(text[k], encode_glass_value(t.cells[k].total().value), 1e-7) << k;  // the text: 6 decimals of a float
      EXPECT_NEAR(csv[k], t.cells[k].total().value, 1e-11) << k;
    }
    const GlassGrade good = grade_glass_against(t, text, 5e-4);
    EXPECT_TRUE(good.passed()) << inverse;
    EXPECT_EQ(good.not_graded, 9u) << "r = 1e-4 (alpha 1e-8) is below the reference's alpha range";
    EXPECT_EQ(good.beyond_quantisation, 0u) << "a table in Cycles' 6 decimals is within its rounding";
    EXPECT_LT(good.max_abs, 6e-7);
    std::vector<double> planted = text;
    const std::size_t node = t.index(2, 1, 1);  // alpha 4/9, mu 1/2, ior 5/3 (inverse: 3/5)
    planted[node] += 1e-3;
    const GlassGrade bad = grade_glass_against(t, planted, 5e-4);
    EXPECT_FALSE(bad.passed());
    EXPECT_EQ(bad.failed, 1u);
    EXPECT_EQ(bad.worst, node);
    EXPECT_EQ(bad.cells[node].x, 2u);
    EXPECT_EQ(bad.cells[node].z, 1u);
    EXPECT_NEAR(bad.cells[node].ior, inverse ? 0.6 : 5.0 / 3, 1e-12);
    EXPECT_NEAR(bad.max_abs, 1e-3, 1e-6);
  }
}

// A table whose nodes carry the noise of N samples of weights in [0, 1] (a Bernoulli count of mean E: the
// largest variance a weight in [0, 1] of mean E can have) passes the noise check at N and fails it at 100 N.
TEST(AlbedoGlassGrade, ANoisyTableIsWithinItsStatedSampleCountsNoise) {
  const GlassLayoutTable& t = graded_reference(false);
  const std::uint64_t samples = 4096;
  std::mt19937_64 rng(3);
  std::vector<double> noisy;
  for (const SingleScatteringAlbedo& c : t.cells) {
    const double e = std::clamp(c.total().value, 0.0, 1.0);
    noisy.push_back(double(std::binomial_distribution<std::uint64_t>(samples, e)(rng)) / double(samples));
  }
  const GlassGrade g = grade_glass_against(t, noisy, 0.05, samples);
  EXPECT_TRUE(g.passed());
  EXPECT_EQ(g.beyond_noise, 0u) << "z " << g.noise_z;
  EXPECT_GT(g.beyond_quantisation, 10u);
  EXPECT_GT(grade_glass_against(t, noisy, 0.05, 100 * samples).beyond_noise, 5u);
}

TEST(AlbedoGlassGradeInput, RefusesWrongCountsMissingColumnsAndRepeatedNodes) {
  const GlassLayout l = small_glass(false);
  EXPECT_THROW(glass_values_from_text("0.5, 0.5\n", l), std::invalid_argument);
  EXPECT_THROW(glass_values_from_csv("x,y,E\n0,0,0.5\n", l), std::invalid_argument);
  EXPECT_THROW(glass_values_from_csv("x,y,z,E\n0,0,0,0.5\n0,0,0,0.5\n", l), std::invalid_argument);
  EXPECT_THROW(glass_values_from_csv("x,y,z,E\n0,0,0,0.5\n", l), std::invalid_argument) << "35 nodes missing";
  EXPECT_THROW(glass_values_from_text(std::string(36 * 5, ',') + "x", l), std::invalid_argument);
  EXPECT_THROW(read_glass_values("table.exr", l), std::invalid_argument);
  const GlassLayoutTable& t = graded_reference(false);
  std::vector<double> values(36, 0.5);
  EXPECT_NO_THROW(grade_glass_against(t, values, 1e-3));
  EXPECT_THROW(grade_glass_against(t, std::vector<double>(35, 0.5), 1e-3), std::invalid_argument);
  values[4] = std::nan("");
  EXPECT_THROW(grade_glass_against(t, values, 1e-3), std::invalid_argument);
  EXPECT_THROW(grade_glass_against(t, std::vector<double>(36, 0.5), 0.0), std::invalid_argument);
  EXPECT_NEAR(glass_grade_reference_tolerance(1e-3), layout_quantisation(LayoutEncoding::six_decimals, 0.5) / 10,
              1e-20);
}

TEST(AlbedoGlassWalk, OrderOneIsTheSmithMaskingsSingleScatteringNotCycles) {
  struct Node {
    const char* layout;
    std::size_t x, y, z;
  };
  double largest_cycles_z = 0;
  for (const Node& n : {Node{"cycles-glass", 10, 8, 5}, Node{"cycles-glass-inv", 12, 4, 8}, Node{"cycles-glass", 14, 3, 10}}) {
    GlassWalkRequest r;
    r.layout = *find_glass_layout(n.layout);
    r.paths = 100'000;
    r.seed = 11;
    r.walk_kernel = WalkKernel::lanes;
    const std::optional<GlassWalkNode> c = glass_walk_node(r, n.x, n.y, n.z);
    ASSERT_TRUE(c);
    const double rough = glass_layout_coordinate(int(n.x), 16), mu = glass_layout_coordinate(int(n.y), 16);
    const Material glass = Material::dielectric(glass_layout_ior(glass_layout_index_coordinate(int(n.z), 16)));
    const Vec3<double> wi = albedo_view(mu, r.layout.inverse);
    const GGX<double> ggx(rough * rough);
    const SingleScatteringAlbedo smith = single_scattering_albedo(ggx, glass, 0, wi, 1e-7);
    const Estimate &e1_r = (*c)[4], &e1_t = (*c)[5];
    EXPECT_NEAR(e1_r.value, smith.reflected.value, 4 * e1_r.standard_error + smith.reflected.standard_error) << n.layout;
    EXPECT_NEAR(e1_t.value, smith.transmitted.value, 4 * e1_t.standard_error + smith.transmitted.standard_error) << n.layout;
    EXPECT_NEAR((*c)[0].value + (*c)[6].value, 1.0, 1e-12);
    const SingleScatteringAlbedo cycles =
        single_scattering_albedo(ggx, glass, 0, wi, 1e-7, RefractionMasking::height_correlated);
    largest_cycles_z = std::max(largest_cycles_z, std::abs(cycles.transmitted.value - e1_t.value) / e1_t.standard_error);
  }
  EXPECT_GT(largest_cycles_z, 4.0) << "the negative control: Cycles' masking";
}

TEST(AlbedoGlassWalk, EveryNodeOfASmallLayoutLosesNothingAndIsItsNode) {
  GlassWalkRequest r;
  r.layout = *find_glass_layout("cycles-glass-inv");
  r.layout.roughness_nodes = r.layout.mu_nodes = r.layout.index_nodes = 4;
  r.paths = 500;
  r.seed = 3;
  r.walk_kernel = WalkKernel::lanes;
  r.run.threads = 1;
  const std::optional<GlassWalkTable> t = glass_walk_table(r);
  ASSERT_TRUE(t);
  ASSERT_EQ(t->cells.size(), 64u);
  for (const GlassWalkNode& c : t->cells) {
    EXPECT_NEAR(c[0].value + c[6].value, 1.0, 1e-12);
    EXPECT_NEAR(c[1].value + c[2].value, c[0].value, 1e-12);
    EXPECT_NEAR(c[4].value + c[5].value, c[3].value, 1e-12);
    EXPECT_LE(c[3].value, c[0].value + 1e-12);
  }
  r.run.threads = 2;
  const std::optional<GlassWalkNode> node = glass_walk_node(r, 2, 1, 3);
  ASSERT_TRUE(node);
  for (std::size_t q = 0; q < node->size(); ++q) EXPECT_EQ((*node)[q].value, t->cells[t->index(2, 1, 3)][q].value) << q;
  const std::string csv = glass_walk_csv(*t);
  EXPECT_NE(csv.find("x,y,z,roughness,alpha,mu,t,ior,E,E_se,E_R,E_R_se,E_T,E_T_se,E1,E1_se,E1_R,E1_R_se,E1_T,E1_T_se,"
                     "unfinished,unfinished_se\n"), std::string::npos);
  EXPECT_NE(csv.find("# masking: "), std::string::npos);
  r.paths = 0;
  EXPECT_THROW(glass_walk_table(r), std::invalid_argument);
  r.paths = 1;
  EXPECT_THROW(glass_walk_node(r, 4, 0, 0), std::invalid_argument);
}

}  // namespace
}  // namespace microsim
