// microgeom: a heightfield's NDF bin by bin. The radial slope matching of assembly.h makes the
// slope-radius law exact, but a tile's angular law is that of its random start field: exact only in
// expectation, with the sampling noise of the (N / l)^2 independent patches of the tile, which a traced
// VNDF resolves at a few million rays (docs/reference/surfaces.md, section 8). This header holds
// - the lobe bins of `trace vndf` (stats/binning.h, DirectionBinning::lobe) in normalised slope space,
//   with the exact reference probability and first moment of each bin;
// - the joint (radius, angle) target of the slope matching: a stratified slope set of the reference law;
// - the final refinement: vertex-height moves that bring the triangle counts (and the mean normalised
//   slope) of every lobe bin, the counts of fine radius bins and of the sphere bins of `trace vndf`, to the
//   reference law;
// - the error of a field's NDF in the lobe bins, beside the noise of as many independent triangles.
//
// Normalised slope u = (sx / ax, sy / ay); in the lobe parameter space of Heitz 2018 (JCGT 7(4), sec. 2-3)
// a triangle's normal maps to Nh = normalize(-ux, -uy, 1): z = 1 / sqrt(1 + |u|^2), phi = atan2(-uy, -ux).
// Lobe bins: `rows` bands uniform in z in [0, 1] times 2 rows sectors uniform in phi; bin = row cols + col.
// Seen from the normal (theta = 0), the VNDF in these bins is the projected-area NDF of the triangles, so
// a tile whose counts match the reference bin probabilities traces Smith's analytic VNDF at theta = 0, and
// a tile whose per-bin mean slopes match as well traces it at any view whose projected-area weight
// (w_z - s . w_xy)+ stays positive over the bin (that weight is linear in u).
#pragma once

#include "microgeom/assembly.h"

#include <array>
#include <bit>
#include <cstdint>
#include <numbers>
#include <vector>

