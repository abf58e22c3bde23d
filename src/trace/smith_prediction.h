// microsim: what Smith's masking model predicts for a heightfield, two ways (design note section 3):
//
// 1. AnalyticSmith: Smith with the surface's NOMINAL analytic NDF, GGX or Beckmann.
//    - GGX: microsim::GGX (Walter 2007 eq. 33-34; Heitz 2014 eq. 86 and 99).
//    - Beckmann: D(m) = exp(-(sx^2/ax^2 + sy^2/ay^2)) / (pi ax ay mz^4) with slopes s = -m_xy / mz
//      (Walter 2007 eq. 25), Lambda(w) = (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)),
//      a = 1 / (alpha(phi) tan theta), alpha(phi)^2 = cos^2 phi ax^2 + sin^2 phi ay^2 (Walter 2007 eq. 27,
//      anisotropic form Heitz 2014 eq. 83), evaluated as (exp(-a^2) / (a sqrt(pi)) - erfc(a)) / 2.
// 2. EmpiricalSmith: Smith with the surface's OWN measured NDF, i.e. its triangle slopes. For a
//    heightfield with slope distribution P(s), Smith's Lambda is (Heitz 2014 JCGT 3(2), eq. 72 with the
//    NDF written in slope space)
//        Lambda(w) = (1 / mu) E[(s_w - mu)+],   mu = cot(theta_w),   s_w = s . (cos phi_w, sin phi_w),
//    which for unit w is  Lambda(w) = E[(s . w_xy - w_z)+] / w_z  (every triangle of the regular split has
//    the same projected area, so E is the plain mean over triangles). With this Lambda,
//        G1_emp(w) = 1 / (1 + Lambda(w)) = w_z / A(w),   A(w) = E[(w_z - s . w_xy)+]
//    (the projected area per unit base area, because E[s] = 0 exactly on a periodic tile): Smith with
//    the empirical NDF reproduces the surface's scalar G1 EXACTLY (design note sec. 3), so any measured
//    deviation from it is a masking-model error, not an NDF error. Its VNDF is the area-weighted
//    histogram of the facets, weight <w, m>+ / mz per triangle.
//    Smith's height-dependent masking uses the surface's own height distribution C1 (the empirical CDF
//    of the vertex heights): G1(w, h) = C1(h)^Lambda(w) (Heitz 2014 eq. 88 / Smith 1967).
//
// Sums over triangles are parallel (TBB) and deterministic: per fixed block of rows, then added in order.
#pragma once

#include "core/ndf_kind.h"
#include "microgeom/heightfield.h"
#include "stats/binning.h"
#include "microfacet/ggx.h"

#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace microsim {

class AnalyticSmith {
public:
  AnalyticSmith(NdfKind ndf, double alpha_x, double alpha_y);

  NdfKind ndf() const { return ndf_; }
  double alpha_x() const { return ax_; }
  double alpha_y() const { return ay_; }
  std::string describe() const;  // "ggx alpha (0.5, 0.5)"

  // D(m) per unit solid angle and unit base area (0 for mz <= 0).
  double D(const Vec3<double>& m) const;
  // Smith Lambda(w) for w.z > 0 (+inf on the horizon, 0 at the pole).
  double Lambda(const Vec3<double>& w) const;
  double G1(const Vec3<double>& w) const;
  // Height-correlated G2 = 1 / (1 + Lambda(wi) + Lambda(wo)) (Heitz 2014 eq. 99); 0 if either is below
  // the horizon.
  double G2(const Vec3<double>& wi, const Vec3<double>& wo) const;
  double G2_separable(const Vec3<double>& wi, const Vec3<double>& wo) const { return G1(wi) * G1(wo); }
  // D_v(m) = G1(w) <w, m>+ D(m) / w.z (Heitz 2014 eq. 16), per unit solid angle of m.
  double vndf(const Vec3<double>& w, const Vec3<double>& m) const;

private:
  NdfKind ndf_;
  double ax_, ay_;
};

// The analytic reference of a surface: its metadata ("reference_ndf", "alpha_x", "alpha_y", as written by
// microgeom::build_assembly) if present, else GGX with alpha fitted per axis from the median |slope|
// (alpha = sqrt(3) median |s_x|: the GGX slope marginal has P(|s_x| < a) = a / sqrt(alpha^2 + a^2)).
// `source` (if non-null) says which ("metadata" or "fitted"). Metadata that is present but malformed (an
// alpha that is not a whole finite decimal number > 0, a reference_ndf other than ggx or beckmann) throws
// std::invalid_argument naming the attribute and quoting a short excerpt of its value.
AnalyticSmith analytic_reference(const microgeom::Heightfield& field, std::string* source = nullptr);

class EmpiricalSmith {
public:
  // Keeps a reference to `field` (which must outlive this object) and sorts its vertex heights.
  explicit EmpiricalSmith(const microgeom::Heightfield& field);
  ~EmpiricalSmith();

  const microgeom::Heightfield& field() const { return field_; }

  // Exact (one pass over all triangles, in double).
  double Lambda(const Vec3<double>& w) const;
  double G1(const Vec3<double>& w) const { return 1.0 / (1.0 + Lambda(w)); }
  // A(w) = E[(w_z - s . w_xy)+]: projected area of the front-facing facets per unit base area.
  double projected_area(const Vec3<double>& w) const;
  // Height-correlated Smith G2 with the empirical Lambda (exact passes).
  double G2(const Vec3<double>& wi, const Vec3<double>& wo) const;
  // The empirical Smith VNDF's probability of every bin of `binning` seen from w: the share of the
  // front-facing projected area, sum of (w_z - s . w_xy)+ over the triangles whose normal falls in the bin,
  // over the sum over all triangles. Normals outside the binning's parameter space are not counted.
  std::vector<double> vndf_bin_probabilities(const DirectionBinning& binning, const Vec3<double>& w) const;

  // Fast Lambda for many directions (e.g. one per sample): from per-azimuth tables of the projected slope
  // s . (cos phi_k, sin phi_k) at kAzimuths azimuths (kSlopeBins bins in q = s / (1 + s), counts and sums:
  // exact for the bins above mu, linear inside mu's bin), linearly interpolated in azimuth. Built on
  // first use (thread-safe). Relative error against Lambda(): see tests (below 1e-3 for isotropic
  // surfaces away from the horizon).
  double Lambda_tabulated(const Vec3<double>& w) const;
  double G2_tabulated(const Vec3<double>& wi, const Vec3<double>& wo) const;
  static constexpr int kAzimuths = 64;
  static constexpr int kSlopeBins = 2048;

  // Empirical CDF of the vertex heights, C1(z) = #{heights <= z} / N^2.
  double height_cdf(double z) const;
  // The vertex heights, sorted ascending.
  const std::vector<float>& sorted_heights() const { return sorted_heights_; }
  // Smith's masking at height z: C1(z)^Lambda, with a given Lambda.
  static double height_masking(double c1, double lambda);

private:
  struct Tables;
  void build_tables() const;
  const microgeom::Heightfield& field_;
  std::vector<float> sorted_heights_;
  mutable std::once_flag tables_once_;
  mutable std::unique_ptr<Tables> tables_;
};

// Deterministic parallel sum of f(row) over rows [0, n): partial sums per fixed block of rows, added in
// block order (the same bits whatever the thread count).
double deterministic_row_sum(int n, const std::function<double(int)>& f);

}  // namespace microsim
