// The published layout tables (docs/data/layout-*, scripts/energy_tables.py) read back the way each renderer
// reads its own table, with a reader written here from the renderer's documented parametrisation (not from
// scatter/albedo_layout.h), and three nodes of each checked against an independent quadrature of the GGX
// mirror's single-scattering albedo over outgoing directions (a tensor Gauss-Legendre rule in theta_o, phi_o:
// no visible-normal substitution, no adaptivity).
//   Cycles (cycles_precompute.cpp, lookup_table.h): 32 text lines of 32 values, table[y][x], x the roughness
//     r = sqrt(alpha) at x / 31, y mu at y / 31.
//   Filament (CubemapIBL.cpp DFG, DFV_Multiscatter; cmgen's "GL order"): 128 x 128 texels of two little-endian
//     half floats, R = DFG.x (the albedo weighted by Schlick's (1 - VoH)^5), G = DFG.y (E of F = 1), row =
//     perceptual roughness r = sqrt(alpha) at (row + 0.5) / 128, column = NoV at (column + 0.5) / 128; a
//     shader reads E(f0) = mix(DFG.x, DFG.y, f0).
//   Enterprise PBR (res/pbrlut.hpp GGX_E[32 roughness][32 cos_theta]): 32 x 32 little-endian float32,
//     nodes at cell centres (i + 0.5) / 32, roughness r = sqrt(alpha).
#include <boost/math/quadrature/gauss.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_albedo_layout_files {

