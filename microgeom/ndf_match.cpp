#include "microgeom/ndf_match.h"

#include "microgeom/surface_stats.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace microgeom {

namespace {

template <class F> void parallel_range(std::size_t n, F&& f) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1 << 14),
                    [&](const tbb::blocked_range<std::size_t>& r) { f(r.begin(), r.end()); });
}

// Radius of the lobe parameter-space height z = 1 / sqrt(1 + r^2) (z = 0: infinity).
double radius_of_z(double z) {
  if (!(z > 0)) return std::numeric_limits<double>::infinity();
  return std::sqrt(std::max(0.0, 1.0 / (z * z) - 1.0));
}

}  // namespace

double reference_radius_partial_mean(NdfKind ref, double r) {
  if (!(r > 0)) return 0.0;
  if (ref == NdfKind::ggx) {
    if (std::isinf(r)) return std::numbers::pi / 2;
    return std::atan(r) - r / (1.0 + r * r);
  }
  const double half_sqrt_pi = 0.5 * std::sqrt(std::numbers::pi);
  if (std::isinf(r)) return half_sqrt_pi;
  return half_sqrt_pi * std::erf(r) - r * std::exp(-r * r);
}

LobeNdfBins::LobeNdfBins(int rows) : rows_(rows) {
  if (rows < 1) throw std::invalid_argument("lobe bins need at least one row");
}

int LobeNdfBins::bin_of(double ux, double uy) const {
  const double z = 1.0 / std::sqrt(1.0 + ux * ux + uy * uy);
  double phi = std::atan2(-uy, -ux);
  if (phi < 0) phi += kTwoPi;
  const int row = std::clamp(int(std::floor((1.0 - z) * rows_)), 0, rows_ - 1);
  const int col = std::clamp(int(std::floor(phi / (kTwoPi / cols()))), 0, cols() - 1);
  return row * cols() + col;
}

std::vector<double> LobeNdfBins::probabilities(NdfKind ref) const {
  std::vector<double> p(static_cast<std::size_t>(size()));
  for (int row = 0; row < rows_; ++row) {
    const double z_hi = 1.0 - double(row) / rows_, z_lo = row + 1 == rows_ ? 0.0 : 1.0 - double(row + 1) / rows_;
    const double mass = reference_radius_cdf(ref, radius_of_z(z_lo)) - reference_radius_cdf(ref, radius_of_z(z_hi));
    for (int col = 0; col < cols(); ++col) p[std::size_t(row * cols() + col)] = mass / cols();
  }
  return p;
}

std::vector<double> LobeNdfBins::row_mean_radius(NdfKind ref) const {
  std::vector<double> mean(std::size_t(rows_), 0.0);
  for (int row = 0; row < rows_; ++row) {
    const double z_hi = 1.0 - double(row) / rows_, z_lo = row + 1 == rows_ ? 0.0 : 1.0 - double(row + 1) / rows_;
    const double r_lo = radius_of_z(z_hi), r_hi = radius_of_z(z_lo);
    const double mass = reference_radius_cdf(ref, r_hi) - reference_radius_cdf(ref, r_lo);
    const double moment = reference_radius_partial_mean(ref, r_hi) - reference_radius_partial_mean(ref, r_lo);
    mean[std::size_t(row)] = mass > 0 ? moment / mass : 0.0;
  }
  return mean;
}

std::vector<std::array<double, 2>> LobeNdfBins::first_moments(NdfKind ref) const {
  std::vector<std::array<double, 2>> m(static_cast<std::size_t>(size()));
  const std::vector<double> p = probabilities(ref), rbar = row_mean_radius(ref);
  const double dphi = kTwoPi / cols();
  for (int row = 0; row < rows_; ++row)
    for (int col = 0; col < cols(); ++col) {
      const std::size_t b = std::size_t(row * cols() + col);
      // Nh's azimuth phi has u along -(cos phi, sin phi); the sector mean of that direction:
      const double p0 = col * dphi, p1 = (col + 1) * dphi;
      const double cx = -(std::sin(p1) - std::sin(p0)) / dphi, cy = (std::cos(p1) - std::cos(p0)) / dphi;
      const double row_moment = p[b] * rbar[std::size_t(row)];  // E[r 1{row, sector}]
      m[b] = {row_moment * cx, row_moment * cy};
    }
  return m;
}

// ---- the joint target ----------------------------------------------------------------------------------------

