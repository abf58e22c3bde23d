// microsim: what an explicit heightfield does, measured by ray tracing (design note sections 3 and 5):
// its visible normals, its masking conditioned on the facet normal and on height, and its
// masking-shadowing G2, each beside Smith's predictions with the analytic NDF and with the surface's own
// measured NDF (smith_prediction.h).
//
// VNDF: rays along -v from uniform (x, y) above the maximum height; the first-hit facet normals are
// histogrammed exactly like the ellipsoid oracle's (trace_vndf.h), same TraceResult.
//
// Masking, by surface points. A point p on triangle m has the weight w = <v, m>+ / m_z, the projected
// area toward v per unit base area, and a shadow ray from p toward v (HeightfieldScene::escapes, start
// triangle skipped) says whether p is visible, V in {0, 1}. Two equivalent samplings:
// - uniform: (x, y) uniform over the tile (every triangle has the same projected area), each sample
//   weighted by w: the estimators are ratios sum(w V) / sum(w). Simple, but w is heavy-tailed (for GGX
//   slopes its variance diverges logarithmically: w grows like |slope| on steep facets facing v), so the
//   standard errors are large and slow to settle at grazing views.
// - projected (default): triangles drawn with probability proportional to their w (a CDF over all
//   triangles, built per view), the point uniform on the triangle: the samples are uniform over the
//   projected area seen from v and every estimator is a plain (binomial-like) mean of V. Same expectations.
// Estimated quantities (written for uniform sampling; E_w is the w-weighted mean):
//   leak ratio   E[w V] / v_z = 1 exactly for ANY heightfield (the visible surface projects onto the base
//                exactly once): the leak and wrap-around test. Uniform: sample mean of w V / v_z;
//                projected: G1 * A(v) / v_z with the exact A(v) = E[w] over all triangles.
//   G1(v)        = E_w[V]: the visible fraction of the front-facing projected area; Smith with the
//                empirical NDF predicts it exactly (v_z / A(v)), so this is the leak test again.
//   G1(v | m)    E_w[V] over facets whose <v, m> lies in one of `normal_bins` bins that each hold an
//                equal share of the front-facing projected area (exact quantiles over all triangles): the
//                first bin holds the most grazing facets, the last those facing v.
//                Smith: G1(v | m) = G1(v) for every front-facing m.
//   G1(v | near-grazing m)  the same over the facets with the smallest <v, m> that hold the bottom
//                `grazing_share` (default 2%) of the front-facing projected area (exact quantile over all
//                triangles): a finer near-grazing class than the first of the `normal_bins` bins. Its
//                angle(m, v) range is reported (at 75-85 deg views it starts at 81-85 deg for alpha 0.5-1
//                and 88 deg for alpha 0.1, where the first decile starts at 70-80 deg and 79-86 deg).
//                Smith: ratio 1.
//   G1(v | h)    over points whose height lies in one of `height_bins` equal-count bins of the vertex
//                heights. Smith: E_w[C1(h)^Lambda(v) | bin] with the surface's height CDF C1.
//   G2 mirror    l = reflect(v, m) per sample: E_w[V_v V_l] (V_l = 0 when l is below the horizon), the
//                fraction of mirror-reflected light that is neither masked nor shadowed.
//                Smith: E_w[G2(v, l)], height-correlated (and separable), both NDFs.
//   G2 pair      for a fixed light l: E_w[V_v V_l] over facets facing both v and l; and the same
//                restricted to facets within `cone_deg` of the half vector (the mirror configuration of
//                that pair). Smith: G2(v, l) height-correlated (and separable).
// Standard errors: the delta method for ratio estimators (Cochran 1977, "Sampling Techniques", sec. 6.4),
// Var(R) ~ sum (y - R x)^2 / (sum x)^2, and for ratios of ratios from the same samples the linearised
// covariance. Determinism: samples in blocks of kSamplesPerBlock, block b from CounterRng(seed, b); block
// sums are added exactly (MaskingSums), so results are identical whatever the threads, and the sums of a
// run's shards add up to the single run's bit for bit (measure/masking.h merges them).
#pragma once

#include "core/estimate.h"

#include "core/exact_sum.h"
#include "core/run_control.h"
#include "stats/binning.h"
#include "trace/heightfield_trace.h"
#include "trace/smith_prediction.h"
#include "trace/trace_vndf.h"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace microsim {

inline constexpr std::uint64_t kSamplesPerBlock = 4096;

// ---- VNDF --------------------------------------------------------------------------------------------------