namespace {

namespace fs = std::filesystem;

const fs::path kData = fs::path(MICROSIM_TEST_DATA) / ".." / ".." / "docs" / "data";

std::string bytes_of(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// E(mu) of a GGX (or Beckmann) mirror, single scattering with the height-correlated Smith G2 (Heitz 2014,
// eq. 99): integral over the upper hemisphere of D(h) G2(i, o) / (4 mu_i) dwo, phi over [0, pi] doubled
// (symmetry). schlick_power 5: each direction weighted by (1 - wi.h)^5 (Filament's DFG.x); 0: F = 1.
// GGX: D and Lambda of Heitz 2014 eqs. 71-72; Beckmann: eqs. 69-70 (Lambda by erf).
double independent_albedo(double alpha, double mu, int schlick_power = 0, bool beckmann = false) {
  const double a2 = alpha * alpha, si = std::sqrt(1 - mu * mu);
  const auto lambda = [&](double c) {
    if (!beckmann) return (-1 + std::sqrt(1 + a2 * (1 - c * c) / (c * c))) / 2;
    const double a = c / (alpha * std::sqrt(1 - c * c));
    return (std::erf(a) - 1) / 2 + std::exp(-a * a) / (2 * a * std::sqrt(std::numbers::pi));
  };
  const auto ndf = [&](double cos2, double tan2) {
    const double p = std::numbers::pi * a2 * cos2 * cos2;
    return beckmann ? std::exp(-tan2 / a2) / p : 1 / (p * std::pow(1 + tan2 / a2, 2));
  };
  const auto integrand = [&](double theta, double phi) {
    const double co = std::cos(theta), so = std::sin(theta);
    const double hx = si + so * std::cos(phi), hy = so * std::sin(phi), hz = mu + co;
    const double hn2 = hx * hx + hy * hy + hz * hz, cos2 = hz * hz / hn2, tan2 = (1 - cos2) / cos2;
    const double d = ndf(cos2, tan2);
    const double g2 = 1 / (1 + lambda(mu) + lambda(co));
    const double weight = std::pow(1 - (si * hx + mu * hz) / std::sqrt(hn2), schlick_power);
    return d * g2 / (4 * mu) * so * weight;
  };
  using Rule = boost::math::quadrature::gauss<double, 200>;
  double sum = 0;
  const int pieces = 8;  // theta in 8 pieces, phi in 8 pieces, 200 nodes each
  for (int i = 0; i < pieces; ++i)
    for (int j = 0; j < pieces; ++j) {
      const double t0 = std::numbers::pi / 2 * i / pieces, t1 = std::numbers::pi / 2 * (i + 1) / pieces;
      const double p0 = std::numbers::pi * j / pieces, p1 = std::numbers::pi * (j + 1) / pieces;
      sum += Rule::integrate([&](double t) { return Rule::integrate([&](double p) { return integrand(t, p); }, p0, p1); },
                             t0, t1);
    }
  return 2 * sum;
}

double half_to_double(std::uint16_t h) {
  const int e = (h >> 10) & 0x1f, m = h & 0x3ff;
  const double v = e == 0 ? std::ldexp(m, -24) : std::ldexp(1024 + m, e - 25);
  return (h & 0x8000) ? -v : v;
}

TEST(AlbedoLayoutFiles, TheIndependentQuadratureIsThePublishedValue) {
  EXPECT_NEAR(independent_albedo(1.0, 1.0), 0.306853, 2e-6);  // Kulla & Conty 2017: E(mu = 1) at alpha 1
}

// Cycles' text form: 32 lines of 32 comma-separated values, table[y][x].
std::vector<std::vector<double>> cycles_table(const fs::path& path) {
  std::istringstream text(bytes_of(path));
  std::vector<std::vector<double>> table;
  for (std::string line; std::getline(text, line);) {
    std::vector<double> row;
    std::istringstream fields(line);
    for (std::string f; std::getline(fields, f, ',');) row.push_back(std::stod(f));
    table.push_back(row);
  }
  return table;
}

void expect_cycles_nodes(const fs::path& path, bool beckmann) {
  const std::vector<std::vector<double>> table = cycles_table(path);
  ASSERT_EQ(table.size(), 32u);
  for (const auto& row : table) ASSERT_EQ(row.size(), 32u);
  for (const auto& [x, y] : {std::pair{16, 20}, std::pair{31, 31}, std::pair{24, 8}}) {
    const double r = x / 31.0, mu = y / 31.0;
    EXPECT_NEAR(table[std::size_t(y)][std::size_t(x)], independent_albedo(r * r, mu, 0, beckmann), 1e-6)
        << x << " " << y;
  }
}

TEST(AlbedoLayoutFiles, CyclesTableReadAsCyclesReadsIt) { expect_cycles_nodes(kData / "layout-cycles.txt", false); }

// The Beckmann mirror's table in Cycles' layout; the GGX quadrature would miss it (negative control).
TEST(AlbedoLayoutFiles, BeckmannTableInCyclesLayoutIsTheBeckmannQuadrature) {
  expect_cycles_nodes(kData / "layout-cycles-beckmann.txt", true);
  const std::vector<std::vector<double>> table = cycles_table(kData / "layout-cycles-beckmann.txt");
  ASSERT_EQ(table.size(), 32u);
  EXPECT_GT(std::abs(table[8][24] - independent_albedo(24.0 * 24.0 / (31.0 * 31.0), 8.0 / 31.0)), 1e-3);
}

TEST(AlbedoLayoutFiles, FilamentDfgReadAsFilamentSamplesIt) {
  const std::string b = bytes_of(kData / "layout-filament-dfg.bin");
  ASSERT_EQ(b.size(), 128u * 128 * 2 * 2);
  const auto texel = [&](int column, int row, int channel) {  // channel 0: R, 1: G
    const std::size_t k = 4 * (std::size_t(row) * 128 + std::size_t(column)) + 2 * std::size_t(channel);
    return half_to_double(std::uint16_t(std::uint8_t(b[k]) | (std::uint8_t(b[k + 1]) << 8)));
  };
  const auto half_ulp = [](double v) { return std::ldexp(1.0, std::ilogb(v) - 11); };
  for (const auto& [column, row] : {std::pair{64, 64}, std::pair{100, 40}, std::pair{20, 120}}) {
    const double nov = (column + 0.5) / 128, r = (row + 0.5) / 128;
    const double y = independent_albedo(r * r, nov), x = independent_albedo(r * r, nov, 5);
    EXPECT_NEAR(texel(column, row, 1), y, half_ulp(y) + 1e-7) << "DFG.y " << column << " " << row;
    EXPECT_NEAR(texel(column, row, 0), x, half_ulp(x) + 1e-7) << "DFG.x " << column << " " << row;
    EXPECT_GT(x, 0.0);
    EXPECT_LT(x, y) << "the grazing weight (1 - VoH)^5 is below 1";
  }
}

TEST(AlbedoLayoutFiles, EnterprisePbrTableReadAsItsSpecSays) {
  const std::string b = bytes_of(kData / "layout-enterprise-pbr.bin");
  ASSERT_EQ(b.size(), 32u * 32 * 4);
  const auto value = [&](int roughness, int cos_theta) {
    float f = 0;
    std::memcpy(&f, b.data() + 4 * (std::size_t(roughness) * 32 + std::size_t(cos_theta)), 4);
    return double(f);
  };
  for (const auto& [ri, ci] : {std::pair{31, 31}, std::pair{12, 5}, std::pair{20, 26}}) {
    const double r = (ri + 0.5) / 32, mu = (ci + 0.5) / 32;
    EXPECT_NEAR(value(ri, ci), independent_albedo(r * r, mu), 2e-7) << ri << " " << ci;
  }
}

}  // namespace

}  // namespace test_albedo_layout_files
