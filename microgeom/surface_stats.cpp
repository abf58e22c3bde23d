#include "microgeom/surface_stats.h"

#include "microgeom/ndf_match.h"
#include "microgeom/rank_order.h"

#include <fmt/core.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <limits>
#include <bit>
#include <cmath>
#include <numbers>

namespace microgeom {

double reference_radius_cdf(NdfKind ref, double r) {
  if (!(r > 0)) return 0.0;
  if (ref == NdfKind::ggx) return std::isinf(r) ? 1.0 : r * r / (1.0 + r * r);
  return -std::expm1(-r * r);
}

double reference_radius_quantile(NdfKind ref, double q) {
  if (!(q > 0)) return 0.0;
  if (q >= 1) return std::numeric_limits<double>::infinity();
  if (ref == NdfKind::ggx) return std::sqrt(q / (1.0 - q));
  return std::sqrt(-std::log1p(-q));
}

double effective_patches(int resolution, double corr_cells) {
  const double cells = std::max(corr_cells, 1.0);
  return std::pow(resolution / cells, 2.0);
}

NdfTolerance tolerance_for(NdfKind ref, int resolution, double corr_cells) {
  // A single tile of a random field is a sample of about n_eff = (N/l)^2 independent patches: a histogram
  // fraction p fluctuates with relative sd ~ sqrt((1 - p) / (p n_eff)) even when the ensemble law is exact.
  // The GGX assemblies force the radius law on every tile (slope matching), so only the angular bins carry
  // this noise; the Beckmann control forces nothing but the second moment, so all its bounds carry it.
  // The constants are calibrated over seeds and resolutions (docs/reference/surfaces.md, section 3): 2-3.3 x the
  // largest ratio error / sqrt(1/(p n_eff)) observed.
  NdfTolerance t;
  const double n_eff = effective_patches(resolution, corr_cells);
  t.angular_bin = std::max(t.angular_bin, kAngularNoiseFactor * std::sqrt(kAngularBins / n_eff));
  if (ref == NdfKind::beckmann) {
    t.quantile = std::max(t.quantile, kBeckmannQuantileNoiseFactor / std::sqrt(n_eff));
    t.radius_bin = std::max(t.radius_bin, kBeckmannRadiusNoiseFactor * std::sqrt(kRadiusBins / n_eff));
  }
  return t;
}

namespace {

template <class F> void parallel_chunks(std::size_t n, F&& f) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1 << 14),
                    [&](const tbb::blocked_range<std::size_t>& r) { f(r.begin(), r.end()); });
}

// Orders like the float for all finite values (negative floats: flip all bits; others: flip the sign).
std::uint32_t ordered_bits(float v) {
  const std::uint32_t b = std::bit_cast<std::uint32_t>(v);
  return (b & 0x80000000u) ? ~b : (b | 0x80000000u);
}

// Spearman correlation from two rank permutations (Pearson correlation of the ranks).
double spearman(const std::vector<std::uint32_t>& ra, const std::vector<std::uint32_t>& rb) {
  const std::size_t n = ra.size();
  if (n < 2) return 0.0;
  const double mean = (double(n) - 1.0) / 2.0;
  const std::size_t chunk = 1 << 16, chunks = (n + chunk - 1) / chunk;
  std::vector<double> partial(chunks);
  tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
    double s = 0;
    for (std::size_t k = c * chunk; k < std::min(n, (c + 1) * chunk); ++k) s += (ra[k] - mean) * (rb[k] - mean);
    partial[c] = s;
  });
  double cov = 0;
  for (double s : partial) cov += s;
  const double var = (double(n) * n - 1.0) / 12.0 * double(n);  // sum of (rank - mean)^2 over a permutation
  return var > 0 ? cov / var : 0.0;
}

