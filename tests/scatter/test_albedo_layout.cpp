// Energy-compensation tables in renderers' layouts and the grade of a shipped table (scatter/albedo_layout.h,
// scatter/albedo_grade.h, scatter/albedo_layout_io.h): the registry and each layout's axes; the encodings
// (IEEE half by its definition, round to nearest even); a small layout's nodes, centres and interpolation
// error against direct evaluation; the grade of tables made here the way renderers make them, written from
// the math in this file (GGX visible-normal sampling, Heitz 2018, and GGX NDF sampling, Walter et al. 2007
// eq. 35-36, with few samples, fp16 encoded): a correct table passes, one node moved by 1e-3 fails (the
// negative control), a VNDF-sampled table stays within its stated sample count's noise, a 64-sample NDF
// table fails a 1e-3 tolerance.
#include "scatter/albedo_grade.h"
#include "scatter/albedo_layout.h"
#include "scatter/albedo_layout_io.h"

#include "core/parse.h"

#include <Eigen/Core>
#include <boost/math/quadrature/gauss.hpp>
#include <fmt/ranges.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

namespace microsim {
namespace {

// ---- the registry --------------------------------------------------------------------------------------------

TEST(AlbedoLayouts, TheRegistryHoldsTheFourLayoutsWithTheirRenderersAxes) {
  EXPECT_EQ(albedo_layout_names(), "cycles, filament-dfg, enterprise-pbr, uniform");
  const AlbedoLayout& cycles = find_albedo_layout("--layout", "cycles");
  EXPECT_EQ(layout_columns(cycles), 32);
  EXPECT_EQ(layout_rows(cycles), 32);
  EXPECT_DOUBLE_EQ(layout_coordinate(cycles.roughness, 0), 1e-4);  // clamped, alpha = 1e-8
  EXPECT_DOUBLE_EQ(layout_coordinate(cycles.roughness, 31), 1.0);
  EXPECT_DOUBLE_EQ(layout_coordinate(cycles.mu, 1), 1.0 / 31);
  EXPECT_DOUBLE_EQ(layout_alpha(cycles, 0.5), 0.25);
  EXPECT_EQ(layout_storage_index(cycles, 3, 5), 5u * 32 + 3) << "Cycles: data[mu * 32 + rough]";
  const AlbedoLayout& filament = find_albedo_layout("--layout", "filament-dfg");
  EXPECT_EQ(layout_columns(filament), 128);
  EXPECT_DOUBLE_EQ(layout_coordinate(filament.mu, 0), 0.5 / 128);
  EXPECT_EQ(layout_storage_index(filament, 3, 5), 3u * 128 + 5) << "GL order: row = roughness";
  EXPECT_EQ(filament.encoding, LayoutEncoding::half);
  const AlbedoLayout& uniform = find_albedo_layout("--layout", "uniform");
  EXPECT_DOUBLE_EQ(layout_alpha(uniform, 0.5), 0.5);
  EXPECT_THROW(find_albedo_layout("--layout", "unreal"), ParseError);
}

// ---- encodings ------------------------------------------------------------------------------------------------

TEST(AlbedoLayouts, HalfFloatsAreIeeeBinary16RoundedToNearestEven) {
  EXPECT_EQ(half_bits(1.0), 0x3c00);
  EXPECT_EQ(half_bits(0.5), 0x3800);
  EXPECT_EQ(half_bits(-2.0), 0xc000);
  EXPECT_EQ(half_bits(65504.0), 0x7bff);
  EXPECT_EQ(half_bits(std::ldexp(1.0, -24)), 0x0001);  // the least subnormal
  EXPECT_EQ(half_bits(std::ldexp(1.0, -14)), 0x0400);  // the least normal
  EXPECT_EQ(half_bits(1.0 + std::ldexp(1.0, -11)), 0x3c00) << "a tie goes to the even mantissa";
  EXPECT_EQ(half_bits(1.0 + 3 * std::ldexp(1.0, -11)), 0x3c02) << "a tie goes to the even mantissa";
  EXPECT_EQ(half_bits(2.0 - std::ldexp(1.0, -12)), 0x4000) << "rounding carries into the exponent";
  for (std::uint32_t b = 0; b < 0x7c00; ++b) ASSERT_EQ(half_bits(half_value(std::uint16_t(b))), b);
  // The rounding error is at most half a unit in the last place, layout_quantisation's bound.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 10000; ++i) {
    const double v = u(rng);
    ASSERT_LE(std::abs(encode_layout_value(LayoutEncoding::half, v) - v), layout_quantisation(LayoutEncoding::half, v));
    ASSERT_LE(std::abs(encode_layout_value(LayoutEncoding::unorm16, v) - v),
              layout_quantisation(LayoutEncoding::unorm16, v) * (1 + 1e-12));
    ASSERT_LE(std::abs(encode_layout_value(LayoutEncoding::six_decimals, v) - v),
              layout_quantisation(LayoutEncoding::six_decimals, v));
  }
}

// ---- a layout's nodes, centres and interpolation error --------------------------------------------------------

AlbedoLayout small_layout() {
  AlbedoLayout l = find_albedo_layout("--layout", "cycles");
  l.name = "small";
  l.roughness = {3, LayoutPlacement::edges, 0.3};
  l.mu = {4, LayoutPlacement::centres, 0};
  return l;
}

TEST(AlbedoLayouts, NodesCentresAndInterpolationErrorAreTheReferenceWhereTheLayoutSays) {
  const AlbedoLayout l = small_layout();
  const std::optional<LayoutTable> t = layout_table(l, 1e-9);
  ASSERT_TRUE(t.has_value());
  ASSERT_EQ(t->cells.size(), 12u);
  ASSERT_EQ(t->centres.size(), 6u);
  ASSERT_EQ(t->average.size(), 3u);
  EXPECT_DOUBLE_EQ(t->roughness[0], 0.3);  // 0 clamped to the layout's lowest
  EXPECT_DOUBLE_EQ(t->alphas[1], 0.25);
  EXPECT_DOUBLE_EQ(t->mus[1], 0.375);
  const Estimate e = mirror_albedo_reference(0.25, 0.375, 1e-10);
  EXPECT_NEAR(t->cells[1 * 4 + 1].value, e.value, 2e-9);
  // The centre of cell (1, 2): roughness midway between 0.5 and 1, mu between 0.625 and 0.875.
  const double centre = mirror_albedo_reference(0.75 * 0.75, 0.75, 1e-10).value;
  EXPECT_NEAR(t->centres[1 * 3 + 2].value, centre, 2e-9);
  const double bilinear = (t->cells[1 * 4 + 2].value + t->cells[1 * 4 + 3].value + t->cells[2 * 4 + 2].value +
                           t->cells[2 * 4 + 3].value) / 4;
  EXPECT_NEAR(t->interpolation.errors[1 * 3 + 2], bilinear - centre, 4e-9);
  double worst = 0;
  for (const double x : t->interpolation.errors) worst = std::max(worst, std::abs(x));
  EXPECT_DOUBLE_EQ(t->interpolation.max_abs, worst);
  // E_avg at alpha 1 (the last roughness node, r = 1): the published 0.409 (Kulla & Conty 2017).
  EXPECT_NEAR(t->average[2].value, 0.409, 1e-3);
}

// ---- tables made the way renderers make them ------------------------------------------------------------------

// GGX with the height-correlated Smith masking of the Smith microsurface (Heitz 2014, eq. 99):
// Lambda(mu) = (-1 + sqrt(1 + alpha^2 tan^2)) / 2.
double lambda(double alpha, double mu) {
  const double t2 = (1 - mu * mu) / (mu * mu);
  return (-1 + std::sqrt(1 + alpha * alpha * t2)) / 2;
}

struct V3 {
  double x, y, z;
};
V3 reflect(const V3& v, const V3& m) {
  const double d = 2 * (v.x * m.x + v.y * m.y + v.z * m.z);
  return {d * m.x - v.x, d * m.y - v.y, d * m.z - v.z};
}

// One VNDF sample's weight (Heitz 2018, "Sampling the GGX Distribution of Visible Normals", listing 1,
// written from its equations): the estimator of E is G2(wi, wo) / G1(wi) = (1 + L(i)) / (1 + L(i) + L(o)).
double vndf_weight(double alpha, double mu, double u1, double u2) {
  const V3 wi{std::sqrt(1 - mu * mu), 0, mu};
  V3 vh{alpha * wi.x, 0, wi.z};
  const double n = std::sqrt(vh.x * vh.x + vh.z * vh.z);
  vh = {vh.x / n, 0, vh.z / n};
  const V3 T1 = vh.x > 0 ? V3{0, 1, 0} : V3{1, 0, 0};  // (-vh.y, vh.x, 0) normalised; vh.y = 0
  const V3 T2{vh.y * T1.z - vh.z * T1.y, vh.z * T1.x - vh.x * T1.z, vh.x * T1.y - vh.y * T1.x};
  const double r = std::sqrt(u1), phi = 2 * std::numbers::pi * u2;
  double p1 = r * std::cos(phi), p2 = r * std::sin(phi);
  const double s = 0.5 * (1 + vh.z);
  p2 = (1 - s) * std::sqrt(1 - p1 * p1) + s * p2;
  const double p3 = std::sqrt(std::max(0.0, 1 - p1 * p1 - p2 * p2));
  const V3 nh{p1 * T1.x + p2 * T2.x + p3 * vh.x, p1 * T1.y + p2 * T2.y + p3 * vh.y, p1 * T1.z + p2 * T2.z + p3 * vh.z};
  V3 m{alpha * nh.x, alpha * nh.y, std::max(0.0, nh.z)};
  const double mn = std::sqrt(m.x * m.x + m.y * m.y + m.z * m.z);
  m = {m.x / mn, m.y / mn, m.z / mn};
  const V3 wo = reflect(wi, m);
  if (wo.z <= 0) return 0;
  return (1 + lambda(alpha, mu)) / (1 + lambda(alpha, mu) + lambda(alpha, wo.z));
}

// One NDF sample's weight (Walter et al. 2007 eq. 35-36: theta_m = atan(alpha sqrt(u1 / (1 - u1))),
// pdf D(m) cos theta_m, wo = reflect, dwo/dm = 1 / (4 |wi.m|)): f cos o / pdf = G2 |wi.m| / (mu cos theta_m).
double ndf_weight(double alpha, double mu, double u1, double u2) {
  const V3 wi{std::sqrt(1 - mu * mu), 0, mu};
  const double tm = std::atan(alpha * std::sqrt(u1 / (1 - u1))), phi = 2 * std::numbers::pi * u2;
  const V3 m{std::sin(tm) * std::cos(phi), std::sin(tm) * std::sin(phi), std::cos(tm)};
  const double im = wi.x * m.x + wi.y * m.y + wi.z * m.z;
  if (im <= 0) return 0;
  const V3 wo = reflect(wi, m);
  if (wo.z <= 0) return 0;
  const double g2 = 1 / (1 + lambda(alpha, mu) + lambda(alpha, wo.z));
  return g2 * im / (mu * m.z);
}

// A table in `layout` from `samples` stratified samples per node of `weight`, fp16 encoded.
template <class W>
std::vector<double> sampled_table(const AlbedoLayout& l, int samples, std::uint64_t seed, const W& weight) {
  std::vector<double> values(std::size_t(layout_columns(l) * layout_rows(l)));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int ri = 0; ri < l.roughness.nodes; ++ri)
    for (int mj = 0; mj < l.mu.nodes; ++mj) {
      const double alpha = layout_alpha(l, layout_coordinate(l.roughness, ri)), mu = layout_coordinate(l.mu, mj);
      double sum = 0;
      for (int s = 0; s < samples; ++s) sum += weight(alpha, mu, u(rng), u(rng));
      values[layout_storage_index(l, std::size_t(ri), std::size_t(mj))] =
          encode_layout_value(LayoutEncoding::half, sum / samples);
    }
  return values;
}

