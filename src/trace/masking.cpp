// microsim: VNDF, conditional masking and G2 of explicit heightfields (see masking.h).
#include "trace/masking.h"

#include "stats/chi2.h"
#include "core/block_runner.h"
#include "core/random.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <stdexcept>

namespace microsim {

namespace {

// One block of the heightfield VNDF: the tally and the diagnostics.
struct HeightfieldBlockTally {
  std::vector<std::vector<std::uint64_t>> counts;  // per binning, per bin
  std::vector<std::uint64_t> unbinned;
  std::uint64_t rays = 0, hits = 0;
  HeightfieldVndfDiagnostics diagnostics;
};

// Traces block `block`: ray origins uniform over the tile from CounterRng(seed, block), along -wi.
// Bins by FastDirectionBinner, which gives exactly DirectionBinning::bin_of (tests/stats/test_direction_binner.cpp)
// at a fraction of its cost.
HeightfieldBlockTally trace_heightfield_block(const HeightfieldScene& scene, const Vec3<double>& wi,
                                              std::span<const DirectionBinning> binnings,
                                              std::span<const FastDirectionBinner> binners, const BlockPlan& plan,
                                              std::uint64_t seed, std::uint64_t block) {
  embree::FlushDenormalsScope ftz;
  const auto& field = scene.field();
  const double tile = field.tile_size(), z0 = scene.start_height();
  HeightfieldBlockTally t;
  t.counts.resize(binnings.size());
  for (std::size_t k = 0; k < binnings.size(); ++k) t.counts[k].assign(std::size_t(binnings[k].size()), 0);
  t.unbinned.assign(binnings.size(), 0);
  t.rays = plan.units_in(block);
  // The hit triangle's normal reads heights far from Embree's data: they are prefetched when the ray hits
  // and the normal is binned after the next ray is traced (integer counts: the order does not matter).
  const auto count_hit = [&](std::uint32_t triangle) {
    const Vec3<double> m = field.triangle_normal(triangle);
    if (!(m.dot(wi) > 0.0)) {
      ++t.diagnostics.backfacing;
      return;
    }
    ++t.hits;
    for (std::size_t k = 0; k < binnings.size(); ++k) {
      const int bin = binners[k](m);
      if (bin >= 0) ++t.counts[k][std::size_t(bin)];
      else ++t.unbinned[k];
    }
  };
  std::optional<std::uint32_t> pending;
  // The block's rays traced together (HeightfieldScene::trace_batch: each ray's result trace()'s), then
  // tallied in their order.
  CounterRng rng(seed, block);
  std::vector<Vec3<double>> origins(t.rays);
  for (Vec3<double>& o : origins) {
    const double x = tile * rng.uniform(), y = tile * rng.uniform();
    o = Vec3<double>(x, y, z0);
  }
  std::vector<HeightfieldHit> hits(t.rays);
  scene.trace_batch(origins, -wi, hits);
  for (const HeightfieldHit& hit : hits) {
    if (hit.edge_grazes > 0) ++t.diagnostics.edge_grazes;
    if (!hit.is_hit()) {
      if (hit.outcome == RayOutcome::unresolved) ++t.diagnostics.unresolved;
      else ++t.diagnostics.leaked;  // a downward ray must hit: escaping or leaking is a leak
      continue;
    }
    field.prefetch_triangle(hit.triangle);
    if (pending) count_hit(*pending);
    pending = hit.triangle;
  }
  if (pending) count_hit(*pending);
  return t;
}

void add_tally(TraceResult& result, HeightfieldVndfDiagnostics& diag, const HeightfieldBlockTally& t) {
  result.rays += t.rays;
  result.hits += t.hits;
  diag.backfacing += t.diagnostics.backfacing;
  diag.edge_grazes += t.diagnostics.edge_grazes;
  diag.leaked += t.diagnostics.leaked;
  diag.unresolved += t.diagnostics.unresolved;
  for (std::size_t k = 0; k < result.counts.size(); ++k) {
    for (std::size_t b = 0; b < result.counts[k].size(); ++b) result.counts[k][b] += t.counts[k][b];
    result.unbinned[k] += t.unbinned[k];
  }
}


}  // namespace

// ---- VNDF ----------------------------------------------------------------------------------------------------

TraceResult trace_vndf_heightfield(const HeightfieldScene& scene, const Vec3<double>& wi_in,
                                   std::span<const DirectionBinning> binnings, const TraceOptions& options,
                                   HeightfieldVndfDiagnostics* diagnostics) {
  if (options.rays == 0) throw std::invalid_argument("trace_vndf_heightfield: the number of rays must be positive");
  if (!(wi_in.z() > 0.0) || !wi_in.allFinite()) {
    throw std::invalid_argument(
        fmt::format("view direction ({}, {}, {}) must point above the horizon", wi_in.x(), wi_in.y(), wi_in.z()));
  }
  const Vec3<double> wi = wi_in.normalized();
  const BlockPlan plan{options.rays, kRaysPerBlock};
  TraceResult result = empty_trace_result(binnings, plan.blocks());
  HeightfieldVndfDiagnostics diag;
  std::vector<FastDirectionBinner> binners;
  for (const DirectionBinning& b : binnings) binners.emplace_back(b);
  const auto start = std::chrono::steady_clock::now();
  const BlockRunStatus status = for_each_block(
      selected_blocks(plan, options.blocks), options.run, {"trace vndf (heightfield)", plan},
      [&](std::uint64_t block) { return trace_heightfield_block(scene, wi, binnings, binners, plan, options.seed, block); },
      [&](HeightfieldBlockTally&& t, std::uint64_t) { add_tally(result, diag, t); });
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.blocks = status.done;
  result.partial = status.cancelled;
  if (diagnostics) *diagnostics = diag;
  return result;
}

VndfComparison compare_vndf(const std::vector<std::uint64_t>& counts, std::uint64_t unbinned,
                            const DirectionBinning& binning, const Vec3<double>& v, const AnalyticSmith& analytic,
                            const EmpiricalSmith& empirical) {
  if (counts.size() != std::size_t(binning.size())) {
    throw std::invalid_argument("compare_vndf: histogram and binning sizes differ");
  }
  VndfComparison c;
  c.binning = binning.name();
  c.bins = binning.size();
  c.p_analytic = binning.integrate([&](const Vec3<double>& m) { return analytic.vndf(v, m); });
  c.p_empirical = empirical.vndf_bin_probabilities(binning, v);
  double n = double(unbinned);
  for (auto k : counts) n += double(k);
  if (!(n > 0)) return c;
  std::vector<double> observed(counts.begin(), counts.end());
  auto tv = [&](const std::vector<double>& p) {
    double s = 0, inside = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
      s += std::abs(observed[i] / n - p[i]);
      inside += p[i];
    }
    s += std::abs(double(unbinned) / n - std::max(0.0, 1.0 - inside));
    return 0.5 * s;
  };
  c.tv_analytic = tv(c.p_analytic);
  c.tv_empirical = tv(c.p_empirical);
  double noise = 0;
  for (double p : c.p_empirical) noise += std::sqrt(2.0 * p * (1.0 - p) / (kPi<double> * n));
  c.tv_noise = 0.5 * noise;
  ChiSquareOptions opts;
  opts.describe_cell = [&](int b) { return binning.describe_bin(b); };
  const ChiSquareResult ra = goodness_of_fit(observed, c.p_analytic, n, opts, double(unbinned));
  const ChiSquareResult re = goodness_of_fit(observed, c.p_empirical, n, opts, double(unbinned));
  c.p_value_analytic = ra.p_value;
  c.chi2_analytic = ra.statistic;
  c.dof_analytic = ra.dof;
  c.p_value_empirical = re.p_value;
  c.chi2_empirical = re.statistic;
  c.dof_empirical = re.dof;
  return c;
}