namespace {

// Angle of u in [0, 2 pi) as a float (0 for u = 0).
float angle_of(float ux, float uy) {
  double a = std::atan2(double(uy), double(ux));
  if (a < 0) a += kTwoPi;
  return std::min(float(a), std::nextafter(float(kTwoPi), 0.0f));
}

// Sorts by angle; writes the uniform target angle (into my) and the angle stratum of every triangle.
void assign_angles(const std::vector<float>& ux, const std::vector<float>& uy, std::vector<float>& my,
                   std::vector<std::uint64_t>& keys, std::vector<std::uint64_t>& scratch,
                   std::vector<std::uint16_t>& stratum, int strata) {
  const std::size_t n = ux.size();
  keys.resize(n);
  parallel_range(n, [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b; k < e; ++k) keys[k] = sort_key(angle_of(ux[k], uy[k]), std::uint32_t(k));
  });
  detail::radix_sort_by_high32(keys, scratch);
  const std::size_t per_stratum = n / std::size_t(strata);
  parallel_range(n, [&](std::size_t b, std::size_t e) {
    for (std::size_t rank = b; rank < e; ++rank) {
      const std::uint32_t k = std::uint32_t(keys[rank]);
      my[k] = float(kTwoPi * (double(rank) + 0.5) / double(n));
      stratum[k] = std::uint16_t(rank / per_stratum);
    }
  });
}

// Sorts by radius; within each stratum (in radius order) the reference quantile of the rank (into mx).
void assign_radii(const std::vector<float>& ux, const std::vector<float>& uy, NdfKind ref,
                  std::vector<float>& mx, std::vector<std::uint64_t>& keys, std::vector<std::uint64_t>& scratch,
                  const std::vector<std::uint16_t>& stratum, int strata) {
  const std::size_t n = ux.size();
  parallel_range(n, [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b; k < e; ++k) keys[k] = sort_key(std::sqrt(ux[k] * ux[k] + uy[k] * uy[k]), std::uint32_t(k));
  });
  detail::radix_sort_by_high32(keys, scratch);
  const double per_stratum = double(n / std::size_t(strata));
  std::vector<std::uint32_t> seen(std::size_t(strata), 0);
  for (std::size_t rank = 0; rank < n; ++rank) {  // sequential: the within-stratum ranks
    const std::uint32_t k = std::uint32_t(keys[rank]);
    const double q = double(++seen[stratum[k]]) / (per_stratum + 1.0);
    mx[k] = float(reference_radius_quantile(ref, q));
  }
}

}  // namespace

void match_joint_target(const std::vector<float>& ux, const std::vector<float>& uy, NdfKind ref,
                        std::vector<float>& mx, std::vector<float>& my, std::vector<std::uint64_t>& keys,
                        std::vector<std::uint64_t>& scratch, std::vector<std::uint16_t>& stratum) {
  const std::size_t n = ux.size();
  const int strata = n % kJointAngleStrata == 0 ? kJointAngleStrata : 1;
  stratum.resize(n);
  mx.resize(n);
  my.resize(n);
  assign_angles(ux, uy, my, keys, scratch, stratum, strata);
  assign_radii(ux, uy, ref, mx, keys, scratch, stratum, strata);
  parallel_range(n, [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b; k < e; ++k) {
      const double radius = mx[k], angle = my[k];
      mx[k] = float(radius * std::cos(angle));
      my[k] = float(radius * std::sin(angle));
    }
  });
}

// ---- the NDF error in lobe bins ------------------------------------------------------------------------------

LobeNdfError lobe_ndf_error(const std::vector<float>& ux, const std::vector<float>& uy, NdfKind ref, int rows) {
  const LobeNdfBins bins(rows);
  LobeNdfError e;
  e.rows = rows;
  e.bins = bins.size();
  e.triangles = ux.size();
  if (ux.empty()) return e;
  std::vector<std::uint64_t> counts(std::size_t(bins.size()), 0);
  for (std::size_t k = 0; k < ux.size(); ++k) ++counts[std::size_t(bins.bin_of(ux[k], uy[k]))];
  const std::vector<double> p = bins.probabilities(ref);
  const double n = double(ux.size());
  double tv = 0, noise = 0;
  for (std::size_t b = 0; b < p.size(); ++b) {
    tv += std::abs(double(counts[b]) / n - p[b]);
    const double per_ray = std::sqrt(2.0 * p[b] * (1.0 - p[b]) / std::numbers::pi);
    noise += per_ray;
    if (p[b] * n >= 100) e.max_rel_error = std::max(e.max_rel_error, std::abs(double(counts[b]) / (p[b] * n) - 1.0));
  }
  e.total_variation = 0.5 * tv;
  e.iid_noise_tv = 0.5 * noise / std::sqrt(n);
  if (e.total_variation > 0) e.resolving_rays = std::pow(0.5 * noise / e.total_variation, 2.0);
  return e;
}

}  // namespace microgeom