// Deterministic parallel sum of f(k) over k in [0, n).
template <class F> double parallel_sum(std::size_t n, F&& f) {
  const std::size_t chunk = 1 << 16, chunks = (n + chunk - 1) / chunk;
  std::vector<double> partial(chunks);
  tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
    double s = 0;
    for (std::size_t k = c * chunk; k < std::min(n, (c + 1) * chunk); ++k) s += f(k);
    partial[c] = s;
  });
  double s = 0;
  for (double p : partial) s += p;
  return s;
}

double median_abs(std::vector<float> v) {
  if (v.empty()) return 0.0;
  for (float& x : v) x = std::fabs(x);
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(mid), v.end());
  double m = v[mid];
  if (v.size() % 2 == 0) m = 0.5 * (m + *std::max_element(v.begin(), v.begin() + std::ptrdiff_t(mid)));
  return m;
}

// Per-triangle physical slopes and centroid heights (float), computed from the heights when asked, so
// the statistics keep no per-triangle arrays but their ranks.
struct TriangleSamples {
  const Heightfield& field;
  std::size_t size() const { return field.triangle_count(); }
  std::array<float, 2> slope(std::size_t k) const {
    const Eigen::Vector2d s = field.triangle_slope(std::uint32_t(k));
    return {float(s.x()), float(s.y())};
  }
  float sx(std::size_t k) const { return slope(k)[0]; }
  float sy(std::size_t k) const { return slope(k)[1]; }
  float hc(std::size_t k) const {
    const auto c = field.triangle_index(std::uint32_t(k));
    return float(field.triangle_centroid_height(c.i, c.j, c.t));
  }
};

// One float per triangle (into a vector of `tris`).
template <class F> std::vector<float> per_triangle(std::size_t tris, const F& f) {
  std::vector<float> v(tris);
  parallel_chunks(tris, [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b; k < e; ++k) v[k] = f(k);
  });
  return v;
}

// Roughness: given, or fitted from the median |slope| per axis. GGX: the x-slope marginal is a Student-t
// with nu = 2 and scale ax/sqrt(2), whose |.| has median ax/sqrt(3). Beckmann: N(0, ax^2/2), whose |.| has
// median Phi^-1(3/4) ax / sqrt(2), Phi^-1(3/4) = 0.6744897501960817 (correctly rounded; Boost.Math's
// normal quantile gives 0.67448975019608182, one ulp above).
void fit_roughness(SurfaceStats& st, const TriangleSamples& t, const StatsOptions& opt) {
  const double med_x = median_abs(per_triangle(t.size(), [&](std::size_t k) { return t.sx(k); }));
  const double med_y = median_abs(per_triangle(t.size(), [&](std::size_t k) { return t.sy(k); }));
  const double fit = opt.reference == NdfKind::ggx ? std::sqrt(3.0) : std::sqrt(2.0) / 0.6744897501960817;
  st.fitted_alpha_x = fit * med_x;
  st.fitted_alpha_y = fit * med_y;
  st.alpha_fitted = !(opt.alpha_x && opt.alpha_y);
  st.alpha_x = opt.alpha_x ? *opt.alpha_x : st.fitted_alpha_x;
  st.alpha_y = opt.alpha_y ? *opt.alpha_y : st.fitted_alpha_y;
}

// Mean and rms slope per axis, and the second moments of the normalised slopes.
void slope_moments(SurfaceStats& st, const TriangleSamples& t, double ax, double ay) {
  const std::size_t tris = t.size();
  const double dn = double(tris);
  st.mean_slope_x = parallel_sum(tris, [&](std::size_t k) { return double(t.sx(k)); }) / dn;
  st.mean_slope_y = parallel_sum(tris, [&](std::size_t k) { return double(t.sy(k)); }) / dn;
  const double m2x = parallel_sum(tris, [&](std::size_t k) { const double s = t.sx(k); return s * s; }) / dn;
  const double m2y = parallel_sum(tris, [&](std::size_t k) { const double s = t.sy(k); return s * s; }) / dn;
  st.rms_slope_x = std::sqrt(m2x);
  st.rms_slope_y = std::sqrt(m2y);
  st.normalised_second_moment_x = m2x / (ax * ax);
  st.normalised_second_moment_y = m2y / (ay * ay);
}