// ---- masking --------------------------------------------------------------------------------------------------

namespace {

// Sums for a ratio estimator R = sum y / sum x, in double: over one block's samples (then added exactly to
// RatioTotals), or the totals rounded once for the estimators.
struct RatioSums {
  double x = 0, y = 0, xx = 0, yy = 0, xy = 0;
  std::uint64_t n = 0;  // samples with x > 0
  void add(double xi, double yi) {
    x += xi;
    y += yi;
    xx += xi * xi;
    yy += yi * yi;
    xy += xi * yi;
    ++n;
  }
  double ratio() const { return x > 0 ? y / x : 0.0; }
  // sum over samples of (y - R x)^2
  double residual(double r) const { return std::max(yy - 2.0 * r * xy + r * r * xx, 0.0); }
  Estimate estimate() const {
    if (!(x > 0)) return {};
    const double r = ratio();
    return {r, std::sqrt(residual(r)) / x};
  }
  // For a proportion (every y is 0 or x): the same estimate, with the standard error kept from falling to
  // 0 when every sample is visible (or none is): at least sqrt(p~ (1 - p~) / n_eff) with the Kish
  // effective sample size n_eff = (sum x)^2 / sum x^2 and p~ = (R n_eff + 1/2) / (n_eff + 1) (a Jeffreys-
  // type half count).
  Estimate proportion() const {
    Estimate e = estimate();
    if (!(x > 0) || !(xx > 0)) return e;
    const double n_eff = x * x / xx;
    const double pt = (e.value * n_eff + 0.5) / (n_eff + 1.0);
    e.standard_error = std::max(e.standard_error, std::sqrt(pt * (1.0 - pt) / n_eff));
    return e;
  }
};

// (R_b / R) for a bin b whose samples are a subset of `all`'s, with the linearised covariance.
Estimate ratio_of_ratios(const RatioSums& bin, const RatioSums& all) {
  const double rb = bin.ratio(), r = all.ratio();
  if (!(bin.x > 0) || !(all.x > 0) || !(rb > 0) || !(r > 0)) return {};
  const double a_bin = bin.residual(rb) / sqr(bin.x * rb);
  const double a_all = all.residual(r) / sqr(all.x * r);
  // sum over the bin's samples of (y - R_b x)(y - R x)
  const double cross = (bin.yy - (r + rb) * bin.xy + r * rb * bin.xx) / (bin.x * rb * all.x * r);
  const double q = rb / r;
  return {q, q * std::sqrt(std::max(a_bin - 2.0 * cross + a_all, 0.0))};
}

struct G2Sums {
  RatioSums measured;                   // (w, w V V)
  RatioSums vs_analytic, vs_empirical;  // (w G2_smith, w V V)
  double pred_analytic = 0, pred_empirical = 0, sep_analytic = 0, sep_empirical = 0;  // sum of w * prediction
  // One sample of weight w whose pair is visible (y2 = w) or not (y2 = 0), with Smith's G2 predictions
  // g2_a, g2_e and the separable ones sep_a, sep_e for its configuration.
  void add(double w, double y2, double g2_a, double g2_e, double sep_a, double sep_e) {
    measured.add(w, y2);
    vs_analytic.add(w * g2_a, y2);
    vs_empirical.add(w * g2_e, y2);
    pred_analytic += w * g2_a;
    pred_empirical += w * g2_e;
    sep_analytic += sep_a;
    sep_empirical += sep_e;
  }
  G2Result result() const {
    G2Result r;
    r.samples = measured.n;
    r.value = measured.proportion();
    if (measured.x > 0) {
      r.smith_analytic = pred_analytic / measured.x;
      r.smith_empirical = pred_empirical / measured.x;
      r.separable_analytic = sep_analytic / measured.x;
      r.separable_empirical = sep_empirical / measured.x;
    }
    r.ratio_analytic = vs_analytic.estimate();
    r.ratio_empirical = vs_empirical.estimate();
    return r;
  }
};

struct BlockSums {
  std::uint64_t samples = 0, front = 0, rays = 0, leaked = 0, unresolved = 0;
  double leak_y = 0, leak_yy = 0;  // sum of w V and (w V)^2 over all samples
  RatioSums g1;
  std::vector<RatioSums> normal, height;
  RatioSums near_grazing;
  std::vector<double> height_pred_analytic, height_pred_empirical;  // sum of w C1^Lambda
  G2Sums mirror, pair, cone;
};

BlockSums empty_block_sums(int normal_bins, int height_bins) {
  BlockSums s;
  s.normal.assign(std::size_t(normal_bins), {});
  s.height.assign(std::size_t(height_bins), {});
  s.height_pred_analytic.assign(std::size_t(height_bins), 0.0);
  s.height_pred_empirical.assign(std::size_t(height_bins), 0.0);
  return s;
}

// ---- the view's bins ----------------------------------------------------------------------------------------

// (<v, m>, <v, m> / mz) of every front-facing facet, ascending in <v, m> (float: 8 bytes per facet).
std::vector<std::pair<float, float>> front_facing_facets(const microgeom::Heightfield& field, const Vec3<double>& v) {
  const int n = field.resolution();
  std::vector<std::vector<std::pair<float, float>>> rows(static_cast<std::size_t>(n));
  tbb::parallel_for(0, n, [&](int j) {
    auto& row = rows[std::size_t(j)];
    row.reserve(std::size_t(2 * n));
    for (int i = 0; i < n; ++i) {
      for (int t = 0; t < 2; ++t) {
        const Eigen::Vector2d s = field.triangle_slope(i, j, t);
        const double w = v.z() - s.x() * v.x() - s.y() * v.y();  // <v, m> / mz
        if (!(w > 0)) continue;
        const double c = w / std::sqrt(1.0 + s.squaredNorm());  // <v, m>
        row.emplace_back(float(c), float(w));
      }
    }
  });
  std::vector<std::pair<float, float>> all;
  std::size_t total_count = 0;
  for (const auto& r : rows) total_count += r.size();
  all.reserve(total_count);
  for (auto& r : rows) {
    all.insert(all.end(), r.begin(), r.end());
    std::vector<std::pair<float, float>>().swap(r);
  }
  std::sort(all.begin(), all.end());
  return all;
}

// The edge between sorted facet idx and the next one (bins are [lo, hi)); `last` when idx is the last.
double edge_after(const std::vector<std::pair<float, float>>& facets, std::size_t idx, double last) {
  return idx + 1 < facets.size() ? 0.5 * (double(facets[idx].first) + double(facets[idx + 1].first)) : last;
}

// Equal-area quantiles of <v, m> over the front-facing projected area `total` of `facets`:
// edges[0] = 0 < ... < edges[k] = 1, and the exact share of each bin.
void equal_area_edges(const std::vector<std::pair<float, float>>& facets, double total, int k, std::vector<double>& edges,
                      std::vector<double>& shares) {
  edges.assign(std::size_t(k) + 1, 0.0);
  edges[std::size_t(k)] = 1.0;
  shares.assign(std::size_t(k), 0.0);
  double cum = 0, last_cum = 0;
  int next = 1;
  for (std::size_t idx = 0; idx < facets.size() && next < k; ++idx) {
    cum += facets[idx].second;
    if (cum >= total * next / k) {
      edges[std::size_t(next)] = edge_after(facets, idx, double(facets[idx].first));
      shares[std::size_t(next - 1)] = (cum - last_cum) / total;
      last_cum = cum;
      ++next;
    }
  }
  while (next < k) {  // degenerate (fewer distinct facets than bins): empty top bins
    edges[std::size_t(next)] = 1.0;
    ++next;
  }
  shares[std::size_t(k - 1)] = total > 0 ? (total - last_cum) / total : 0.0;
}

// The near-grazing edge: the first facet at which the cumulative share reaches `fine`; the edge lies between
// it and the next facet, as for the bins. Also its exact share.
void near_grazing_edge(const std::vector<std::pair<float, float>>& facets, double total, double fine, double& fine_edge,
                       double& fine_share) {
  fine_edge = 1.0;
  fine_share = 1.0;
  double cum = 0;
  for (std::size_t idx = 0; idx < facets.size(); ++idx) {
    cum += facets[idx].second;
    if (cum >= total * fine) {
      fine_edge = edge_after(facets, idx, 1.0);
      fine_share = total > 0 ? cum / total : 0.0;
      break;
    }
  }
}

// Equal-area bins of <v, m> over the front-facing projected area (weight <v,m>+/mz per triangle), their
// exact shares, and the near-grazing class [0, fine_edge) holding the share `fine` (and its exact share).
void normal_bin_edges(const microgeom::Heightfield& field, const Vec3<double>& v, int k, std::vector<double>& edges,
                      std::vector<double>& shares, double fine, double& fine_edge, double& fine_share) {
  const std::vector<std::pair<float, float>> facets = front_facing_facets(field, v);
  double total = 0;
  for (const auto& p : facets) total += p.second;
  equal_area_edges(facets, total, k, edges, shares);
  near_grazing_edge(facets, total, fine, fine_edge, fine_share);
}

// Equal-count bins of the vertex heights, from the lowest to the highest.
std::vector<double> height_bin_edges(const microgeom::Heightfield& field, const EmpiricalSmith& empirical, int k) {
  std::vector<double> edges(std::size_t(k) + 1);
  const auto& hs = empirical.sorted_heights();
  for (int b = 0; b <= k; ++b) {
    const std::size_t idx = std::min(hs.size() - 1, std::size_t(double(hs.size()) * b / k));
    edges[std::size_t(b)] = double(hs[idx]);
  }
  edges.front() = field.min_height();
  edges.back() = field.max_height();
  return edges;
}

int bin_index(const std::vector<double>& edges, double x) {
  // edges[0] .. edges[k]; bin b = [edges[b], edges[b+1]); values outside clamp to the end bins.
  const auto it = std::upper_bound(edges.begin() + 1, edges.end() - 1, x);
  return int(it - (edges.begin() + 1));
}

// ---- projected-area sampling --------------------------------------------------------------------------------

// w = <v, m>+ / mz of the 2N triangles of row j (into w, in triangle order) and their sum, added in order.
double row_projected_weights(const microgeom::Heightfield& field, const Vec3<double>& v, int j, double* w) {
  double sum = 0;
  for (int i = 0; i < field.resolution(); ++i) {
    for (int t = 0; t < 2; ++t) {
      const Eigen::Vector2d s = field.triangle_slope(i, j, t);
      const double wk = std::max(v.z() - s.x() * v.x() - s.y() * v.y(), 0.0);
      w[std::size_t(2 * i + t)] = wk;
      sum += wk;
    }
  }
  return sum;
}

// The sum of w over all triangles: row sums added in row order (the same bits as ProjectedAreaSampler::total).
double projected_weight_total(const microgeom::Heightfield& field, const Vec3<double>& v) {
  const int n = field.resolution();
  std::vector<double> row_sum(std::size_t(n), 0.0);
  tbb::parallel_for(0, n, [&](int j) {
    std::vector<double> w(2 * std::size_t(n));
    row_sum[std::size_t(j)] = row_projected_weights(field, v, j, w.data());
  });
  double total = 0;
  for (int j = 0; j < n; ++j) total = total + row_sum[std::size_t(j)];
  return total;
}

// Draws triangles with probability proportional to w = <v, m>+ / mz: a CDF over rows (double) and, per
// row, a normalised cumulative over its 2N triangles (float: 4 bytes per triangle). Row sums are computed
// row by row and accumulated in row order: deterministic.
class ProjectedAreaSampler {
public:
  ProjectedAreaSampler(const microgeom::Heightfield& field, const Vec3<double>& v) : n_(field.resolution()) {
    const std::size_t per_row = 2 * std::size_t(n_);
    row_cdf_.assign(std::size_t(n_) + 1, 0.0);
    triangle_cdf_.assign(per_row * std::size_t(n_), 0.0f);
    std::vector<double> row_sum(std::size_t(n_), 0.0);
    tbb::parallel_for(0, n_, [&](int j) {
      float* cdf = triangle_cdf_.data() + per_row * std::size_t(j);
      std::vector<double> w(per_row);
      const double sum = row_projected_weights(field, v, j, w.data());
      double cum = 0;
      for (std::size_t k = 0; k < per_row; ++k) {
        cum += w[k];
        cdf[k] = sum > 0 ? float(cum / sum) : 0.0f;
      }
      if (sum > 0) cdf[per_row - 1] = 1.0f;
      row_sum[std::size_t(j)] = sum;
    });
    for (int j = 0; j < n_; ++j) row_cdf_[std::size_t(j) + 1] = row_cdf_[std::size_t(j)] + row_sum[std::size_t(j)];
    total_ = row_cdf_.back();
  }
  // Sum of w over all triangles.
  double total() const { return total_; }
  // (row, triangle-in-row) from two uniforms; returns the triangle id.
  std::uint32_t sample(double u_row, double u_triangle) const {
    const double target = u_row * total_;
    auto it = std::upper_bound(row_cdf_.begin() + 1, row_cdf_.end(), target);
    if (it == row_cdf_.end()) --it;
    const int j = int(it - (row_cdf_.begin() + 1));
    const std::size_t per_row = 2 * std::size_t(n_);
    const float* cdf = triangle_cdf_.data() + per_row * std::size_t(j);
    const float* t = std::upper_bound(cdf, cdf + per_row, float(u_triangle));
    std::size_t k = std::size_t(t - cdf);
    if (k >= per_row) k = per_row - 1;
    return std::uint32_t(per_row * std::size_t(j) + k);  // = 2 (j N + i) + t
  }

private:
  int n_;
  std::vector<double> row_cdf_;
  std::vector<float> triangle_cdf_;
  double total_ = 0;
};

// ---- the setup: what every sample of one view shares --------------------------------------------------------

// The view's constants and bins, computed once before sampling (and again, identically, by a merge).
struct MaskingView {
  Vec3<double> v = Vec3<double>::UnitZ();
  std::optional<Vec3<double>> light;
  bool projected = true;
  bool mirror = true;
  int kn = 0, kh = 0;  // normal and height bins
  double projected_area = 0;
  std::vector<double> nedges, nshares, hedges;
  double grazing_edge = 1.0, grazing_share = 1.0;
  // Smith: G1(v) and Lambda(v) (analytic, empirical); for the pair, G2(v, l) height-correlated and separable.
  double g1a_v = 0, g1e_v = 0, lambda_a_v = 0, lambda_e_v = 0;
  double pair_a = 0, pair_e = 0, pair_sep_a = 0, pair_sep_e = 0;
  Vec3<double> half = Vec3<double>::UnitZ();
  double cos_cone = 1.0;
};

void check_masking_options(const Vec3<double>& v, const MaskingOptions& options) {
  if (!(v.z() > 0.0) || !v.allFinite()) {
    throw std::invalid_argument(fmt::format("view direction ({}, {}, {}) must point above the horizon", v.x(), v.y(), v.z()));
  }
  if (options.samples == 0) throw std::invalid_argument("estimate_masking: the number of samples must be positive");
  if (options.normal_bins < 1 || options.height_bins < 1) {
    throw std::invalid_argument("estimate_masking: normal and height bins must be >= 1");
  }
  if (options.light && (!(options.light->z() > 0.0) || !options.light->allFinite())) {
    throw std::invalid_argument("estimate_masking: the light direction must point above the horizon");
  }
  if (!(options.grazing_share > 0.0 && options.grazing_share < 1.0)) {
    throw std::invalid_argument(fmt::format("estimate_masking: near-grazing share {} must be in (0, 1)", options.grazing_share));
  }
  if (!(options.cone_deg > 0.0 && options.cone_deg <= 90.0)) {
    throw std::invalid_argument(fmt::format("estimate_masking: cone half-angle {} must be in (0, 90] degrees", options.cone_deg));
  }
}

void set_smith_constants(MaskingView& view, const AnalyticSmith& analytic, const EmpiricalSmith& empirical,
                         double cone_deg) {
  const Vec3<double>& v = view.v;
  view.lambda_a_v = analytic.Lambda(v);
  view.lambda_e_v = empirical.Lambda(v);
  view.g1a_v = analytic.G1(v);
  view.g1e_v = 1.0 / (1.0 + view.lambda_e_v);
  view.cos_cone = std::cos(cone_deg * kPi<double> / 180.0);
  if (view.light) {
    const Vec3<double>& l = *view.light;
    view.pair_a = analytic.G2(v, l);
    view.pair_e = empirical.G2(v, l);
    view.pair_sep_a = analytic.G2_separable(v, l);
    view.pair_sep_e = view.g1e_v * empirical.G1(l);
    view.half = (v + l).normalized();
  }
}

// The setup of one view. `sampler` (projected sampling, when tracing) supplies the projected area it
// already summed; without it the same sum is computed again. Throws std::invalid_argument (see masking.h).
MaskingView masking_view(const microgeom::Heightfield& field, const AnalyticSmith& analytic,
                         const EmpiricalSmith& empirical, const Vec3<double>& v_in, const MaskingOptions& options,
                         const ProjectedAreaSampler* sampler) {
  check_masking_options(v_in, options);
  MaskingView view;
  view.v = v_in.normalized();
  view.projected = options.sampling == PointSampling::projected;
  view.mirror = options.mirror;
  if (options.light) view.light = options.light->normalized();
  view.kn = options.normal_bins;
  view.kh = options.height_bins;
  if (view.projected) {
    const double total = sampler ? sampler->total() : projected_weight_total(field, view.v);
    view.projected_area = total / double(field.triangle_count());
  } else {
    view.projected_area = empirical.projected_area(view.v);
  }
  if (!(view.projected_area > 0)) throw std::invalid_argument("estimate_masking: no facet faces the view");
  normal_bin_edges(field, view.v, view.kn, view.nedges, view.nshares, options.grazing_share, view.grazing_edge,
                   view.grazing_share);
  view.hedges = height_bin_edges(field, empirical, view.kh);
  set_smith_constants(view, analytic, empirical, options.cone_deg);
  return view;
}

// ---- one block's sampling -----------------------------------------------------------------------------------

// What the samples of a run share.
struct SamplingContext {
  const HeightfieldScene& scene;
  const AnalyticSmith& analytic;
  const EmpiricalSmith& empirical;
  const MaskingView& view;
  const ProjectedAreaSampler* sampler;  // projected sampling
  BlockPlan plan;
  std::uint64_t seed;
};

struct SurfacePoint {
  double x = 0, y = 0;
  std::uint32_t triangle = 0;
};

// A point: with projected sampling a triangle with probability ~ w, then a uniform point on it (local
// u >= v for triangle 0); with uniform sampling (x, y) uniform over the tile.
SurfacePoint draw_surface_point(const SamplingContext& c, CounterRng& rng) {
  const auto& field = c.scene.field();
  SurfacePoint s;
  if (c.view.projected) {
    s.triangle = c.sampler->sample(rng.uniform(), rng.uniform());
    const auto t = field.triangle_index(s.triangle);
    const double a = rng.uniform(), b = rng.uniform();
    const double lu = t.t == 0 ? std::max(a, b) : std::min(a, b), lv = t.t == 0 ? std::min(a, b) : std::max(a, b);
    const double h = field.cell_size();
    s.x = (t.i + lu) * h;
    s.y = (t.j + lv) * h;
  } else {
    const double tile = field.tile_size();
    s.x = tile * rng.uniform();
    s.y = tile * rng.uniform();
    s.triangle = field.triangle_at(s.x, s.y);
  }
  return s;
}

// G1: the sample (weight w, visible y_v = w or 0) in the overall, normal, near-grazing and height sums.
void add_g1_sample(const SamplingContext& c, BlockSums& bs, double w, double y_v, double vm, double z) {
  const MaskingView& view = c.view;
  bs.leak_y += y_v;
  bs.leak_yy += y_v * y_v;
  bs.g1.add(w, y_v);
  bs.normal[std::size_t(bin_index(view.nedges, vm))].add(w, y_v);
  if (vm < view.grazing_edge) bs.near_grazing.add(w, y_v);
  const std::size_t hb = std::size_t(bin_index(view.hedges, z));
  bs.height[hb].add(w, y_v);
  const double c1 = c.empirical.height_cdf(z);
  bs.height_pred_analytic[hb] += w * EmpiricalSmith::height_masking(c1, view.lambda_a_v);
  bs.height_pred_empirical[hb] += w * EmpiricalSmith::height_masking(c1, view.lambda_e_v);
}

// G2 in the mirror configuration l = reflect(v, m) of the sample's facet; vis_l: p sees both v and l.
void add_mirror_sample(const SamplingContext& c, BlockSums& bs, const Vec3<double>& m, double w, bool vis_l) {
  const Vec3<double> l = reflect(c.view.v, m);
  const double y2 = vis_l ? w : 0.0;
  const double ga = c.analytic.G2(c.view.v, l), ge = c.empirical.G2_tabulated(c.view.v, l);
  const double sep_a = w * c.view.g1a_v * c.analytic.G1(l);
  const double sep_e = l.z() > 0 ? w * c.view.g1e_v / (1.0 + c.empirical.Lambda_tabulated(l)) : 0.0;
  bs.mirror.add(w, y2, ga, ge, sep_a, sep_e);
}

// G2 for the fixed light, on facets facing it (and those within the cone around the half vector).
void add_pair_sample(const SamplingContext& c, BlockSums& bs, const Vec3<double>& m, double w, bool vis_l) {
  const MaskingView& view = c.view;
  const double y2 = vis_l ? w : 0.0;
  const double sep_a = w * view.pair_sep_a, sep_e = w * view.pair_sep_e;
  bs.pair.add(w, y2, view.pair_a, view.pair_e, sep_a, sep_e);
  if (m.dot(view.half) >= view.cos_cone) bs.cone.add(w, y2, view.pair_a, view.pair_e, sep_a, sep_e);
}

// A front-facing point of a block and its shadow rays' indices (-1: none).
struct FrontPoint {
  SurfacePoint s;
  Vec3<double> m, p;
  double vm = 0, w = 0;
  std::ptrdiff_t g1 = -1, mirror = -1, pair = -1;
};

// The shadow rays of a block, traced together (HeightfieldScene::escape_outcomes), each counted with its
// outcome; visible(k): ray k escaped.
struct ShadowRays {
  std::vector<HeightfieldScene::ShadowRay> rays;
  std::vector<RayOutcome> outcomes;
  std::ptrdiff_t add(const Vec3<double>& p, const Vec3<double>& dir, std::uint32_t triangle) {
    rays.push_back({p, dir, triangle});
    return std::ptrdiff_t(rays.size()) - 1;
  }
  void trace(const HeightfieldScene& scene, BlockSums& bs, std::size_t from) {
    outcomes.resize(rays.size());
    scene.escape_outcomes(std::span(rays).subspan(from), std::span(outcomes).subspan(from));
    for (std::size_t k = from; k < rays.size(); ++k) {
      ++bs.rays;
      if (outcomes[k] == RayOutcome::leaked) ++bs.leaked;
      if (outcomes[k] == RayOutcome::unresolved) ++bs.unresolved;
    }
  }
  bool visible(std::ptrdiff_t k) const { return k >= 0 && outcomes[std::size_t(k)] == RayOutcome::escaped; }
};

// A surface point: its facet, weight (w for uniform points, 1 for points already drawn proportionally to w)
// and shadow ray toward v, if it faces v.
std::optional<FrontPoint> front_point(const SamplingContext& c, const SurfacePoint& s, ShadowRays& shadow) {
  const auto& field = c.scene.field();
  FrontPoint f{s, field.triangle_normal(s.triangle), Vec3<double>::Zero()};
  f.vm = c.view.v.dot(f.m);
  if (!(f.vm > 0)) return std::nullopt;
  f.w = c.view.projected ? 1.0 : f.vm / f.m.z();
  f.p = Vec3<double>(s.x, s.y, field.height_at(s.x, s.y));
  f.g1 = shadow.add(f.p, c.view.v, s.triangle);
  return f;
}

// Block `block` of the run: its points from CounterRng(seed, block). Their rays toward v traced together,
// then the second rays (toward the mirror direction and the light) of the points that see v; the sums
// taken in point order, as one point after the other would.
BlockSums sample_masking_block(const SamplingContext& c, std::uint64_t block) {
  embree::FlushDenormalsScope ftz;
  BlockSums bs = empty_block_sums(c.view.kn, c.view.kh);
  const std::uint64_t count = c.plan.units_in(block);
  CounterRng rng(c.seed, block);
  ShadowRays shadow;
  std::vector<FrontPoint> front;
  for (std::uint64_t i = 0; i < count; ++i)
    if (auto f = front_point(c, draw_surface_point(c, rng), shadow)) front.push_back(*f);
  bs.samples = count;
  shadow.trace(c.scene, bs, 0);
  const std::size_t second = shadow.rays.size();
  for (FrontPoint& f : front) {
    if (!shadow.visible(f.g1)) continue;
    const Vec3<double> l = reflect(c.view.v, f.m);
    if (c.view.mirror && l.z() > 0) f.mirror = shadow.add(f.p, l, f.s.triangle);
    if (c.view.light && c.view.light->dot(f.m) > 0) f.pair = shadow.add(f.p, *c.view.light, f.s.triangle);
  }
  shadow.trace(c.scene, bs, second);
  for (const FrontPoint& f : front) {
    ++bs.front;
    const bool vis = shadow.visible(f.g1);
    add_g1_sample(c, bs, f.w, vis ? f.w : 0.0, f.vm, f.p.z());
    if (c.view.mirror) add_mirror_sample(c, bs, f.m, f.w, shadow.visible(f.mirror));
    if (c.view.light && c.view.light->dot(f.m) > 0) add_pair_sample(c, bs, f.m, f.w, shadow.visible(f.pair));
  }
  return bs;
}

// ---- adding block sums --------------------------------------------------------------------------------------
// A block's double sums enter the totals exactly: the totals of any grouping of blocks are the same bits.

void add_exact(RatioTotals& t, const RatioSums& s) {
  t.n += s.n;
  t.x.add(s.x);
  t.y.add(s.y);
  t.xx.add(s.xx);
  t.yy.add(s.yy);
  t.xy.add(s.xy);
}

void add_exact(G2Totals& t, const G2Sums& s) {
  add_exact(t.measured, s.measured);
  add_exact(t.vs_analytic, s.vs_analytic);
  add_exact(t.vs_empirical, s.vs_empirical);
  t.pred_analytic.add(s.pred_analytic);
  t.pred_empirical.add(s.pred_empirical);
  t.sep_analytic.add(s.sep_analytic);
  t.sep_empirical.add(s.sep_empirical);
}

void add_block_sums(MaskingSums& total, const BlockSums& bs) {
  total.samples += bs.samples;
  total.front += bs.front;
  total.rays += bs.rays;
  total.leaked += bs.leaked;
  total.unresolved += bs.unresolved;
  total.leak_y.add(bs.leak_y);
  total.leak_yy.add(bs.leak_yy);
  add_exact(total.g1, bs.g1);
  for (std::size_t b = 0; b < total.normal.size(); ++b) add_exact(total.normal[b], bs.normal[b]);
  add_exact(total.near_grazing, bs.near_grazing);
  for (std::size_t b = 0; b < total.height.size(); ++b) {
    add_exact(total.height[b], bs.height[b]);
    total.height_pred_analytic[b].add(bs.height_pred_analytic[b]);
    total.height_pred_empirical[b].add(bs.height_pred_empirical[b]);
  }
  add_exact(total.mirror, bs.mirror);
  add_exact(total.pair, bs.pair);
  add_exact(total.cone, bs.cone);
}

// ---- from total sums to the result --------------------------------------------------------------------------

// The totals, each rounded once to double, for the estimators.
RatioSums rounded(const RatioTotals& t) {
  RatioSums s;
  s.x = t.x.value();
  s.y = t.y.value();
  s.xx = t.xx.value();
  s.yy = t.yy.value();
  s.xy = t.xy.value();
  s.n = t.n;
  return s;
}

G2Result g2_result(const G2Totals& t) {
  G2Sums s;
  s.measured = rounded(t.measured);
  s.vs_analytic = rounded(t.vs_analytic);
  s.vs_empirical = rounded(t.vs_empirical);
  s.pred_analytic = t.pred_analytic.value();
  s.pred_empirical = t.pred_empirical.value();
  s.sep_analytic = t.sep_analytic.value();
  s.sep_empirical = t.sep_empirical.value();
  return s.result();
}

// E[w V] / v_z: with projected sampling G1 A(v) / v_z; with uniform sampling the sample mean of w V / v_z.
Estimate leak_ratio(const MaskingView& view, const MaskingSums& total, const Estimate& g1) {
  if (view.projected) {
    const double scale = view.projected_area / view.v.z();
    return {g1.value * scale, g1.standard_error * scale};
  }
  if (total.samples <= 1) return {};
  const double ns = double(total.samples);
  const double mean = total.leak_y.value() / ns;
  const double var = std::max(total.leak_yy.value() / ns - mean * mean, 0.0) / (ns - 1.0);
  return {mean / view.v.z(), std::sqrt(var) / view.v.z()};
}

// A conditional class: G1 over its samples and the ratio to the overall G1.
ConditionalBin conditional_bin(const RatioSums& s, const RatioSums& all, double lo, double hi, double share) {
  ConditionalBin cb;
  cb.lo = lo;
  cb.hi = hi;
  cb.share = share;
  cb.samples = s.n;
  cb.g1 = s.proportion();
  cb.ratio = ratio_of_ratios(s, all);
  return cb;
}

// G1(v | m) per bin of <v, m> and over the near-grazing class; Smith: G1(v) for every front-facing m.
void add_normal_bins(MaskingResult& result, const MaskingView& view, const MaskingSums& total) {
  const RatioSums all = rounded(total.g1);
  for (int b = 0; b < view.kn; ++b) {
    const std::size_t k = std::size_t(b);
    ConditionalBin cb = conditional_bin(rounded(total.normal[k]), all, view.nedges[k], view.nedges[k + 1], view.nshares[k]);
    cb.smith_analytic = view.g1a_v;
    cb.smith_empirical = view.g1e_v;
    result.by_normal.push_back(cb);
  }
  result.near_grazing = conditional_bin(rounded(total.near_grazing), all, 0.0, view.grazing_edge, view.grazing_share);
  result.near_grazing.smith_analytic = view.g1a_v;
  result.near_grazing.smith_empirical = view.g1e_v;
}

// G1(v | h) per height bin; Smith: the sampled mean of C1(h)^Lambda(v) over the bin.
void add_height_bins(MaskingResult& result, const MaskingView& view, const MaskingSums& total) {
  const RatioSums all = rounded(total.g1);
  for (int b = 0; b < view.kh; ++b) {
    const std::size_t k = std::size_t(b);
    const RatioSums s = rounded(total.height[k]);
    const double share = all.x > 0 ? s.x / all.x : 0.0;
    ConditionalBin cb = conditional_bin(s, all, view.hedges[k], view.hedges[k + 1], share);
    if (s.x > 0) {
      cb.smith_analytic = total.height_pred_analytic[k].value() / s.x;
      cb.smith_empirical = total.height_pred_empirical[k].value() / s.x;
    }
    result.by_height.push_back(cb);
  }
}

// The estimates of a view from its total sums.
MaskingResult masking_result(const MaskingView& view, const MaskingOptions& options, const MaskingSums& total) {
  if (total.normal.size() != std::size_t(view.kn) || total.height.size() != std::size_t(view.kh))
    throw std::invalid_argument("masking_result_from_sums: the sums' bins are not the options' bins");
  MaskingResult result;
  result.v = view.v;
  result.sampling = options.sampling;
  result.projected_area = view.projected_area;
  result.light = view.light;
  result.cone_deg = options.cone_deg;
  result.lambda_analytic = view.lambda_a_v;
  result.lambda_empirical = view.lambda_e_v;
  result.g1_smith_analytic = view.g1a_v;
  result.g1_smith_empirical = view.g1e_v;
  result.samples = total.samples;
  result.front_facing = total.front;
  result.rays = total.rays;
  result.leaked = total.leaked;
  result.unresolved = total.unresolved;
  result.g1 = rounded(total.g1).proportion();
  result.leak_ratio = leak_ratio(view, total, result.g1);
  add_normal_bins(result, view, total);
  add_height_bins(result, view, total);
  if (view.mirror) result.mirror = g2_result(total.mirror);
  if (view.light) {
    result.pair = g2_result(total.pair);
    result.pair_cone = g2_result(total.cone);
  }
  result.sums = total;
  return result;
}

}  // namespace

