// microgeom: measured statistics of a heightfield: its NDF against an analytic reference (GGX or
// Beckmann), slope and height statistics, and how strongly heights are tied to facet slopes.
//
// The NDF is measured from the triangles (design note sec. 5): every triangle of the regular split has the
// same projected area, so the histogram of triangle slopes with equal weights is the slope density P22,
// i.e. D(m) weighted by projected area. Everything is done in normalised slope space,
// u = (sx/ax, sy/ay), where the reference law is isotropic with alpha = 1:
//   GGX:      P(|u| <= R) = R^2 / (1 + R^2),   quantile sqrt(q / (1 - q))      (Heitz 2014 eq. 39)
//   Beckmann: P(|u| <= R) = 1 - exp(-R^2),     quantile sqrt(-log(1 - q))      (slopes N(0, alpha^2/2))
// and the angle of u is uniform.
#pragma once

#include "microgeom/assembly.h"
#include "microgeom/heightfield.h"
#include "microgeom/ndf_match.h"

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace microgeom {

double reference_radius_cdf(ReferenceNdf ref, double radius);
double reference_radius_quantile(ReferenceNdf ref, double q);

// Histogram layout: 40 radius bins of equal reference probability; 4 rings (radius quartiles) x 8
// angle sectors = 32 (radius, angle) bins of equal reference probability.
inline constexpr int kRadiusBins = 40;
inline constexpr int kRingBins = 4, kAngleBins = 8, kAngularBins = kRingBins * kAngleBins;

// Bound on how far a built surface may miss its NDF (a build that exceeds it fails).
struct NdfTolerance {
  double quantile = 0.03;     // max |relative error| of the slope-radius quantiles for q in [0.01, 0.999]
  double radius_bin = 0.03;   // max |relative error| of the radius bins
  double angular_bin = 0.05;  // max |relative error| of the (radius, angle) bins
};

// n_eff = (N / l)^2: the number of independent patches of a random field on the tile.
double effective_patches(int resolution, double corr_cells);
// Noise factors of tolerance_for (calibrated over seeds; see docs/reference/surfaces.md).
inline constexpr double kAngularNoiseFactor = 5.0;
inline constexpr double kBeckmannQuantileNoiseFactor = 8.0;
inline constexpr double kBeckmannRadiusNoiseFactor = 3.0;

// The stated tolerance of an assembly's surface: the fixed NdfTolerance{} bounds, widened where a single
// tile cannot do better than sampling noise: the angular bins of every assembly (their angular law is that
// of a Gaussian start field, exact only in expectation), and all bounds of the Beckmann control (a
// Gaussian field whose slope law is exact pointwise but whose histogram fluctuates): max(fixed bound,
// factor x sqrt(bins / n_eff)) (quantiles: factor / sqrt(n_eff)).
NdfTolerance tolerance_for(ReferenceNdf ref, int resolution, double corr_cells);

struct StatsOptions {
  ReferenceNdf reference = ReferenceNdf::ggx;
  // Normalising roughness; unset -> fitted from the slopes (GGX: alpha = sqrt(3) median |s| per axis;
  // Beckmann: alpha = sqrt(2) median |s| / 0.67449).
  std::optional<double> alpha_x, alpha_y;
  NdfTolerance tolerance;
};

struct QuantileRow {
  double q, measured, expected, rel_error;
};
struct BinRow {
  double lo, hi;  // normalised radius range of the bin
  double expected_fraction, measured_fraction, rel_error;
};

struct SurfaceStats {
  std::size_t triangles = 0;
  ReferenceNdf reference = ReferenceNdf::ggx;
  double alpha_x = 0, alpha_y = 0;  // normalisation used
  bool alpha_fitted = false;
  double fitted_alpha_x = 0, fitted_alpha_y = 0;  // from the median |slope| per axis, for the reference

  // NDF against the reference.
  std::vector<QuantileRow> quantiles;   // q in {0.01, 0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.95, 0.99, 0.995, 0.999, 0.9999}
  std::vector<BinRow> radius_bins;      // kRadiusBins bins of equal reference probability
  double max_quantile_error = 0;        // over q in [0.01, 0.999]
  double max_radius_bin_error = 0;
  double max_angular_bin_error = 0;     // over the kAngularBins (radius, angle) bins
  double max_normalised_radius = 0;
  std::array<double, kAngularBins> angular_bin_errors{};  // ring-major: ring * kAngleBins + sector
  NdfTolerance tolerance;
  bool ndf_within_tolerance = false;
  std::string ndf_verdict;  // "ok" or which bound was exceeded and by how much
  // The NDF error in the lobe bins of `trace vndf` (kDefaultLobeRows rows; ndf_match.h), beside the noise
  // of as many independent triangles and the ray count that resolves it. Reported, not checked.
  LobeNdfError lobe;

  // Slopes (physical): mean, rms per axis; second moment of the normalised slopes per axis.
  double mean_slope_x = 0, mean_slope_y = 0, rms_slope_x = 0, rms_slope_y = 0;
  double normalised_second_moment_x = 0, normalised_second_moment_y = 0;

  // Heights (vertex heights, physical units).
  double height_mean = 0, height_sd = 0, height_min = 0, height_max = 0, height_skewness = 0,
         height_excess_kurtosis = 0;
  double tile_size = 0, cell_size = 0;

  // Height-slope coupling, per triangle (centroid height, normalised slope radius):
  double spearman_height_slope = 0;     // Spearman rank correlation of height and slope radius
  double spearman_extremity_slope = 0;  // of |height - median height| and slope radius
  double steepest_1pct_height_z = 0;    // mean height of the steepest 1% of triangles, in height sd
  double steepest_01pct_height_z = 0;   // same for the steepest 0.1%
};

SurfaceStats measure_surface(const Heightfield& field, const StatsOptions& options);

}  // namespace microgeom