// The Cycles layout's reference, computed once per process at quadrature tolerance 1e-5: the grades below
// compare tables made from it (its own nodes rounded, one node moved by 1e-3) or sampled with noise of 1e-2
// and fp16 rounding of 2.4e-4, so what they check does not depend on its accuracy beyond that (its error
// estimate is part of each node's slack).
const LayoutTable& cycles_reference() {
  static const LayoutTable t = *layout_table(find_albedo_layout("--layout", "cycles"), 1e-5, {}, false);
  return t;
}

std::vector<double> reference_values(const LayoutTable& t) {
  std::vector<double> v(t.cells.size());
  for (std::size_t ri = 0; ri < t.alphas.size(); ++ri)
    for (std::size_t mj = 0; mj < t.mus.size(); ++mj)
      v[layout_storage_index(t.layout, ri, mj)] =
          encode_layout_value(t.layout.encoding, t.cells[ri * t.mus.size() + mj].value);
  return v;
}

TEST(AlbedoGrade, TheCorrectTablePassesAndOneNodeOffBy1e3IsFlagged) {
  const LayoutTable& ref = cycles_reference();
  std::vector<double> values = reference_values(ref);
  const AlbedoGrade good = grade_against(ref, values, 5e-4);
  EXPECT_TRUE(good.passed());
  EXPECT_EQ(good.not_graded, 32u) << "Cycles' r = 1e-4 (alpha 1e-8) is below the reference's alpha range";
  EXPECT_EQ(good.beyond_quantisation, 0u) << "a table in Cycles' 6 decimals is within its rounding";
  EXPECT_LT(good.max_abs, 6e-7);
  // The negative control: one node (alpha 0.25, mu 10/31) moved by 1e-3.
  const std::size_t planted = layout_storage_index(ref.layout, 16, 10);
  values[planted] += 1e-3;
  const AlbedoGrade bad = grade_against(ref, values, 5e-4);
  EXPECT_FALSE(bad.passed());
  EXPECT_EQ(bad.failed, 1u);
  EXPECT_EQ(bad.cells[bad.worst].ri, 16u);
  EXPECT_EQ(bad.cells[bad.worst].mj, 10u);
  EXPECT_NEAR(bad.max_abs, 1e-3, 1e-6);
  EXPECT_EQ(bad.beyond_quantisation, 1u);
}