// Counts of the normalised slopes in the radius bins and the (ring, sector) bins, all of equal reference
// probability; `radius` receives every triangle's normalised slope radius (float bits).
struct NdfCounts {
  std::array<double, kRadiusBins> radius{};
  std::array<double, kAngularBins> angular{};
};

NdfCounts ndf_counts(const TriangleSamples& t, double ax, double ay, NdfKind reference, std::vector<std::uint32_t>& radius) {
  const std::size_t tris = t.size();
  radius.resize(tris);
  const std::size_t chunk = 1 << 16, chunks = (tris + chunk - 1) / chunk;
  std::vector<std::array<std::uint64_t, kRadiusBins>> rb(chunks);
  std::vector<std::array<std::uint64_t, kAngularBins>> ab(chunks);
  tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
    rb[c].fill(0);
    ab[c].fill(0);
    for (std::size_t k = c * chunk; k < std::min(tris, (c + 1) * chunk); ++k) {
      const auto s = t.slope(k);
      const double u = s[0] / ax, v = s[1] / ay;
      const double r = std::sqrt(u * u + v * v);
      radius[k] = std::bit_cast<std::uint32_t>(float(r));
      const double F = reference_radius_cdf(reference, r);
      const int bin = std::min(kRadiusBins - 1, int(F * kRadiusBins));
      ++rb[c][bin];
      const int ring = std::min(kRingBins - 1, int(F * kRingBins));
      const double phi = std::atan2(v, u);  // (-pi, pi]
      const int sector = std::clamp(int((phi + std::numbers::pi) / (2 * std::numbers::pi) * kAngleBins), 0,
                                    kAngleBins - 1);
      ++ab[c][ring * kAngleBins + sector];
    }
  });
  NdfCounts counts;
  for (std::size_t c = 0; c < chunks; ++c) {
    for (int b = 0; b < kRadiusBins; ++b) counts.radius[b] += double(rb[c][b]);
    for (int b = 0; b < kAngularBins; ++b) counts.angular[b] += double(ab[c][b]);
  }
  return counts;
}

// The radius bins and (radius, angle) bins against their expected fractions.
void ndf_bins(SurfaceStats& st, const NdfCounts& counts, double dn) {
  for (int b = 0; b < kRadiusBins; ++b) {
    BinRow row;
    row.lo = reference_radius_quantile(st.reference, double(b) / kRadiusBins);
    row.hi = reference_radius_quantile(st.reference, double(b + 1) / kRadiusBins);
    row.expected_fraction = 1.0 / kRadiusBins;
    row.measured_fraction = counts.radius[b] / dn;
    row.rel_error = row.measured_fraction / row.expected_fraction - 1.0;
    st.max_radius_bin_error = std::max(st.max_radius_bin_error, std::fabs(row.rel_error));
    st.radius_bins.push_back(row);
  }
  for (int b = 0; b < kAngularBins; ++b) {
    st.angular_bin_errors[b] = counts.angular[b] / dn * kAngularBins - 1.0;
    st.max_angular_bin_error = std::max(st.max_angular_bin_error, std::fabs(st.angular_bin_errors[b]));
  }
}

// What the statistics need of the order of the slope radii: the order statistics at the quantiles'
// ranks, the sums of the centroid heights of the steepest triangles (in rank order), and every
// triangle's rank (written over its radius).
struct RadiusOrder {
  std::vector<std::size_t> wanted;  // ranks whose radius is kept
  std::vector<double> value;        // their radii
  std::array<std::size_t, 2> top_count{};
  std::array<double, 2> top_sum{};  // sum of hc over the top_count steepest, ascending rank
  double order_stat(std::size_t rank) const {
    return value[std::size_t(std::lower_bound(wanted.begin(), wanted.end(), rank) - wanted.begin())];
  }
};