struct HeightfieldVndfDiagnostics {
  std::uint64_t backfacing = 0;  // first hits on a facet facing away from v (left out of the histogram;
                                 // after the convex-edge pass-over of HeightfieldScene::trace, never seen)
  std::uint64_t edge_grazes = 0; // rays that passed within float precision over a convex edge (their
                                 // reported hit is the next front-facing one; heightfield_trace.h)
  std::uint64_t leaked = 0, unresolved = 0;
};

// Traces options.rays rays along -wi (wi.z > 0) from uniform points above the tile and histograms the
// first-hit normals in every binning. Same result type as the ellipsoid oracle (trace_vndf.h); hits =
// front-facing first hits. Throws std::invalid_argument for wi.z <= 0 or rays == 0.
TraceResult trace_vndf_heightfield(const HeightfieldScene& scene, const Vec3<double>& wi,
                                   std::span<const DirectionBinning> binnings, const TraceOptions& options,
                                   HeightfieldVndfDiagnostics* diagnostics = nullptr);

// A traced VNDF histogram against Smith's, with both NDFs.
struct VndfComparison {
  std::string binning;                 // "sphere" or "lobe"
  int bins = 0;
  double tv_analytic = 0;              // total variation to Smith's D_v with the analytic NDF
  double tv_empirical = 0;             // ... with the surface's own NDF (masking-model error only)
  double tv_noise = 0;                 // expected TV of a histogram drawn from the empirical Smith VNDF
                                       // itself (multinomial noise floor): 1/2 sum sqrt(2 p (1-p) / (pi n))
  double p_value_analytic = 1, p_value_empirical = 1;  // chi-square goodness of fit (pooled, chi2.h)
  double chi2_analytic = 0, chi2_empirical = 0;
  int dof_analytic = 0, dof_empirical = 0;
  std::vector<double> p_analytic, p_empirical;  // bin probabilities
};
VndfComparison compare_vndf(const std::vector<std::uint64_t>& counts, std::uint64_t unbinned,
                            const DirectionBinning& binning, const Vec3<double>& v, const AnalyticSmith& analytic,
                            const EmpiricalSmith& empirical);

// ---- masking by surface points -----------------------------------------------------------------------------

enum class PointSampling { projected, uniform };

struct MaskingOptions {
  std::uint64_t samples = 1'000'000;  // surface points
  PointSampling sampling = PointSampling::projected;
  std::uint64_t seed = 1;
  std::optional<BlockRange> blocks;  // sample only these blocks of kSamplesPerBlock points; default all
  RunControl run;                    // threads, cancel token, progress ("trace masking")
  int normal_bins = 10;
  int height_bins = 10;
  // The fine near-grazing class: the facets with the smallest <v, m> holding this share of the front-facing
  // projected area, in (0, 1). Defined by projected area rather than by an angle threshold so that the
  // class is never empty and holds the same share of samples (hence a comparable error) at every view and
  // on every assembly; its angle range is reported beside it.
  double grazing_share = 0.02;
  bool mirror = true;                  // G2 in the per-sample mirror configuration
  std::optional<Vec3<double>> light;   // G2 for the pair (v, light), if given (unit, light.z > 0)
  double cone_deg = 5.0;               // half-angle of the mirror cone for the pair
};

struct ConditionalBin {
  double lo = 0, hi = 0;      // bin range: <v, m> (normal bins) or height (height bins)
  double share = 0;           // share of the front-facing projected area in the bin (normal: exact over
                              // all triangles; height: sampled)
  std::uint64_t samples = 0;  // front-facing samples in the bin
  Estimate g1;                // G1(v | bin)
  Estimate ratio;             // G1(v | bin) / G1(v)
  double smith_analytic = 0;  // Smith's G1(v | bin), analytic NDF
  double smith_empirical = 0;  // ... with the empirical NDF (and height CDF)
};

struct G2Result {
  std::uint64_t samples = 0;        // samples that entered the ratio
  Estimate value;                   // measured
  double smith_analytic = 0;        // height-correlated Smith, analytic NDF
  double smith_empirical = 0;       // height-correlated Smith, empirical NDF
  double separable_analytic = 0, separable_empirical = 0;
  Estimate ratio_analytic;          // measured / smith_analytic (same samples; delta-method SE)
  Estimate ratio_empirical;         // measured / smith_empirical
};