// Filament's DFG layout, both channels, on an 8 x 8 grid of its own placement (texel centres, perceptual
// roughness) so that the test stays cheap: DFG.y is E of F = 1 (the mirror's reference), DFG.x the albedo
// weighted by (1 - VoH)^5, and a Schlick material's albedo is mix(DFG.x, DFG.y, f0). The table as Filament
// stores it (halves) passes in both channels; one DFG.x texel moved by 1e-3 is flagged (the negative control)
// while DFG.y still passes.
TEST(AlbedoGradeChannels, FilamentsTwoChannelsAreGradedAndOnePlantedTexelIsFlagged) {
  AlbedoLayout l = find_albedo_layout("--layout", "filament-dfg");
  ASSERT_TRUE(l.has_grazing());
  EXPECT_EQ(l.grazing_quantity, "DFG.x");
  l.roughness.nodes = 8;
  l.mu.nodes = 8;
  const std::optional<LayoutTable> t = layout_table(l, 1e-5, {}, false);
  ASSERT_TRUE(t.has_value());
  ASSERT_EQ(t->grazing.size(), 64u);
  ASSERT_EQ(t->grazing_centres.size(), 49u);
  EXPECT_LT(t->grazing_interpolation.max_abs, 0.05);
  const std::size_t node = 5 * 8 + 2;  // r = 5.5 / 8, NoV = 2.5 / 8
  EXPECT_NEAR(t->cells[node].value, mirror_albedo_reference(t->alphas[5], t->mus[2], 1e-9).value, 1e-5);
  EXPECT_GT(t->grazing[node].value, 0.0);
  EXPECT_LT(t->grazing[node].value, t->cells[node].value);
  std::vector<double> y(64), x(64);
  for (std::size_t k = 0; k < 64; ++k) {
    y[layout_storage_index(l, k / 8, k % 8)] = encode_layout_value(l.encoding, t->cells[k].value);
    x[layout_storage_index(l, k / 8, k % 8)] = encode_layout_value(l.encoding, t->grazing[k].value);
  }
  const AlbedoGrade gy = grade_against(*t, y, 5e-4), gx = grade_against(*t, x, 5e-4, 0, true);
  EXPECT_TRUE(gy.passed());
  EXPECT_TRUE(gx.passed());
  EXPECT_EQ(gx.quantity, "DFG.x");
  EXPECT_EQ(gx.beyond_quantisation, 0u) << "a half-float table is within its rounding";
  // At the default tolerance (1e-4, below half floats' rounding near 1: up to 2.4e-4) the exact table still passes:
  // it is judged beyond what its encoding can hold.
  EXPECT_TRUE(grade_against(*t, y, 1e-4).passed());
  EXPECT_TRUE(grade_against(*t, x, 1e-4, 0, true).passed());
  EXPECT_GT(std::max(grade_against(*t, y, 1e-4).max_abs, grade_against(*t, x, 1e-4, 0, true).max_abs), 1e-4)
      << "the rounding exceeds the tolerance somewhere (else this checks nothing)";
  x[layout_storage_index(l, 3, 6)] += 1e-3;
  EXPECT_FALSE(grade_against(*t, x, 1e-4, 0, true).passed());
  const AlbedoGrade bad = grade_against(*t, x, 5e-4, 0, true);
  EXPECT_FALSE(bad.passed());
  EXPECT_EQ(bad.failed, 1u);
  EXPECT_EQ(bad.cells[bad.worst].ri, 3u);
  EXPECT_EQ(bad.cells[bad.worst].mj, 6u);
  const LayoutTable plain = *layout_table(small_layout(), 1e-6, {}, false);
  EXPECT_THROW(grade_against(plain, reference_values(plain), 5e-4, 0, true), std::invalid_argument)
      << "a layout without a grazing channel";
}