// ---- exact sums ---------------------------------------------------------------------------------------------

RatioTotals& RatioTotals::operator+=(const RatioTotals& o) {
  n += o.n;
  x += o.x;
  y += o.y;
  xx += o.xx;
  yy += o.yy;
  xy += o.xy;
  return *this;
}

G2Totals& G2Totals::operator+=(const G2Totals& o) {
  measured += o.measured;
  vs_analytic += o.vs_analytic;
  vs_empirical += o.vs_empirical;
  pred_analytic += o.pred_analytic;
  pred_empirical += o.pred_empirical;
  sep_analytic += o.sep_analytic;
  sep_empirical += o.sep_empirical;
  return *this;
}

MaskingSums MaskingSums::empty(int normal_bins, int height_bins) {
  MaskingSums s;
  s.normal.assign(std::size_t(normal_bins), {});
  s.height.assign(std::size_t(height_bins), {});
  s.height_pred_analytic.assign(std::size_t(height_bins), {});
  s.height_pred_empirical.assign(std::size_t(height_bins), {});
  return s;
}

MaskingSums& MaskingSums::operator+=(const MaskingSums& o) {
  if (o.normal.size() != normal.size() || o.height.size() != height.size() ||
      o.height_pred_analytic.size() != height.size() || o.height_pred_empirical.size() != height.size() ||
      height_pred_analytic.size() != height.size() || height_pred_empirical.size() != height.size())
    throw std::invalid_argument("MaskingSums: sums of different bins");
  samples += o.samples;
  front += o.front;
  rays += o.rays;
  leaked += o.leaked;
  unresolved += o.unresolved;
  leak_y += o.leak_y;
  leak_yy += o.leak_yy;
  g1 += o.g1;
  near_grazing += o.near_grazing;
  for (std::size_t b = 0; b < normal.size(); ++b) normal[b] += o.normal[b];
  for (std::size_t b = 0; b < height.size(); ++b) {
    height[b] += o.height[b];
    height_pred_analytic[b] += o.height_pred_analytic[b];
    height_pred_empirical[b] += o.height_pred_empirical[b];
  }
  mirror += o.mirror;
  pair += o.pair;
  cone += o.cone;
  return *this;
}

