// The cubature's break curves (IntegrationOptions::breaks) against exact bin probabilities: a pdf uniform on
// a tilted hemisphere {w . n > 0} jumps to 0 on a great circle that crosses the sphere bins obliquely. The
// exact probability of a bin is its area inside the hemisphere over 2 pi: on the meridian phi the
// hemisphere is z > z*(phi) = -c / sqrt(c^2 + nz^2), c = nx cos phi + ny sin phi, so the area is the
// integral over phi of the z-length above z*, a smooth function between the phi where z* meets the bin's
// edges (found in closed form), integrated by Gauss-Kronrod to round-off. With the break curve every bin
// meets the cubature's own tolerance; without it the error is 200 times larger for 25 times the work (the
// negative control). The root finder on the cut lines is TOMS 748 (cubature.cpp): against the Illinois
// regula falsi it replaced, the worst bin error is the same (4.271635e-10 over the 162 bins, set by the
// outer rule, not by the roots) for 554985 evaluations instead of 565039.
#include "stats/binning.h"

#include <boost/math/quadrature/gauss_kronrod.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_cubature_breaks {

using namespace microsim;

namespace {

constexpr double kTwoPi = 2 * kPi<double>;

// Area of the sphere bin [z_lo, z_hi] x [p0, p1] inside {w . n > 0} (n unit, nz > 0).
double exact_area(const Vec3<double>& n, double z_lo, double z_hi, double p0, double p1) {
  const double R = std::hypot(n.x(), n.y()), phi_n = std::atan2(n.y(), n.x());
  auto z_star = [&](double phi) {
    const double c = n.x() * std::cos(phi) + n.y() * std::sin(phi);
    return -c / std::sqrt(c * c + n.z() * n.z());
  };
  auto length = [&](double phi) { return std::clamp(z_hi - std::max(z_lo, z_star(phi)), 0.0, z_hi - z_lo); };
  // The phi where z*(phi) meets z_lo or z_hi: c = -z nz / sqrt(1 - z^2), c = R cos(phi - phi_n).
  std::vector<double> pieces = {p0, p1};
  for (double z : {z_lo, z_hi}) {
    if (!(std::abs(z) < 1)) continue;
    const double q = -z * n.z() / std::sqrt(1 - z * z) / R;
    if (std::abs(q) > 1) continue;
    for (double sign : {-1.0, 1.0})
      for (int turn = -1; turn <= 1; ++turn) {
        const double phi = phi_n + sign * std::acos(q) + turn * kTwoPi;
        if (phi > p0 && phi < p1) pieces.push_back(phi);
      }
  }
  std::sort(pieces.begin(), pieces.end());
  double area = 0;
  for (std::size_t k = 0; k + 1 < pieces.size(); ++k)
    area += boost::math::quadrature::gauss_kronrod<double, 31>::integrate(length, pieces[k], pieces[k + 1], 8, 1e-13);
  return area;
}

struct Outcome {
  double worst_error = 0;  // max over bins of |probability - exact|
  bool every_bin_within_tolerance = true;
  long long evaluations = 0;
};

Outcome integrate_tilted_hemisphere(bool with_break) {
  const Vec3<double> n = direction_from_degrees<double>(35, 70).normalized();
  const DirectionBinning binning = DirectionBinning::sphere(9);
  auto pdf = [&](const Vec3<double>& w) { return w.dot(n) > 0 ? 1 / kTwoPi : 0.0; };
  IntegrationOptions options;
  if (with_break) options.breaks = {[&](const Vec3<double>& w) { return w.dot(n); }};
  const BinIntegrals got = binning.integrate(pdf, options);
  Outcome out;
  out.evaluations = got.evaluations;
  const double dz = 2.0 / binning.rows(), dphi = kTwoPi / binning.cols();
  for (int bin = 0; bin < binning.size(); ++bin) {
    const int row = bin / binning.cols(), col = bin % binning.cols();
    const double z_hi = 1 - row * dz, z_lo = row == binning.rows() - 1 ? -1.0 : 1 - (row + 1) * dz;
    const double exact = exact_area(n, z_lo, z_hi, col * dphi, (col + 1) * dphi) / kTwoPi;
    const double error = std::abs(got.probability[bin] - exact);
    out.worst_error = std::max(out.worst_error, error);
    if (!(error <= std::max(options.abs_tolerance, options.rel_tolerance * exact))) out.every_bin_within_tolerance = false;
  }
  return out;
}

}  // namespace

TEST(CubatureBreaks, TiltedHemisphereBinsMatchTheirExactAreas) {
  const Outcome with = integrate_tilted_hemisphere(true);
  RecordProperty("worst_error", std::to_string(with.worst_error));
  RecordProperty("evaluations", std::to_string(with.evaluations));
  EXPECT_TRUE(with.every_bin_within_tolerance);
  EXPECT_LT(with.worst_error, 1e-9);
  std::printf("with the break curve: worst bin error %.6e, %lld evaluations\n", with.worst_error, with.evaluations);

  const Outcome without = integrate_tilted_hemisphere(false);  // negative control: the jump inside cells
  std::printf("without it: worst bin error %.3g, %lld evaluations\n", without.worst_error, without.evaluations);
  EXPECT_GT(without.worst_error, 100 * with.worst_error);
  EXPECT_GT(without.evaluations, 10 * with.evaluations);
}

}  // namespace test_cubature_breaks