// A table filled one roughness node up (as Filament's generator fills its LUT: row i at roughness node i + 1, the
// last row clamped) fails, and the grade names the shift; a transposed one likewise; the exact table, and one with
// errors that no misreading explains, get no such hint.
TEST(AlbedoGradeChannels, ATableFilledOneNodeOffOrTransposedIsNamed) {
  AlbedoLayout l = find_albedo_layout("--layout", "filament-dfg");
  l.roughness.nodes = 8;
  l.mu.nodes = 8;
  const std::optional<LayoutTable> t = layout_table(l, 1e-6, {}, false);
  ASSERT_TRUE(t.has_value());
  const auto table = [&](const auto& node_of) {
    std::vector<double> v(64);
    for (std::size_t ri = 0; ri < 8; ++ri)
      for (std::size_t mj = 0; mj < 8; ++mj) {
        const auto [r, m] = node_of(ri, mj);
        v[layout_storage_index(l, ri, mj)] = t->cells[r * 8 + m].value;
      }
    return v;
  };
  const auto names = [](const AlbedoGrade& g, const std::string& words) {
    return std::any_of(g.hints.begin(), g.hints.end(), [&](const std::string& h) { return h.find(words) != std::string::npos; });
  };
  const AlbedoGrade up = grade_against(*t, table([](std::size_t ri, std::size_t mj) {
    return std::pair{std::min<std::size_t>(ri + 1, 7), mj};
  }), 1e-4);
  EXPECT_FALSE(up.passed());
  EXPECT_TRUE(names(up, "roughness rows one node up")) << fmt::format("{}", fmt::join(up.hints, " | "));
  const AlbedoGrade swapped = grade_against(*t, table([](std::size_t ri, std::size_t mj) { return std::pair{mj, ri}; }), 1e-4);
  EXPECT_FALSE(swapped.passed());
  EXPECT_TRUE(names(swapped, "transposed")) << fmt::format("{}", fmt::join(swapped.hints, " | "));
  const AlbedoGrade exact = grade_against(*t, table([](std::size_t ri, std::size_t mj) { return std::pair{ri, mj}; }), 1e-4);
  EXPECT_TRUE(exact.passed() && exact.hints.empty());
  std::vector<double> noisy = table([](std::size_t ri, std::size_t mj) { return std::pair{ri, mj}; });
  for (std::size_t k = 0; k < noisy.size(); ++k) noisy[k] += (k % 3 == 0 ? 2e-3 : -1e-3);
  const AlbedoGrade off = grade_against(*t, noisy, 1e-4);
  EXPECT_FALSE(off.passed());
  EXPECT_TRUE(off.hints.empty()) << fmt::format("{}", fmt::join(off.hints, " | "));
}