// ---- exact sums: what a masking estimate is computed from ---------------------------------------------------
// Within a block the sums are accumulated in double (per block, so they depend on the block only); the
// totals over blocks are ExactSum (core/exact_sum.h), so that the totals of a run's blocks are the same
// bits in any grouping: the merge of a run's shards is the single run. Every term is non-negative: the
// weights w = <v, m>+ / mz (1 with projected sampling), the visible weights y in {0, w}, their squares and
// products, and w times Smith predictions (G2, G1 G1, C1^Lambda, all in [0, 1]). A block's sum must stay
// within ExactSum's [0, 2^40] (with uniform sampling, facets of slope below 2^14: else std::domain_error).

// The sums of a ratio estimator R = sum y / sum x (n: the samples that entered it).
struct RatioTotals {
  std::uint64_t n = 0;
  ExactSum x, y, xx, yy, xy;
  RatioTotals& operator+=(const RatioTotals& other);
  bool operator==(const RatioTotals&) const = default;
};

// G2: measured (w, w V V), against Smith (w G2_smith, w V V), and sum of w times each prediction.
struct G2Totals {
  RatioTotals measured, vs_analytic, vs_empirical;
  ExactSum pred_analytic, pred_empirical, sep_analytic, sep_empirical;
  G2Totals& operator+=(const G2Totals& other);
  bool operator==(const G2Totals&) const = default;
};

struct MaskingSums {
  std::uint64_t samples = 0, front = 0, rays = 0, leaked = 0, unresolved = 0;
  ExactSum leak_y, leak_yy;  // sum of w V and (w V)^2 over all samples
  RatioTotals g1, near_grazing;
  std::vector<RatioTotals> normal, height;                            // per bin
  std::vector<ExactSum> height_pred_analytic, height_pred_empirical;  // per height bin: sum of w C1^Lambda
  G2Totals mirror, pair, cone;

  // Zero sums for these bins.
  static MaskingSums empty(int normal_bins, int height_bins);
  // Adds `other`'s sums exactly; throws std::invalid_argument when its bins differ.
  MaskingSums& operator+=(const MaskingSums& other);
  bool operator==(const MaskingSums&) const = default;
};

struct MaskingResult {
  Vec3<double> v = Vec3<double>::UnitZ();
  PointSampling sampling = PointSampling::projected;
  double projected_area = 0;       // A(v) = E[w] over all triangles (exact)
  std::uint64_t samples = 0;       // surface points drawn (completed blocks)
  std::uint64_t front_facing = 0;  // with <v, m> > 0 (all of them with projected sampling)
  std::uint64_t rays = 0;          // shadow rays traced
  std::uint64_t leaked = 0, unresolved = 0;
  Estimate leak_ratio;             // E[w V] / v_z, must be 1
  Estimate g1;
  double lambda_analytic = 0, lambda_empirical = 0;
  double g1_smith_analytic = 0, g1_smith_empirical = 0;
  std::vector<ConditionalBin> by_normal, by_height;
  ConditionalBin near_grazing;     // G1(v | m) over the bottom grazing_share of the projected area
                                   // (lo = 0, hi = its <v, m> edge, share = exact share)
  std::optional<G2Result> mirror;
  std::optional<Vec3<double>> light;
  std::optional<G2Result> pair, pair_cone;
  double cone_deg = 0;
  double seconds = 0;
  BlockRange blocks;                 // the blocks sampled (a prefix of the requested ones when cancelled)
  std::uint64_t total_blocks = 0;    // blocks of the whole run
  bool partial = false;
  MaskingSums sums;                  // the totals the estimates were computed from
  double rays_per_second() const { return seconds > 0 ? double(rays) / seconds : 0.0; }
};

// Throws std::invalid_argument for v.z <= 0, samples == 0, bins < 1, grazing_share outside (0, 1), or a
// light below the horizon.
MaskingResult estimate_masking(const HeightfieldScene& scene, const AnalyticSmith& analytic,
                               const EmpiricalSmith& empirical, const Vec3<double>& v, const MaskingOptions& options);

// The result of `sums`, the totals of the blocks `blocks` of a run, exactly as estimate_masking computes it
// from the same totals (so the merge of a run's parts is the single run): the same field (the scene's),
// predictions, view and options as that run. Not timed (seconds 0), not partial. Throws as estimate_masking,
// and std::invalid_argument when the sums' bins are not the options'.
MaskingResult masking_result_from_sums(const microgeom::Heightfield& field, const AnalyticSmith& analytic,
                                       const EmpiricalSmith& empirical, const Vec3<double>& v,
                                       const MaskingOptions& options, const MaskingSums& sums, const BlockRange& blocks);

nlohmann::json to_json(const Estimate& e);
nlohmann::json to_json(const MaskingResult& r);
nlohmann::json to_json(const VndfComparison& c);

}  // namespace microsim