constexpr std::array<double, 12> kQuantileLevels = {0.01, 0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 0.95, 0.99, 0.995, 0.999, 0.9999};
constexpr std::array<double, 2> kSteepestFractions = {0.01, 0.001};

// Ranks of the keys (value_of(k) << 32 | k) through detail::visit_in_rank_order with a buffer of a quarter
// of the triangles: visit(rank, key) in rank order, sequentially within each block.
template <class Value, class Visit> void in_rank_order(std::size_t tris, const Value& value_of, const Visit& visit) {
  std::vector<std::uint64_t> buffer(std::max<std::size_t>(2, tris / 4));
  detail::visit_in_rank_order(tris, value_of, buffer.data(), buffer.size(),
                              [&](std::size_t first, const std::uint64_t* keys, std::size_t count) {
                                visit(first, keys, count);
                              });
}

// Replaces radius (float bits) by the rank of each triangle (ties broken by index) and gathers `order`.
RadiusOrder rank_radii(const TriangleSamples& t, std::vector<std::uint32_t>& radius) {
  const std::size_t tris = radius.size();
  const double dn = double(tris);
  RadiusOrder o;
  o.wanted.push_back(tris - 1);
  for (double q : kQuantileLevels) {
    const std::size_t lo = std::size_t(q * (dn - 1.0));
    o.wanted.push_back(lo);
    o.wanted.push_back(std::min(lo + 1, tris - 1));
  }
  std::sort(o.wanted.begin(), o.wanted.end());
  o.wanted.erase(std::unique(o.wanted.begin(), o.wanted.end()), o.wanted.end());
  o.value.assign(o.wanted.size(), 0.0);
  for (std::size_t f = 0; f < kSteepestFractions.size(); ++f)
    o.top_count[f] = std::max<std::size_t>(1, std::size_t(kSteepestFractions[f] * dn));
  constexpr std::uint32_t kRanked = 0x80000000u;  // radii are >= +0: their top bit is clear
  in_rank_order(tris, [&](std::size_t k) { return radius[k]; },
                [&](std::size_t first, const std::uint64_t* keys, std::size_t count) {
                  for (std::size_t w = 0; w < o.wanted.size(); ++w)
                    if (o.wanted[w] >= first && o.wanted[w] < first + count)
                      o.value[w] = double(std::bit_cast<float>(std::uint32_t(keys[o.wanted[w] - first] >> 32)));
                  for (std::size_t f = 0; f < o.top_count.size(); ++f)
                    for (std::size_t r = std::max(first, tris - o.top_count[f]); r < first + count; ++r)
                      o.top_sum[f] += t.hc(std::uint32_t(keys[r - first]));
                  parallel_chunks(count, [&](std::size_t b, std::size_t e) {
                    for (std::size_t s = b; s < e; ++s) radius[std::uint32_t(keys[s])] = std::uint32_t(first + s) | kRanked;
                  });
                });
  parallel_chunks(tris, [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b; k < e; ++k) radius[k] &= ~kRanked;
  });
  return o;
}

// Quantiles of the normalised radius (linear interpolation between order statistics) against the
// reference's.
void radius_quantiles(SurfaceStats& st, const RadiusOrder& order, std::size_t tris) {
  const double dn = double(tris);
  auto order_stat = [&](std::size_t r) { return order.order_stat(r); };
  st.max_normalised_radius = order_stat(tris - 1);
  for (double q : kQuantileLevels) {
    const double pos = q * (dn - 1.0);
    const std::size_t lo = std::size_t(pos);
    const std::size_t hi = std::min(lo + 1, tris - 1);
    const double measured = order_stat(lo) + (pos - double(lo)) * (order_stat(hi) - order_stat(lo));
    const double expected = reference_radius_quantile(st.reference, q);
    const double rel = measured / expected - 1.0;
    st.quantiles.push_back({q, measured, expected, rel});
    if (q <= 0.999 + 1e-12) st.max_quantile_error = std::max(st.max_quantile_error, std::fabs(rel));
  }
}