// The 200-point Gauss-Legendre rule (even: no node at the centre) of a two-valued f on [a, b].
template <class F> Eigen::Array2d gauss_legendre_pair(const F& f, double a, double b) {
  using Rule = boost::math::quadrature::gauss<double, 200>;
  const double mid = (a + b) / 2, half = (b - a) / 2;
  Eigen::Array2d sum = Eigen::Array2d::Zero();
  for (std::size_t i = 0; i < Rule::abscissa().size(); ++i)
    sum += Rule::weights()[i] * (f(mid + half * Rule::abscissa()[i]) + f(mid - half * Rule::abscissa()[i]));
  return half * sum;
}

// E(mu) of a Beckmann mirror, single scattering with the height-correlated Smith G2 (Heitz 2014, eq. 99):
// Beckmann's D (Walter et al. 2007, eq. 25) and its Smith Lambda (Walter et al. 2007, eq. 27 as
// Lambda = (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)), a = 1 / (alpha tan theta)), integrated over the
// outgoing hemisphere by Gauss-Legendre in theta and phi (phi over [0, pi] doubled: symmetry), as
// test_albedo_layout_files.cpp integrates GGX's; and the same weighted by Schlick's grazing term (1 - wi.h)^5
// (h the half vector), Filament's DFG.x.
Eigen::Array2d independent_beckmann_albedo(double alpha, double mu) {
  const double a2 = alpha * alpha, si = std::sqrt(1 - mu * mu), sqrt_pi = std::sqrt(std::numbers::pi);
  const auto lambda = [&](double c) {
    const double s = std::sqrt(std::max(0.0, 1 - c * c));
    if (s == 0) return 0.0;
    const double a = c / (alpha * s);
    return (std::erf(a) - 1) / 2 + std::exp(-a * a) / (2 * a * sqrt_pi);
  };
  const auto integrand = [&](double theta, double phi) {
    const double co = std::cos(theta), so = std::sin(theta);
    const double hx = si + so * std::cos(phi), hy = so * std::sin(phi), hz = mu + co;
    const double cos2 = hz * hz / (hx * hx + hy * hy + hz * hz), tan2 = (1 - cos2) / cos2;
    const double d = std::exp(-tan2 / a2) / (std::numbers::pi * a2 * cos2 * cos2);
    const double e = d / (1 + lambda(mu) + lambda(co)) / (4 * mu) * so;
    const double c = 1 - (si * hx + mu * hz) / std::sqrt(hx * hx + hy * hy + hz * hz);
    return Eigen::Array2d(e, e * c * c * c * c * c);
  };
  Eigen::Array2d sum = Eigen::Array2d::Zero();
  const int pieces = 8;  // theta in 8 pieces, phi in 8 pieces, 200 nodes each
  for (int i = 0; i < pieces; ++i)
    for (int j = 0; j < pieces; ++j) {
      const double t0 = std::numbers::pi / 2 * i / pieces, t1 = std::numbers::pi / 2 * (i + 1) / pieces;
      const double p0 = std::numbers::pi * j / pieces, p1 = std::numbers::pi * (j + 1) / pieces;
      sum += gauss_legendre_pair(
          [&](double t) { return gauss_legendre_pair([&](double p) { return integrand(t, p); }, p0, p1); }, t0, t1);
    }
  return 2 * sum;
}