// ---- the estimate -------------------------------------------------------------------------------------------

MaskingResult estimate_masking(const HeightfieldScene& scene, const AnalyticSmith& analytic,
                               const EmpiricalSmith& empirical, const Vec3<double>& v, const MaskingOptions& options) {
  check_masking_options(v, options);
  const auto& field = scene.field();
  std::unique_ptr<ProjectedAreaSampler> sampler;
  if (options.sampling == PointSampling::projected) sampler = std::make_unique<ProjectedAreaSampler>(field, v.normalized());
  const MaskingView view = masking_view(field, analytic, empirical, v, options, sampler.get());
  if (view.mirror) empirical.Lambda_tabulated(view.v);  // build the tables before the parallel loop
  const BlockPlan plan{options.samples, kSamplesPerBlock};
  const SamplingContext context{scene, analytic, empirical, view, sampler.get(), plan, options.seed};
  MaskingSums total = MaskingSums::empty(view.kn, view.kh);
  const auto start = std::chrono::steady_clock::now();
  const BlockRunStatus status = for_each_block(
      selected_blocks(plan, options.blocks), options.run, {"trace masking", plan},
      [&](std::uint64_t block) { return sample_masking_block(context, block); },
      [&](BlockSums&& bs, std::uint64_t) { add_block_sums(total, bs); });
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  MaskingResult result = masking_result(view, options, total);
  result.seconds = seconds;
  result.blocks = status.done;
  result.total_blocks = plan.blocks();
  result.partial = status.cancelled;
  return result;
}