// Verdict of the NDF against the tolerance: "ok", or every bound exceeded and by how much.
void ndf_verdict(SurfaceStats& st) {
  std::vector<std::string> misses;
  if (!(st.max_quantile_error <= st.tolerance.quantile))
    misses.push_back(fmt::format("slope-radius quantile error {:.3g}% > {:.3g}%", 100 * st.max_quantile_error,
                                 100 * st.tolerance.quantile));
  if (!(st.max_radius_bin_error <= st.tolerance.radius_bin))
    misses.push_back(fmt::format("radius-bin error {:.3g}% > {:.3g}%", 100 * st.max_radius_bin_error,
                                 100 * st.tolerance.radius_bin));
  if (!(st.max_angular_bin_error <= st.tolerance.angular_bin))
    misses.push_back(fmt::format("(radius, angle)-bin error {:.3g}% > {:.3g}%", 100 * st.max_angular_bin_error,
                                 100 * st.tolerance.angular_bin));
  st.ndf_within_tolerance = misses.empty();
  if (misses.empty()) {
    st.ndf_verdict = "ok";
  } else {
    for (std::size_t k = 0; k < misses.size(); ++k) st.ndf_verdict += (k ? "; " : "") + misses[k];
  }
}

// Vertex height moments.
void height_moments(SurfaceStats& st, const Heightfield& field) {
  const auto& hv = field.heights();
  const double nv = double(hv.size());
  st.height_mean = parallel_sum(hv.size(), [&](std::size_t k) { return double(hv[k]); }) / nv;
  const double mu = st.height_mean;
  auto dev = [&](std::size_t k) { return double(hv[k]) - mu; };
  const double c2 = parallel_sum(hv.size(), [&](std::size_t k) { return dev(k) * dev(k); }) / nv;
  const double c3 = parallel_sum(hv.size(), [&](std::size_t k) { return dev(k) * dev(k) * dev(k); }) / nv;
  const double c4 = parallel_sum(hv.size(), [&](std::size_t k) { const double d2 = dev(k) * dev(k); return d2 * d2; }) / nv;
  st.height_sd = std::sqrt(c2);
  st.height_min = field.min_height();
  st.height_max = field.max_height();
  st.height_skewness = c2 > 0 ? c3 / std::pow(c2, 1.5) : 0.0;
  st.height_excess_kurtosis = c2 > 0 ? c4 / (c2 * c2) - 3.0 : 0.0;
}

// Ranks 0..n-1 of the values (ties broken by index) into `rank`, which first holds the values' ordered
// bits: a ranked entry is marked in a bitmap (one bit per triangle) and read as 0xffffffff, above every
// finite value's bits, so the later blocks of visit_in_rank_order skip it.
template <class Value> void ranks_of(std::size_t tris, const Value& value_of, std::vector<std::uint32_t>& rank) {
  rank.resize(tris);
  parallel_chunks(tris, [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b; k < e; ++k) rank[k] = ordered_bits(value_of(k));
  });
  std::vector<std::uint64_t> ranked((tris + 63) / 64, 0);
  auto is_ranked = [&](std::size_t k) { return (ranked[k / 64] >> (k % 64)) & 1u; };
  in_rank_order(tris, [&](std::size_t k) { return is_ranked(k) ? 0xffffffffu : rank[k]; },
                [&](std::size_t first, const std::uint64_t* keys, std::size_t count) {
                  parallel_chunks(count, [&](std::size_t b, std::size_t e) {
                    for (std::size_t s = b; s < e; ++s) {
                      const std::uint32_t k = std::uint32_t(keys[s]);
                      rank[k] = std::uint32_t(first + s);
                      std::atomic_ref<std::uint64_t>(ranked[k / 64]).fetch_or(std::uint64_t(1) << (k % 64),
                                                                               std::memory_order_relaxed);
                    }
                  });
                });
}