// --ndf beckmann in a layout: the same grid holds a Beckmann mirror's E, three nodes of it agree with the
// independent quadrature above, it is not GGX's table, the files say which it is, and grading GGX's table
// against the Beckmann reference fails while the Beckmann table passes (the negative control).
TEST(AlbedoLayouts, ABeckmannTableHoldsTheBeckmannMirrorsAlbedo) {
  const AlbedoLayout l = small_layout();
  const std::optional<LayoutTable> b = layout_table(l, 1e-9, {}, true, NdfKind::beckmann);
  const std::optional<LayoutTable> g = layout_table(l, 1e-6, {}, false);
  ASSERT_TRUE(b.has_value() && g.has_value());
  EXPECT_EQ(b->ndf, NdfKind::beckmann);
  for (const std::size_t k : {1u, 6u, 11u}) {
    const Eigen::Array2d independent = independent_beckmann_albedo(b->alphas[k / 4], b->mus[k % 4]);
    EXPECT_NEAR(b->cells[k].value, independent[0], 2e-6) << k;
    // Filament's DFG.x of a Beckmann mirror at the same node: the same quadrature's second integral.
    EXPECT_NEAR(mirror_split_reference(b->alphas[k / 4], b->mus[k % 4], 1e-9, NdfKind::beckmann).grazing.value,
                independent[1], 2e-6) << k;
  }
  double apart = 0;
  for (std::size_t k = 0; k < b->cells.size(); ++k) apart = std::max(apart, std::abs(b->cells[k].value - g->cells[k].value));
  EXPECT_GT(apart, 1e-2);
  EXPECT_EQ(layout_table_json(*b).at("ndf"), "beckmann");
  EXPECT_EQ(layout_table_exr(*g).attributes.at("ndf"), "ggx");
  EXPECT_NE(layout_table_csv(*b).find("of a Beckmann mirror"), std::string::npos);
  EXPECT_TRUE(grade_against(*b, reference_values(*b), 1e-4).passed());
  const AlbedoGrade wrong = grade_against(*b, reference_values(*g), 1e-4);
  EXPECT_FALSE(wrong.passed());
  EXPECT_EQ(wrong.ndf, NdfKind::beckmann);
}

