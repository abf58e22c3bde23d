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
HeightfieldBlockTally trace_heightfield_block(const HeightfieldScene& scene, const Vec3<double>& wi,
                                              std::span<const DirectionBinning> binnings, const BlockPlan& plan,
                                              std::uint64_t seed, std::uint64_t block) {
  embree::FlushDenormalsScope ftz;
  const auto& field = scene.field();
  const double tile = field.tile_size(), z0 = scene.start_height();
  HeightfieldBlockTally t;
  t.counts.resize(binnings.size());
  for (std::size_t k = 0; k < binnings.size(); ++k) t.counts[k].assign(std::size_t(binnings[k].size()), 0);
  t.unbinned.assign(binnings.size(), 0);
  t.rays = plan.units_in(block);
  CounterRng rng(seed, block);
  for (std::uint64_t i = 0; i < t.rays; ++i) {
    const double x = tile * rng.uniform(), y = tile * rng.uniform();
    const HeightfieldHit hit = scene.trace(Vec3<double>(x, y, z0), -wi);
    if (hit.edge_grazes > 0) ++t.diagnostics.edge_grazes;
    if (!hit.is_hit()) {
      if (hit.outcome == RayOutcome::unresolved) ++t.diagnostics.unresolved;
      else ++t.diagnostics.leaked;  // a downward ray must hit: escaping or leaking is a leak
      continue;
    }
    const Vec3<double> m = field.triangle_normal(hit.triangle);
    if (!(m.dot(wi) > 0.0)) {
      ++t.diagnostics.backfacing;
      continue;
    }
    ++t.hits;
    for (std::size_t k = 0; k < binnings.size(); ++k) {
      const auto bin = binnings[k].bin_of(m);
      if (bin) ++t.counts[k][std::size_t(*bin)];
      else ++t.unbinned[k];
    }
  }
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
  const auto start = std::chrono::steady_clock::now();
  const BlockRunStatus status = for_each_block(
      selected_blocks(plan, options.blocks), options.run, {"trace vndf (heightfield)", plan},
      [&](std::uint64_t block) { return trace_heightfield_block(scene, wi, binnings, plan, options.seed, block); },
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

// Sums for a ratio estimator R = sum y / sum x.
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
  void merge(const RatioSums& o) {
    x += o.x, y += o.y, xx += o.xx, yy += o.yy, xy += o.xy;
    n += o.n;
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
    e.se = std::max(e.se, std::sqrt(pt * (1.0 - pt) / n_eff));
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
  void merge(const G2Sums& o) {
    measured.merge(o.measured);
    vs_analytic.merge(o.vs_analytic);
    vs_empirical.merge(o.vs_empirical);
    pred_analytic += o.pred_analytic;
    pred_empirical += o.pred_empirical;
    sep_analytic += o.sep_analytic;
    sep_empirical += o.sep_empirical;
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

// Equal-area quantiles of <v, m> over the front-facing projected area (weight <v,m>+/mz per triangle):
// edges[0] = 0 < ... < edges[k] = 1, and the exact share of each bin. Also the edge below which the facets
// hold the share `fine` of the projected area (the near-grazing class [0, fine_edge)) and its exact share.
void normal_bin_edges(const microgeom::Heightfield& field, const Vec3<double>& v, int k, std::vector<double>& edges,
                      std::vector<double>& shares, double fine, double& fine_edge, double& fine_share) {
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
  double total = 0;
  for (const auto& p : all) total += p.second;
  edges.assign(std::size_t(k) + 1, 0.0);
  edges[std::size_t(k)] = 1.0;
  shares.assign(std::size_t(k), 0.0);
  double cum = 0, last_cum = 0;
  int next = 1;
  for (std::size_t idx = 0; idx < all.size() && next < k; ++idx) {
    cum += all[idx].second;
    if (cum >= total * next / k) {
      // Edge between this facet and the next one (bins are [lo, hi)).
      const double hi = idx + 1 < all.size() ? 0.5 * (double(all[idx].first) + double(all[idx + 1].first))
                                              : double(all[idx].first);
      edges[std::size_t(next)] = hi;
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
  // The near-grazing edge: the first facet at which the cumulative share reaches `fine`; the edge lies
  // between it and the next facet, as for the bins.
  fine_edge = 1.0;
  fine_share = 1.0;
  cum = 0;
  for (std::size_t idx = 0; idx < all.size(); ++idx) {
    cum += all[idx].second;
    if (cum >= total * fine) {
      fine_edge = idx + 1 < all.size() ? 0.5 * (double(all[idx].first) + double(all[idx + 1].first)) : 1.0;
      fine_share = total > 0 ? cum / total : 0.0;
      break;
    }
  }
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
      double sum = 0;
      for (int i = 0; i < n_; ++i) {
        for (int t = 0; t < 2; ++t) {
          const Eigen::Vector2d s = field.triangle_slope(i, j, t);
          const double wk = std::max(v.z() - s.x() * v.x() - s.y() * v.y(), 0.0);
          w[std::size_t(2 * i + t)] = wk;
          sum += wk;
        }
      }
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

int bin_index(const std::vector<double>& edges, double x) {
  // edges[0] .. edges[k]; bin b = [edges[b], edges[b+1]); values outside clamp to the end bins.
  const auto it = std::upper_bound(edges.begin() + 1, edges.end() - 1, x);
  return int(it - (edges.begin() + 1));
}

}  // namespace

MaskingResult estimate_masking(const HeightfieldScene& scene, const AnalyticSmith& analytic,
                               const EmpiricalSmith& empirical, const Vec3<double>& v_in, const MaskingOptions& options) {
  if (!(v_in.z() > 0.0) || !v_in.allFinite()) {
    throw std::invalid_argument(fmt::format("view direction ({}, {}, {}) must point above the horizon", v_in.x(), v_in.y(), v_in.z()));
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
  const Vec3<double> v = v_in.normalized();
  const bool projected = options.sampling == PointSampling::projected;
  const std::optional<Vec3<double>> light =
      options.light ? std::optional<Vec3<double>>(options.light->normalized()) : std::nullopt;
  const auto& field = scene.field();
  const double tile = field.tile_size();
  const int kn = options.normal_bins, kh = options.height_bins;

  MaskingResult result;
  result.v = v;
  result.sampling = options.sampling;
  std::unique_ptr<ProjectedAreaSampler> sampler;
  if (projected) {
    sampler = std::make_unique<ProjectedAreaSampler>(field, v);
    result.projected_area = sampler->total() / double(field.triangle_count());
  } else {
    result.projected_area = empirical.projected_area(v);
  }
  if (!(result.projected_area > 0)) throw std::invalid_argument("estimate_masking: no facet faces the view");
  result.light = light;
  result.cone_deg = options.cone_deg;
  result.lambda_analytic = analytic.Lambda(v);
  result.lambda_empirical = empirical.Lambda(v);
  result.g1_smith_analytic = analytic.G1(v);
  result.g1_smith_empirical = 1.0 / (1.0 + result.lambda_empirical);

  std::vector<double> nedges, nshares;
  double grazing_edge = 1.0, grazing_share = 1.0;
  normal_bin_edges(field, v, kn, nedges, nshares, options.grazing_share, grazing_edge, grazing_share);
  std::vector<double> hedges(std::size_t(kh) + 1);
  {
    const auto& hs = empirical.sorted_heights();
    for (int b = 0; b <= kh; ++b) {
      const std::size_t idx = std::min(hs.size() - 1, std::size_t(double(hs.size()) * b / kh));
      hedges[std::size_t(b)] = double(hs[idx]);
    }
    hedges.front() = field.min_height();
    hedges.back() = field.max_height();
  }

  // Smith constants.
  const double g1a_v = analytic.G1(v), g1e_v = result.g1_smith_empirical;
  const double lambda_a_v = result.lambda_analytic, lambda_e_v = result.lambda_empirical;
  double pair_a = 0, pair_e = 0, pair_sep_a = 0, pair_sep_e = 0;
  Vec3<double> half = Vec3<double>::UnitZ();
  double cos_cone = std::cos(options.cone_deg * kPi<double> / 180.0);
  if (light) {
    pair_a = analytic.G2(v, *light);
    pair_e = empirical.G2(v, *light);
    pair_sep_a = analytic.G2_separable(v, *light);
    pair_sep_e = g1e_v * empirical.G1(*light);
    half = (v + *light).normalized();
  }
  if (options.mirror) empirical.Lambda_tabulated(v);  // build the tables before the parallel loop

  const BlockPlan plan{options.samples, kSamplesPerBlock};
  const auto start = std::chrono::steady_clock::now();
  auto sample_block = [&](std::uint64_t block) {
    embree::FlushDenormalsScope ftz;
    BlockSums bs;
    bs.normal.assign(std::size_t(kn), {});
    bs.height.assign(std::size_t(kh), {});
    bs.height_pred_analytic.assign(std::size_t(kh), 0.0);
    bs.height_pred_empirical.assign(std::size_t(kh), 0.0);
    const std::uint64_t first = block * kSamplesPerBlock;
    const std::uint64_t count = std::min(kSamplesPerBlock, options.samples - first);
    CounterRng rng(options.seed, block);
    auto shadow = [&](const Vec3<double>& p, const Vec3<double>& dir, std::uint32_t tri) {
      RayOutcome outcome;
      const bool visible = scene.escapes(p, dir, tri, &outcome);
      ++bs.rays;
      if (outcome == RayOutcome::leaked) ++bs.leaked;
      if (outcome == RayOutcome::unresolved) ++bs.unresolved;
      return visible;
    };
    const double h = field.cell_size();
    for (std::uint64_t i = 0; i < count; ++i) {
      ++bs.samples;
      double x, y;
      std::uint32_t tri;
      if (projected) {
        // A triangle with probability ~ w, then a uniform point on it (local u >= v for triangle 0).
        tri = sampler->sample(rng.uniform(), rng.uniform());
        const auto c = field.triangle_index(tri);
        const double a = rng.uniform(), b = rng.uniform();
        const double lu = c.t == 0 ? std::max(a, b) : std::min(a, b), lv = c.t == 0 ? std::min(a, b) : std::max(a, b);
        x = (c.i + lu) * h;
        y = (c.j + lv) * h;
      } else {
        x = tile * rng.uniform();
        y = tile * rng.uniform();
        tri = field.triangle_at(x, y);
      }
      const Vec3<double> m = field.triangle_normal(tri);
      const double vm = v.dot(m);
      if (!(vm > 0)) continue;
      ++bs.front;
      // Sample weight: w for uniform points, 1 for points already drawn proportionally to w.
      const double w = projected ? 1.0 : vm / m.z();
      const double z = field.height_at(x, y);
      const Vec3<double> p(x, y, z);
      const bool vis = shadow(p, v, tri);
      const double y_v = vis ? w : 0.0;
      bs.leak_y += y_v;
      bs.leak_yy += y_v * y_v;
      bs.g1.add(w, y_v);
      bs.normal[std::size_t(bin_index(nedges, vm))].add(w, y_v);
      if (vm < grazing_edge) bs.near_grazing.add(w, y_v);
      const std::size_t hb = std::size_t(bin_index(hedges, z));
      bs.height[hb].add(w, y_v);
      const double c1 = empirical.height_cdf(z);
      bs.height_pred_analytic[hb] += w * EmpiricalSmith::height_masking(c1, lambda_a_v);
      bs.height_pred_empirical[hb] += w * EmpiricalSmith::height_masking(c1, lambda_e_v);
      if (options.mirror) {
        const Vec3<double> l = reflect(v, m);
        const bool vis_l = vis && l.z() > 0 && shadow(p, l, tri);
        const double y2 = vis_l ? w : 0.0;
        const double ga = analytic.G2(v, l), ge = empirical.G2_tabulated(v, l);
        bs.mirror.measured.add(w, y2);
        bs.mirror.vs_analytic.add(w * ga, y2);
        bs.mirror.vs_empirical.add(w * ge, y2);
        bs.mirror.pred_analytic += w * ga;
        bs.mirror.pred_empirical += w * ge;
        bs.mirror.sep_analytic += w * g1a_v * analytic.G1(l);
        bs.mirror.sep_empirical += l.z() > 0 ? w * g1e_v / (1.0 + empirical.Lambda_tabulated(l)) : 0.0;
      }
      if (light && light->dot(m) > 0) {
        const bool vis_l = vis && shadow(p, *light, tri);
        const double y2 = vis_l ? w : 0.0;
        auto add_pair = [&](G2Sums& g) {
          g.measured.add(w, y2);
          g.vs_analytic.add(w * pair_a, y2);
          g.vs_empirical.add(w * pair_e, y2);
          g.pred_analytic += w * pair_a;
          g.pred_empirical += w * pair_e;
          g.sep_analytic += w * pair_sep_a;
          g.sep_empirical += w * pair_sep_e;
        };
        add_pair(bs.pair);
        if (m.dot(half) >= cos_cone) add_pair(bs.cone);
      }
    }
    return bs;
  };
  // Reduced in block order (deterministic).
  BlockSums total;
  total.normal.assign(std::size_t(kn), {});
  total.height.assign(std::size_t(kh), {});
  total.height_pred_analytic.assign(std::size_t(kh), 0.0);
  total.height_pred_empirical.assign(std::size_t(kh), 0.0);
  auto add_block = [&](BlockSums&& bs, std::uint64_t) {
    total.samples += bs.samples;
    total.front += bs.front;
    total.rays += bs.rays;
    total.leaked += bs.leaked;
    total.unresolved += bs.unresolved;
    total.leak_y += bs.leak_y;
    total.leak_yy += bs.leak_yy;
    total.g1.merge(bs.g1);
    for (int b = 0; b < kn; ++b) total.normal[std::size_t(b)].merge(bs.normal[std::size_t(b)]);
    total.near_grazing.merge(bs.near_grazing);
    for (int b = 0; b < kh; ++b) {
      total.height[std::size_t(b)].merge(bs.height[std::size_t(b)]);
      total.height_pred_analytic[std::size_t(b)] += bs.height_pred_analytic[std::size_t(b)];
      total.height_pred_empirical[std::size_t(b)] += bs.height_pred_empirical[std::size_t(b)];
    }
    total.mirror.merge(bs.mirror);
    total.pair.merge(bs.pair);
    total.cone.merge(bs.cone);
  };
  const BlockRunStatus status = for_each_block(selected_blocks(plan, options.blocks), options.run,
                                               {"trace masking", plan}, sample_block, add_block);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.blocks = status.done;
  result.total_blocks = plan.blocks();
  result.samples = total.samples;
  result.front_facing = total.front;
  result.rays = total.rays;
  result.leaked = total.leaked;
  result.unresolved = total.unresolved;
  result.partial = status.cancelled;
  result.g1 = total.g1.proportion();
  if (projected) {
    const double scale = result.projected_area / v.z();
    result.leak_ratio = {result.g1.value * scale, result.g1.se * scale};
  } else if (total.samples > 1) {
    const double ns = double(total.samples);
    const double mean = total.leak_y / ns;
    const double var = std::max(total.leak_yy / ns - mean * mean, 0.0) / (ns - 1.0);
    result.leak_ratio = {mean / v.z(), std::sqrt(var) / v.z()};
  }
  for (int b = 0; b < kn; ++b) {
    ConditionalBin cb;
    const RatioSums& s = total.normal[std::size_t(b)];
    cb.lo = nedges[std::size_t(b)];
    cb.hi = nedges[std::size_t(b) + 1];
    cb.share = nshares[std::size_t(b)];
    cb.samples = s.n;
    cb.g1 = s.proportion();
    cb.ratio = ratio_of_ratios(s, total.g1);
    cb.smith_analytic = g1a_v;
    cb.smith_empirical = g1e_v;
    result.by_normal.push_back(cb);
  }
  {
    ConditionalBin& cb = result.near_grazing;
    cb.lo = 0.0;
    cb.hi = grazing_edge;
    cb.share = grazing_share;
    cb.samples = total.near_grazing.n;
    cb.g1 = total.near_grazing.proportion();
    cb.ratio = ratio_of_ratios(total.near_grazing, total.g1);
    cb.smith_analytic = g1a_v;
    cb.smith_empirical = g1e_v;
  }
  for (int b = 0; b < kh; ++b) {
    ConditionalBin cb;
    const RatioSums& s = total.height[std::size_t(b)];
    cb.lo = hedges[std::size_t(b)];
    cb.hi = hedges[std::size_t(b) + 1];
    cb.share = total.g1.x > 0 ? s.x / total.g1.x : 0.0;
    cb.samples = s.n;
    cb.g1 = s.proportion();
    cb.ratio = ratio_of_ratios(s, total.g1);
    if (s.x > 0) {
      cb.smith_analytic = total.height_pred_analytic[std::size_t(b)] / s.x;
      cb.smith_empirical = total.height_pred_empirical[std::size_t(b)] / s.x;
    }
    result.by_height.push_back(cb);
  }
  if (options.mirror) result.mirror = total.mirror.result();
  if (light) {
    result.pair = total.pair.result();
    result.pair_cone = total.cone.result();
  }
  return result;
}

// ---- JSON -------------------------------------------------------------------------------------------------------

nlohmann::json to_json(const Estimate& e) { return {{"value", e.value}, {"stderr", e.se}}; }

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
