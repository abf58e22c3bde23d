// microsim: equal-area direction bins for histograms of sampled or traced directions, and the exact
// probability of each bin under a claimed pdf (adaptive cubature), for chi-square tests.
//
// A binning maps a direction w (a microfacet normal or a reflected direction) to a point u of its
// PARAMETER SPACE, a unit sphere or hemisphere, and bins u in equal-area cells: `rows` bands uniform in
// z = cos(theta) (Archimedes: equal z-widths have equal areas) times `cols` = 2 rows sectors uniform in
// phi. Two parameterizations:
//
// - sphere(rows): u = w; the full sphere, rows odd (the equator z = 0 is then inside the middle band,
//   not a bin edge). Simple and generic, but at small alpha the whole lobe falls into a few bins and the
//   test loses its power.
// - lobe(ggx, wi, domain, rows): follows the GGX lobe. A microfacet normal m is mapped to the normal of
//   the hemisphere configuration of Heitz 2018 ("Sampling the GGX Distribution of Visible Normals",
//   JCGT 7(4), sec. 2-3), u = Nh = normalize(mx / ax, my / ay, mz); a reflected direction wo is first
//   mapped to its half vector m = normalize(wi + wo). u lives on the hemisphere on the side of wi
//   (u.z >= 0 when wi.z >= 0, else u.z <= 0). In this space the VNDF is the clamped cosine
//   2 <Vh, Nh>+ / (pi (1 + Vh.z)) whatever alpha, so every bin keeps a useful expected count.
//
// Bin order: bin = row * cols + col; row 0 is the band at the top of the parameter space (largest z),
// col 0 starts at phi = 0 (the +x axis of the parameter space) and phi grows towards +y.
//
// Probabilities: integrate(pdf) returns, for each bin, the integral over the bin's cell of the claimed
// pdf (per unit solid angle of w), computed in parameter space as the integral over u of
// pdf(w(u)) |dw/du| by adaptive Gauss-Kronrod cubature in (theta, phi) of u. Jacobians:
//   direction map u -> m = normalize(A u), A = diag(ax, ay, 1): |dm/du| = det(A) / |A u|^3
//   (Heitz 2018 sec. 2), and for reflections |dwo/dm| = 4 |wi . m| (Walter et al. 2007, eq. 14).
// A narrow peak (alpha = 1e-3 puts a whole lobe inside one sphere bin) can slip between quadrature
// nodes; IntegrationOptions::focus lists directions where the pdf has mass (lattice_directions() of a
// lobe binning gives a good set) and every cell holding more than a few of them is subdivided before
// the error-driven refinement starts.
#pragma once

#include "microfacet/ggx.h"
#include "microfacet/samplers.h"

#include <nlohmann/json_fwd.hpp>

#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace microsim {

enum class BinningKind { sphere, lobe };

// The most rows a binning may have (every command's --rows; validate and trace check it the same way).
// 501 rows are 502002 bins: the probabilities, counts and figures of one binning stay in memory and the
// cubature of the expected counts finishes in minutes. Bin indices are int: rows * cols = 2 rows^2 must
// fit, and does by far.
inline constexpr int kMaxBinningRows = 501;
static_assert(2LL * kMaxBinningRows * kMaxBinningRows <= 2147483647LL, "bin indices are int");

// Bounds of a bin in its own parameter space (degrees; theta from the parameter space's +z).
struct BinBounds {
  double theta_min_deg, theta_max_deg;
  double phi_min_deg, phi_max_deg;
};