// The Cycles grid with half-float storage (the encoding of the sampled tables below).
LayoutTable half_reference() {
  LayoutTable t = cycles_reference();
  t.layout.encoding = LayoutEncoding::half;
  return t;
}

TEST(AlbedoGrade, TablesSampledAsRenderersDoAreGradedAgainstTheirNoise) {
  const LayoutTable ref = half_reference();
  // VNDF sampling, 4096 samples per node, fp16: within its stated sample count's noise, and beyond that of
  // a count 100 times larger (the negative control).
  const int samples = 4096;
  const std::vector<double> vndf = sampled_table(ref.layout, samples, 11, vndf_weight);
  const AlbedoGrade g = grade_against(ref, vndf, 0.05, std::uint64_t(samples));
  EXPECT_TRUE(g.passed());
  EXPECT_EQ(g.beyond_noise, 0u) << "level " << kGradeNoiseLevel << ", z " << g.noise_z;
  EXPECT_GT(g.beyond_quantisation, 500u) << "4096 samples leave noise far above fp16's rounding";
  const AlbedoGrade claimed = grade_against(ref, vndf, 0.05, 100 * std::uint64_t(samples));
  EXPECT_GT(claimed.beyond_noise, 100u);
  // NDF sampling, 64 samples per node: fails a tolerance of 1e-3, worst at a grazing view.
  const std::vector<double> ndf = sampled_table(ref.layout, 64, 5, ndf_weight);
  const AlbedoGrade n = grade_against(ref, ndf, 1e-3, 64);
  EXPECT_FALSE(n.passed());
  EXPECT_GT(n.max_abs, 1e-2);
  EXPECT_LT(n.cells[n.worst].mu, 0.5) << "NDF sampling's weights are largest at grazing views";
}

TEST(AlbedoGradeInput, RefusesATableOfTheWrongSizeOrWithANonFiniteValue) {
  const LayoutTable ref = *layout_table(small_layout(), 1e-6, {}, false);
  EXPECT_THROW(grade_against(ref, std::vector<double>(10, 0.5), 1e-3), std::invalid_argument);
  EXPECT_NO_THROW(grade_against(ref, reference_values(ref), 1e-3));
  std::vector<double> values = reference_values(ref);
  values[3] = std::nan("");
  EXPECT_THROW(grade_against(ref, values, 1e-3), std::invalid_argument);
  EXPECT_THROW(grade_against(ref, reference_values(ref), 0.0), std::invalid_argument);
}

// A table as a renderer's source prints it (Cycles' shader.tables: C floats with their 'f', comma-separated
// rows): every number in order; a wrong count or a number that does not parse is named.
TEST(AlbedoGradeInput, PrintedValuesAreReadAsTheRenderersSourcePrintsThem) {
  EXPECT_EQ(printed_values("  1.000000f, 0.980405f,\n  0.5f, 0.25\n", 4, "cycles"),
            (std::vector<double>{1.0, 0.980405, 0.5, 0.25}));
  EXPECT_EQ(printed_values("1,2\n\n3,4", 4, "cycles"), (std::vector<double>{1, 2, 3, 4}));
  try {
    printed_values("1, 2,\n3, x4f", 4, "cycles");
    ADD_FAILURE() << "a number that does not parse";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("line 2"), std::string::npos) << e.what();
  }
  try {
    printed_values("1, 2, 3", 4, "cycles");
    ADD_FAILURE() << "three values for four";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("3 values in the text; the cycles layout has 4"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace microsim