namespace microgeom {

inline constexpr double kTwoPi = 2.0 * std::numbers::pi;  // the angle range of the lobe bins' sectors

// A rank sort key: a non-negative float's bit pattern orders like the float; the low 32 bits (the index)
// break ties deterministically (the slope matchings of assembly.cpp and ndf_match.cpp sort by it).
inline std::uint64_t sort_key(float nonneg_value, std::uint32_t index) {
  return (std::uint64_t(std::bit_cast<std::uint32_t>(nonneg_value)) << 32) | index;
}

// The rows of the lobe binning of `trace vndf` and `validate` by default (measure/vndf.h, VndfRequest).
inline constexpr int kDefaultLobeRows = 31;

class LobeNdfBins {
public:
  explicit LobeNdfBins(int rows = kDefaultLobeRows);  // rows >= 1
  int rows() const { return rows_; }
  int cols() const { return 2 * rows_; }
  int size() const { return rows_ * cols(); }
  // The bin of a normalised slope (finite).
  int bin_of(double ux, double uy) const;
  // Reference probability of every bin (a row's probability F(r(z_lo)) - F(r(z_hi)), r(z) = sqrt(1/z^2 - 1),
  // F the radius CDF, split evenly among its sectors).
  std::vector<double> probabilities(NdfKind ref) const;
  // E[u 1{u in bin}] of every bin under the reference law: the row's integral of r dF times the sector's
  // mean of -(cos phi, sin phi).
  std::vector<std::array<double, 2>> first_moments(NdfKind ref) const;
  // E[r | row] of the reference law (0 when the row has no mass).
  std::vector<double> row_mean_radius(NdfKind ref) const;

private:
  int rows_;
};

// Integral of r dF(r) from 0 to R for the reference radius law (GGX: atan R - R / (1 + R^2);
// Beckmann: sqrt(pi)/2 erf R - R exp(-R^2)); R = infinity allowed.
double reference_radius_partial_mean(NdfKind ref, double radius);

// ---- the joint target ----------------------------------------------------------------------------------------
// Angle strata of the joint target (a power of two: n = 2 N^2 triangles is a multiple of it for N >= 16).
inline constexpr int kJointAngleStrata = 64;

// One joint matching step (compare match_ggx_marginal in assembly.cpp, which keeps the angles): the
// triangles sorted by the angle of u get the angles 2 pi (rank + 1/2) / n (exactly uniform); the n / S
// triangles of each of the S = kJointAngleStrata angle strata, sorted by radius, get the reference radius
// quantiles of their rank within the stratum, q = (rank + 1) / (n / S + 1). The result is a stratified
// sample of the reference law: uniform angle, the reference radius law in every angle stratum. Ties are
// broken by index (deterministic). `keys`, `scratch`, `stratum` are work buffers.
void match_joint_target(const std::vector<float>& ux, const std::vector<float>& uy, NdfKind ref,
                        std::vector<float>& mx, std::vector<float>& my, std::vector<std::uint64_t>& keys,
                        std::vector<std::uint64_t>& scratch, std::vector<std::uint16_t>& stratum);

// ---- the final refinement ------------------------------------------------------------------------------------
struct NdfRefineOptions {
  int rows = kDefaultLobeRows;  // lobe bins matched
  int radius_bins = 1024;       // radius bins of equal reference probability (the last one split in the tail)
  int max_sweeps = 2;  // measured at 1024^2: the first sweep removes 99% of the discrepancy, later ones ~1-10% each
  double step = 0.03;           // largest move, in normalised slope units (x max(1, |u|) of the steepest neighbour)
};

struct NdfRefineReport {
  int sweeps = 0;
  std::uint64_t moves = 0;            // accepted vertex moves
  double objective_before = 0, objective_after = 0;  // chi-square-like discrepancy (see ndf_match.cpp)
};

// Moves vertex heights (cell units; slopes normalised by ax, ay) one at a time, in row order, each by the
// first of +-step, +-0.3 step, +-0.1 step that lowers the discrepancy
//   sum over lobe bins of ((c - t)^2 + |m - M|^2 / rbar^2) / t  +  sum over radius bins of (c - t)^2 / t
//   + sum over the sphere bins of trace vndf (rows, or rows + 1 if even) of (c - t)^2 / max(t, 5)
// (c, m: triangle count and sum of u in the bin; t, M: their reference values; rbar: the row's mean
// radius; the sphere bins depend on (ax, ay): ndf_refine.cpp, SphereNdfBins); stops after max_sweeps sweeps or when a sweep moves fewer than 1e-4 of the vertices. Sequential:
// the result does not depend on the thread count. `cancelled` is polled between sweeps (throws
// BuildCancelled).
NdfRefineReport refine_binned_ndf(std::vector<double>& h, int n, double ax, double ay, NdfKind ref,
                                  const NdfRefineOptions& options, const BuildCancel& cancelled = {});

// ---- the NDF error in lobe bins ------------------------------------------------------------------------------
struct LobeNdfError {
  int rows = 0, bins = 0;
  std::uint64_t triangles = 0;
  double total_variation = 0;     // 1/2 sum over bins |measured fraction - reference probability|
  double max_rel_error = 0;       // max |measured / expected - 1| over bins expecting >= 100 triangles
  // Expected TV of as many independent triangles drawn from the reference law, 1/2 sum sqrt(2 p (1 - p) / (pi n))
  // (the mean absolute deviation of a binomial fraction, normal approximation).
  double iid_noise_tv = 0;
  // The ray count at which a traced VNDF at theta = 0 starts to resolve this NDF error: the R whose ray
  // noise TV 1/2 sum sqrt(2 p (1 - p) / (pi R)) equals total_variation (0 when the TV is 0).
  double resolving_rays = 0;
};
// From the normalised triangle slopes.
LobeNdfError lobe_ndf_error(const std::vector<float>& ux, const std::vector<float>& uy, NdfKind ref,
                            int rows = kDefaultLobeRows);

}  // namespace microgeom