// Height-slope coupling: Spearman correlations (ranks: ties broken by index) of the slope radius with the
// centroid height and with |height - median height|.
void height_slope_ranks(SurfaceStats& st, const TriangleSamples& t, const std::vector<std::uint32_t>& radius_rank) {
  const std::size_t tris = t.size();
  std::vector<float> tmp = per_triangle(tris, [&](std::size_t k) { return t.hc(k); });
  const std::size_t mid = tmp.size() / 2;
  std::nth_element(tmp.begin(), tmp.begin() + std::ptrdiff_t(mid), tmp.end());
  const float median = tmp[mid];
  std::vector<float>().swap(tmp);
  std::vector<std::uint32_t> rank;
  ranks_of(tris, [&](std::size_t k) { return t.hc(k); }, rank);
  st.spearman_height_slope = spearman(rank, radius_rank);
  ranks_of(tris, [&](std::size_t k) { return std::fabs(t.hc(k) - median); }, rank);
  st.spearman_extremity_slope = spearman(rank, radius_rank);
}

// Mean centroid height (in sd of centroid heights) of the steepest 1% and 0.1% of the triangles.
void steepest_heights(SurfaceStats& st, const TriangleSamples& t, const RadiusOrder& order) {
  const std::size_t tris = t.size();
  const double dn = double(tris);
  const double hmean = parallel_sum(tris, [&](std::size_t k) { return double(t.hc(k)); }) / dn;
  const double hsd =
      std::sqrt(parallel_sum(tris, [&](std::size_t k) { const double d = t.hc(k) - hmean; return d * d; }) / dn);
  auto top_mean = [&](std::size_t f) {
    return hsd > 0 ? (order.top_sum[f] / double(order.top_count[f]) - hmean) / hsd : 0.0;
  };
  st.steepest_1pct_height_z = top_mean(0);
  st.steepest_01pct_height_z = top_mean(1);
}

// The NDF error in the lobe bins of trace vndf (normalised slopes). Two float arrays for the moment
// (16 bytes per texel, beside the heights and the radius ranks: within the build's peak).
void lobe_bins_error(SurfaceStats& st, const TriangleSamples& t, double ax, double ay) {
  std::vector<float> ux(t.size()), uy(t.size());
  parallel_chunks(ux.size(), [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b; k < e; ++k) {
      const auto s = t.slope(k);
      ux[k] = float(s[0] / ax);
      uy[k] = float(s[1] / ay);
    }
  });
  st.lobe = lobe_ndf_error(ux, uy, st.reference, kDefaultLobeRows);
}

}  // namespace

SurfaceStats measure_surface(const Heightfield& field, const StatsOptions& opt) {
  SurfaceStats st;
  st.triangles = field.triangle_count();
  st.reference = opt.reference;
  st.tolerance = opt.tolerance;
  st.tile_size = field.tile_size();
  st.cell_size = field.cell_size();
  const TriangleSamples t{field};
  fit_roughness(st, t, opt);
  const double ax = st.alpha_x > 0 ? st.alpha_x : 1.0, ay = st.alpha_y > 0 ? st.alpha_y : 1.0;  // flat: avoid 0/0
  slope_moments(st, t, ax, ay);
  std::vector<std::uint32_t> radius;  // float bits of the normalised radius, then its rank
  ndf_bins(st, ndf_counts(t, ax, ay, opt.reference, radius), double(st.triangles));
  const RadiusOrder order = rank_radii(t, radius);
  radius_quantiles(st, order, st.triangles);
  ndf_verdict(st);
  lobe_bins_error(st, t, ax, ay);
  height_moments(st, field);
  height_slope_ranks(st, t, radius);
  steepest_heights(st, t, order);
  return st;
}

}  // namespace microgeom