struct IntegrationOptions {
  // Per-bin stopping rule: error estimate <= max(abs_tolerance, rel_tolerance * |integral|).
  double abs_tolerance = 1e-10;
  double rel_tolerance = 1e-7;
  // Error-driven refinement budget per bin (cell splits after the focus phase); bins with a
  // discontinuity of the pdf inside may hit it, their error estimate is then reported in
  // BinIntegrals::error_estimate.
  int max_cells_per_bin = 1024;
  // Directions (in the sample domain) where the pdf has mass: cells holding more than
  // max_focus_per_cell of them are split before the adaptive phase (down to min_cell_size radians).
  std::vector<Vec3<double>> focus;
  int max_focus_per_cell = 4;
  double min_cell_size = 1e-9;
  // Parameter-space heights z where the pdf may jump (e.g. the equator for normals): every band that
  // straddles one is integrated in two pieces, so the jump falls on a cell edge.
  std::vector<double> z_breaks;
  // Functions of the direction whose zero set is a curve where the pdf jumps (or has a kink), e.g. the
  // boundary of a sampler's support: on every theta line of a cell where one changes sign, the line is
  // integrated piecewise between the roots (TOMS 748, Alefeld, Potra & Shi 1995), so the jump no longer
  // costs refinement.
  std::vector<std::function<double(const Vec3<double>&)>> breaks;
  // Second pass, for lobes the first one cannot resolve (alpha 1e-4 seen at 89.99 deg,
  // reflected directions, where the lobe is a wedge 1e-4 long and alpha |wi + wo| wide ending at -wi).
  // When the per-bin error estimates add up to more than second_pass_total_error, every bin that missed
  // its tolerance is integrated again with focus + second_pass_focus, and after the budget above with
  // up to max_directed_cells_per_bin more splits, each along the side whose rule error dominates.
  // Infinity (the default) disables it; bins that met their tolerance are never integrated again.
  double second_pass_total_error = std::numeric_limits<double>::infinity();
  std::vector<Vec3<double>> second_pass_focus;
  int max_directed_cells_per_bin = 16384;
};

struct BinIntegrals {
  std::vector<double> probability;  // per bin
  double total = 0;                 // sum over bins
  double error_estimate = 0;        // sum of the per-bin error estimates
  long long evaluations = 0;        // pdf evaluations
  int second_pass_bins = 0;         // bins integrated again (IntegrationOptions::second_pass_total_error)
};

class DirectionBinning {
public:
  // Full sphere, u = w. rows must be odd, in [1, kMaxBinningRows] (throws std::invalid_argument otherwise).
  static DirectionBinning sphere(int rows);
  // The full sphere, u = w, with the equator as a bin edge: 2 rows_per_hemisphere rows, the first half in
  // the upper hemisphere (reflection), the second in the lower (transmission). For scattered directions
  // (stats/scatter_histogram.h); its description's kind is "hemispheres". rows_per_hemisphere in
  // [1, kMaxBinningRows / 2].
  static DirectionBinning hemispheres(int rows_per_hemisphere);
  // The lobe-following parameterization (see above) for samples in `domain` seen from wi (unit).
  // rows in [1, kMaxBinningRows] (throws std::invalid_argument otherwise).
  static DirectionBinning lobe(const GGX<double>& ggx, const Vec3<double>& wi, SampleDomain domain, int rows);
  // Rebuilds a binning from describe(); throws std::invalid_argument on a malformed description.
  static DirectionBinning from_description(const nlohmann::json& description);

  BinningKind kind() const { return kind_; }
  int rows() const { return rows_; }
  int cols() const { return 2 * rows_; }
  int size() const { return rows_ * cols(); }
  // z range of the parameter space: [-1, 1] (sphere), [0, 1] or [-1, 0] (lobe).
  double z_min() const { return z_min_; }
  double z_max() const { return z_max_; }
  std::string name() const { return kind_ == BinningKind::sphere ? "sphere" : "lobe"; }

  // The parameter-space point of a direction (normalised first); nullopt for a zero or non-finite
  // direction, or one outside the parameter space (e.g. a normal on the far side for lobe bins).
  std::optional<Vec3<double>> to_param(const Vec3<double>& direction) const;
  // The direction (in the sample domain) of a parameter-space point, and |dw/du| there.
  Vec3<double> from_param(const Vec3<double>& u) const;
  double jacobian(const Vec3<double>& u) const;