MaskingResult masking_result_from_sums(const microgeom::Heightfield& field, const AnalyticSmith& analytic,
                                       const EmpiricalSmith& empirical, const Vec3<double>& v,
                                       const MaskingOptions& options, const MaskingSums& sums, const BlockRange& blocks) {
  const MaskingView view = masking_view(field, analytic, empirical, v, options, nullptr);
  MaskingResult result = masking_result(view, options, sums);
  result.blocks = blocks;
  result.total_blocks = BlockPlan{options.samples, kSamplesPerBlock}.blocks();
  return result;
}

// ---- JSON -------------------------------------------------------------------------------------------------------

nlohmann::json to_json(const Estimate& e) { return {{"value", e.value}, {"stderr", e.standard_error}}; }

namespace {
nlohmann::json bins_json(const std::vector<ConditionalBin>& bins, bool normal) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& b : bins) {
    nlohmann::json j = {{"lo", b.lo},
                        {"hi", b.hi},
                        {"share", b.share},
                        {"samples", b.samples},
                        {"g1", to_json(b.g1)},
                        {"ratio_to_g1", to_json(b.ratio)},
                        {"smith_analytic", b.smith_analytic},
                        {"smith_empirical", b.smith_empirical}};
    if (normal) {
      j["angle_m_v_deg_min"] = std::acos(std::clamp(b.hi, -1.0, 1.0)) * 180.0 / kPi<double>;
      j["angle_m_v_deg_max"] = std::acos(std::clamp(b.lo, -1.0, 1.0)) * 180.0 / kPi<double>;
    }
    a.push_back(j);
  }
  return a;
}

