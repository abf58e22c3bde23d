// The anisotropic GGX mirror's E(mu, phi; alpha_x, alpha_y) and E_avg (scatter/albedo_anisotropic.h):
// alpha_x = alpha_y is the isotropic table (every phi the same, E_avg as the isotropic one and the published
// Kulla & Conty 2017 values at alpha 1: E(mu = 1) 0.307, E_avg 0.409); swapping the roughnesses is a rotation
// by pi / 2 (E(mu, phi; ax, ay) = E(mu, pi / 2 - phi; ay, ax), with the phi nodes symmetric about pi / 4);
// at normal incidence E does not depend on phi; anisotropy between the two isotropic tables' values. The Smith
// random walk on the anisotropic microsurface (Heitz et al. 2016) checks the table from outside the quadrature:
// its order 1 is the table's E within its sampling error, its every-order albedo is 1 (a mirror absorbs nothing).
// The walk's own table (scatter/albedo_anisotropic_walk.h) is checked node by node against the analytic one.
#include "scatter/albedo_anisotropic.h"

#include "scatter/albedo_anisotropic_walk.h"
#include "scatter/albedo_layout.h"
#include "scatter/albedo_table.h"
#include "scatter/smith_walk.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace microsim {
namespace {

TEST(AlbedoAnisotropic, EqualRoughnessesAreTheIsotropicTableAndItsPublishedValues) {
  AnisotropicAlbedoRequest r;
  r.alphas_x = {0.5, 1.0};
  r.alphas_y = {1.0};
  r.mus = 12;
  r.phis = 2;
  r.tolerance = 1e-9;
  const std::optional<AnisotropicAlbedoTable> t = anisotropic_albedo_table(r);
  ASSERT_TRUE(t.has_value());
  ASSERT_EQ(t->cells.size(), 2u * 12 * 2);
  for (std::size_t j = 0; j < 12; ++j) {
    const double iso = mirror_albedo_reference(1.0, t->mus[j], 1e-10).value;
    for (std::size_t k = 0; k < 2; ++k) EXPECT_NEAR(t->cells[t->index(1, 0, j, k)].value, iso, 3e-9) << j << " " << k;
  }
  // E_avg at alpha 1 on the same 12 mu nodes, from the isotropic reference; and the published value.
  const MuGrid g = gauss_legendre_mus(12);
  double iso_avg = 0;
  for (std::size_t j = 0; j < 12; ++j) iso_avg += 2 * g.weights[j] * g.mus[j] * mirror_albedo_reference(1.0, g.mus[j], 1e-10).value;
  EXPECT_NEAR(t->average[1].value, iso_avg, 1e-8);
  EXPECT_NEAR(t->average[1].value, 0.409, 5e-4);
  for (const double phi : {0.0, 0.7, 2.0}) EXPECT_NEAR(anisotropic_mirror_albedo(1, 1, 1, phi, 1e-9).value, 0.307, 5e-4);
  // (0.5, 1): between the isotropic 0.5 and 1 tables' E_avg.
  const double avg_half = t->average[0].value;
  AnisotropicAlbedoRequest half = r;
  half.alphas_x = {0.5};
  half.alphas_y = {0.5};
  half.phis = 1;
  const double iso_half = anisotropic_albedo_table(half)->average[0].value;
  EXPECT_GT(avg_half, t->average[1].value);
  EXPECT_LT(avg_half, iso_half);
}

TEST(AlbedoAnisotropic, SwappingTheRoughnessesRotatesTheViewByAQuarterTurn) {
  AnisotropicAlbedoRequest r;
  r.alphas_x = {0.2, 0.8};
  r.alphas_y = {0.2, 0.8};
  r.mus = 4;
  r.phis = 4;
  r.tolerance = 1e-9;
  const std::optional<AnisotropicAlbedoTable> t = anisotropic_albedo_table(r);
  ASSERT_TRUE(t.has_value());
  for (std::size_t k = 0; k < 4; ++k) EXPECT_NEAR(t->phis[k] + t->phis[3 - k], std::numbers::pi / 2, 1e-14);
  for (std::size_t j = 0; j < 4; ++j)
    for (std::size_t k = 0; k < 4; ++k)
      EXPECT_NEAR(t->cells[t->index(0, 1, j, k)].value, t->cells[t->index(1, 0, j, 3 - k)].value, 4e-9) << j << " " << k;
  EXPECT_NEAR(t->average[1].value, t->average[2].value, 1e-8);
  // Near normal incidence E hardly depends on phi (exactly at mu = 1: the view has no azimuth).
  AnisotropicAlbedoRequest normal = r;
  normal.alphas_x = {0.8};
  normal.alphas_y = {0.2};
  normal.mus = 2;
  normal.phis = 4;
  const std::optional<AnisotropicAlbedoTable> n = anisotropic_albedo_table(normal);
  ASSERT_TRUE(n.has_value());
  const double spread = std::abs(n->cells[n->index(0, 0, 1, 0)].value - n->cells[n->index(0, 0, 1, 3)].value);
  const double spread_low = std::abs(n->cells[n->index(0, 0, 0, 0)].value - n->cells[n->index(0, 0, 0, 3)].value);
  EXPECT_LT(spread, spread_low);
}

// Two views on two anisotropic surfaces, 2e5 walks each (fixed seeds): order 1 within 4 standard errors (plus
// the quadrature's error estimate) of the analytic node, a two-sided level of 6e-5 per check; every path
// leaves (E over all orders plus the unfinished weight is 1). The negative control: the roughnesses swapped
// (the view turned by a quarter relative to the ellipse) move E by more than 10 of the walk's standard errors,
// so the check would see a table that confused the axes.
TEST(AlbedoAnisotropicWalk, OrderOneIsTheAnalyticNodeAndEveryPathLeaves) {
  struct Node {
    double ax, ay, mu, phi;
  };
  for (const Node& n : {Node{0.2, 0.8, 0.3, 0.4}, Node{1.0, 0.3, 0.7, 1.2}}) {
    ScatterOptions o;
    const double s = std::sqrt(1 - n.mu * n.mu);
    o.wi = Vec3<double>(s * std::cos(n.phi), s * std::sin(n.phi), n.mu);
    o.paths = 200'000;
    o.seed = 17;
    o.rows = 1;
    const ScatterHistogram h = smith_walk_scatter({NdfKind::ggx, n.ax, n.ay, HeightDistribution::uniform}, o);
    const Estimate single = h.albedo(0, 0), all = h.albedo(0, -1), unfinished = h.unfinished(0);
    const Estimate analytic = anisotropic_mirror_albedo(n.ax, n.ay, n.mu, n.phi, 1e-9);
    EXPECT_NEAR(single.value, analytic.value, 4 * single.standard_error + analytic.standard_error)
        << n.ax << " " << n.ay << " " << n.mu << " " << n.phi;
    EXPECT_NEAR(all.value + unfinished.value, 1.0, 1e-12);
    const Estimate swapped = anisotropic_mirror_albedo(n.ay, n.ax, n.mu, n.phi, 1e-9);
    EXPECT_GT(std::abs(swapped.value - single.value), 10 * single.standard_error) << "the negative control";
  }
}

// The walk table (lanes kernel, fixed seed) against the analytic table at the same 2 x 2 nodes of (0.3, 0.8):
// E1 within 4 standard errors plus the quadrature's estimate at every node and in E1_avg (two-sided level 6e-5
// per check); E + unfinished = 1 and E1 + E_ms = E per node (a mirror absorbs nothing; the orders partition
// the paths). Negative control: the analytic table with the roughnesses swapped is more than 4 standard errors
// off at some node. Same seed, same table with 1 or 2 threads.
TEST(AlbedoAnisotropicWalk, TheWalkTablesOrderOneIsTheAnalyticTable) {
  AnisotropicWalkRequest w;
  w.alphas_x = {0.3};
  w.alphas_y = {0.8};
  w.mus = 2;
  w.phis = 2;
  w.paths = 40'000;
  w.seed = 7;
  w.walk_kernel = WalkKernel::lanes;
  const std::optional<AnisotropicWalkTable> walk = anisotropic_walk_table(w);
  ASSERT_TRUE(walk);
  AnisotropicAlbedoRequest a;
  a.alphas_x = w.alphas_x;
  a.alphas_y = w.alphas_y;
  a.mus = w.mus;
  a.phis = w.phis;
  a.tolerance = 1e-7;
  const std::optional<AnisotropicAlbedoTable> exact = anisotropic_albedo_table(a);
  ASSERT_TRUE(exact);
  ASSERT_EQ(walk->cells.size(), exact->cells.size());
  double largest_swapped_z = 0;
  for (std::size_t c = 0; c < walk->cells.size(); ++c) {
    const Estimate &e = walk->cells[c][0], &e1 = walk->cells[c][1], &ms = walk->cells[c][2], &left = walk->cells[c][3];
    EXPECT_NEAR(e1.value, exact->cells[c].value, 4 * e1.standard_error + exact->cells[c].standard_error) << c;
    EXPECT_NEAR(e.value + left.value, 1.0, 1e-12) << c;
    EXPECT_NEAR(e1.value + ms.value, e.value, 1e-12) << c;
    EXPECT_GT(ms.value, 0.0) << c;
    const std::size_t j = c / 2, k = c % 2;
    const double swapped = anisotropic_mirror_albedo(0.8, 0.3, walk->mus[j], walk->phis[k], 1e-7).value;
    largest_swapped_z = std::max(largest_swapped_z, std::abs(swapped - e1.value) / e1.standard_error);
  }
  EXPECT_NEAR(walk->average[0][1].value, exact->average[0].value,
              4 * walk->average[0][1].standard_error + exact->average[0].standard_error);
  EXPECT_GT(largest_swapped_z, 4.0) << "the negative control";
  w.paths = 2'000;
  w.run.threads = 1;
  const std::optional<AnisotropicWalkTable> one = anisotropic_walk_table(w);
  w.run.threads = 2;
  const std::optional<AnisotropicWalkTable> two = anisotropic_walk_table(w);
  ASSERT_TRUE(one && two);
  EXPECT_EQ(anisotropic_walk_csv(*one), anisotropic_walk_csv(*two));
  w.paths = 0;
  EXPECT_THROW(anisotropic_walk_table(w), std::invalid_argument);
}

TEST(AlbedoAnisotropicInput, RefusesRoughnessesNodesAndTolerancesOutOfRange) {
  AnisotropicAlbedoRequest r;
  r.alphas_x = {};
  EXPECT_THROW(anisotropic_albedo_table(r), std::invalid_argument);
  r.alphas_x = {0.001};
  EXPECT_THROW(anisotropic_albedo_table(r), std::invalid_argument);
  r.alphas_x = {0.5};
  r.phis = 0;
  EXPECT_THROW(anisotropic_albedo_table(r), std::invalid_argument);
  r.phis = 2;
  r.mus = 1;
  EXPECT_THROW(anisotropic_albedo_table(r), std::invalid_argument);
  r.mus = 2;
  r.tolerance = 0.5;
  EXPECT_THROW(anisotropic_albedo_table(r), std::invalid_argument);
}

}  // namespace
}  // namespace microsim