  // The bin of a direction; nullopt when to_param() is nullopt.
  std::optional<int> bin_of(const Vec3<double>& direction) const;
  BinBounds bounds(int bin) const;
  // Bin center in its parameter space (degrees): the middle of its z range and phi range.
  double center_theta_deg(int bin) const;
  double center_phi_deg(int bin) const;
  // "theta 12.3..15.6 phi 0.0..5.8 (lobe)" for reports.
  std::string describe_bin(int bin) const;

  // Probability of every bin under pdf (per unit solid angle of the sample direction; must be safe to
  // call concurrently). Parallel over bins (TBB); deterministic. Defined in cubature.cpp.
  std::vector<double> integrate(const std::function<double(const Vec3<double>&)>& pdf) const;
  BinIntegrals integrate(const std::function<double(const Vec3<double>&)>& pdf, const IntegrationOptions& options) const;

  // n directions (sample domain) of a Fibonacci lattice uniform over the parameter space: for a lobe
  // binning they cover the lobe densely wherever it has mass; use them as IntegrationOptions::focus.
  std::vector<Vec3<double>> lattice_directions(int n) const;
  // For a lobe binning: directions of parameter-space points graded toward the visible edge, the circle
  // u . v = 0 of the stretched view v = normalize(ax wi.x, ay wi.y, wi.z): `rings` circles at angles
  // 0.5 * 2^(-k/4) (k = 0 .. rings - 1) inside it, `per_ring` points each. For reflected directions the
  // whole edge maps to wo = -wi, where the lobe narrows to a point: use them as second-pass focus there.
  std::vector<Vec3<double>> visible_edge_directions(int rings, int per_ring) const;

  // Everything needed to rebuild the binning (kind, rows, cols, and for lobe bins alpha, wi, domain),
  // plus a human-readable statement of the bin order.
  nlohmann::json describe() const;

private:
  DirectionBinning() = default;
  BinningKind kind_ = BinningKind::sphere;
  int rows_ = 1;
  double z_min_ = -1, z_max_ = 1;
  // lobe only
  double ax_ = 1, ay_ = 1;
  Vec3<double> wi_ = Vec3<double>(0, 0, 1);
  SampleDomain domain_ = SampleDomain::microfacet_normal;
};

// Inline: the cubature (cubature.cpp) calls them at every node.
inline Vec3<double> DirectionBinning::from_param(const Vec3<double>& u) const {
  if (kind_ == BinningKind::sphere) return u;
  const Vec3<double> m = normalized_or_zero(Vec3<double>(ax_ * u.x(), ay_ * u.y(), u.z()));
  if (domain_ == SampleDomain::microfacet_normal) return m;
  return reflect(wi_, m);
}

inline double DirectionBinning::jacobian(const Vec3<double>& u) const {
  if (kind_ == BinningKind::sphere) return 1.0;
  const Vec3<double> au(ax_ * u.x(), ay_ * u.y(), u.z());
  const double len = au.norm();
  if (!(len > 0)) return 0.0;
  // |dm/du| = det(A) / |A u|^3 (the direction map u -> normalize(A u)).
  double j = ax_ * ay_ / (len * len * len);
  if (domain_ == SampleDomain::reflected_direction) {
    // |dwo/dm| = 4 |wi . m| for wo = reflect(wi, m). The half vector of wi and wo always faces wi, so a
    // u whose m faces away from wi is the image of no direction: its cell measure is 0.
    const double wm = wi_.dot(au / len);
    if (!(wm > 0)) return 0.0;
    j *= 4 * wm;
  }
  return j;
}

// phi = atan2(u.y, u.x) of a parameter-space point, in [0, 2 pi) (0 at the poles): the column coordinate.
double param_phi(const Vec3<double>& u);

std::string to_string(SampleDomain domain);
// Parses "microfacet_normal" or "reflected_direction"; throws std::invalid_argument otherwise.
SampleDomain sample_domain_from_string(const std::string& s);

}  // namespace microsim