nlohmann::json g2_json(const G2Result& g) {
  return {{"samples", g.samples},
          {"measured", to_json(g.value)},
          {"smith_height_correlated_analytic", g.smith_analytic},
          {"smith_height_correlated_empirical", g.smith_empirical},
          {"smith_separable_analytic", g.separable_analytic},
          {"smith_separable_empirical", g.separable_empirical},
          {"ratio_to_smith_analytic", to_json(g.ratio_analytic)},
          {"ratio_to_smith_empirical", to_json(g.ratio_empirical)}};
}
}  // namespace

nlohmann::json to_json(const MaskingResult& r) {
  nlohmann::json j;
  j["v"] = {r.v.x(), r.v.y(), r.v.z()};
  j["sampling"] = r.sampling == PointSampling::projected ? "projected" : "uniform";
  j["projected_area"] = r.projected_area;
  j["samples"] = r.samples;
  j["front_facing_samples"] = r.front_facing;
  j["shadow_rays"] = r.rays;
  j["leaked_rays"] = r.leaked;
  j["unresolved_rays"] = r.unresolved;
  j["seconds"] = r.seconds;
  j["rays_per_second"] = r.rays_per_second();
  j["partial"] = r.partial;
  j["leak_ratio"] = to_json(r.leak_ratio);
  j["g1"] = to_json(r.g1);
  j["lambda_smith_analytic"] = r.lambda_analytic;
  j["lambda_smith_empirical"] = r.lambda_empirical;
  j["g1_smith_analytic"] = r.g1_smith_analytic;
  j["g1_smith_empirical"] = r.g1_smith_empirical;
  j["g1_given_normal"] = bins_json(r.by_normal, true);
  j["g1_given_height"] = bins_json(r.by_height, false);
  j["g1_near_grazing"] = bins_json({r.near_grazing}, true).front();
  if (r.mirror) j["g2_mirror"] = g2_json(*r.mirror);
  if (r.light) {
    j["light"] = {r.light->x(), r.light->y(), r.light->z()};
    j["g2_pair"] = g2_json(*r.pair);
    j["g2_pair_mirror_cone"] = g2_json(*r.pair_cone);
    j["mirror_cone_deg"] = r.cone_deg;
  }
  return j;
}

nlohmann::json to_json(const VndfComparison& c) {
  return {{"binning", c.binning},
          {"bins", c.bins},
          {"tv_smith_analytic", c.tv_analytic},
          {"tv_smith_empirical", c.tv_empirical},
          {"tv_noise_floor", c.tv_noise},
          {"chi2_smith_analytic", {{"statistic", c.chi2_analytic}, {"dof", c.dof_analytic}, {"p_value", c.p_value_analytic}}},
          {"chi2_smith_empirical", {{"statistic", c.chi2_empirical}, {"dof", c.dof_empirical}, {"p_value", c.p_value_empirical}}}};
}

}  // namespace microsim
