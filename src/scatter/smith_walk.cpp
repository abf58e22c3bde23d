// scatter: the Smith random walk (smith_walk.h), Heitz, Hanika, d'Eon, Dachsbacher 2016.
#include "scatter/smith_walk.h"

#include "core/parse.h"
#include "core/random.h"
#include "microfacet/beckmann.h"
#include "microfacet/bsdf.h"
#include "microfacet/ggx.h"
#include "microfacet/roughness.h"
#include "microfacet/upper_vndf.h"
#include "scatter/smith_walk_lanes.h"
#include "stats/direction_binner.h"

#include <boost/math/special_functions/erf.hpp>
#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <span>
#include <stdexcept>

namespace microsim {

std::string to_string(HeightDistribution heights) {
  return heights == HeightDistribution::uniform ? "uniform" : "gaussian";
}

HeightDistribution parse_height_distribution(std::string_view what, std::string_view text) {
  if (text == "uniform") return HeightDistribution::uniform;
  if (text == "gaussian") return HeightDistribution::gaussian;
  throw ParseError(
      fmt::format("{} {}: unknown height distribution (expected uniform or gaussian)", what, quote_excerpt(text)));
}

std::string to_string(WalkKernel kernel) { return kernel == WalkKernel::scalar ? "scalar" : "lanes"; }

WalkKernel parse_walk_kernel(std::string_view what, std::string_view text) {
  if (text == "scalar") return WalkKernel::scalar;
  if (text == "lanes") return WalkKernel::lanes;
  throw ParseError(fmt::format("{} {}: unknown walk kernel (expected scalar or lanes)", what, quote_excerpt(text)));
}

std::string describe(const SmithMicrosurface& s) {
  return fmt::format("{} alpha={},{} heights={}", to_string(s.ndf), s.alpha_x, s.alpha_y, to_string(s.heights));
}

void check_smith_microsurface(const SmithMicrosurface& s) { check_supported_alpha("smith walk alpha", s.alpha_x, s.alpha_y); }

Estimate SmithWalkEval::value(int channel, int order_bin) const {
  return order_bin < 0 ? total[std::size_t(channel)] : order[std::size_t(channel)][std::size_t(order_bin)];
}

namespace {

using detail::WalkFault;
using Weights = std::array<double, Material::kMaxChannels>;

constexpr double kInf = std::numeric_limits<double>::infinity();

// The height distribution through its CDF C1 and the inverse (Heitz et al. 2016 sec. 3): uniform on [-1, 1]
// or the standard Gaussian, both symmetric (C1(-h) = 1 - C1(h)), as the side change needs: the microsurface
// seen from below then has the same height distribution. C1 is kept in [DBL_MIN, 1] (a ray at C1 = 0 could never rise again: a set of
// measure zero that rounding could otherwise reach) and the inverse never returns +-inf.
struct Heights {
  HeightDistribution kind;

  double cdf(double h) const {
    if (h == kInf) return 1.0;
    const double c = kind == HeightDistribution::uniform ? (h + 1) / 2 : 0.5 * std::erfc(-h / std::sqrt(2.0));
    return std::clamp(c, std::numeric_limits<double>::min(), 1.0);
  }
  double inverse(double c) const {
    c = std::clamp(c, std::numeric_limits<double>::min(), 1 - 0x1p-53);
    if (kind == HeightDistribution::uniform) return 2 * c - 1;
    return -std::sqrt(2.0) * boost::math::erfc_inv(2 * c);
  }
};

// The walk needs the heights only through C1 (every rule of sec. 3 is a rule on C1(h), and the side change
// is C1 -> 1 - C1 by the symmetry), so for uniform heights the path keeps g = ln C1(h) instead of h: the
// rules become
//   escape upward iff ln U <= Lambda g (U <= C1^Lambda), then g' = g - ln U / Lambda;
//   downward g' = g + ln U / (1 + Lambda);          side change g' = ln(1 - e^g);
// one logarithm per meeting instead of one or two powers, the same decisions up to rounding. g is kept in
// [ln DBL_MIN, ln(1 - 2^-53)] after a meeting, the range of C1 above. The Gaussian keeps the heights
// themselves (through Heights): the check that the distribution drops out.
inline constexpr double kLogCdfMin = -708.39641853226410622;    // ln DBL_MIN (below it: DBL_MIN's log)
inline constexpr double kLogCdfMax = -1.1102230246251565e-16;  // ln(1 - 2^-53)

// ln(1 - e^g) for g <= 0 without cancellation (Maechler 2012, "Accurately computing log(1 - exp(-|a|))").
double log_one_minus_exp(double g) { return g > -0.6931471805599453 ? std::log(-std::expm1(g)) : std::log1p(-std::exp(g)); }

// One path's state, in the frame of the side it is on: the global frame outside (above the dielectric, or
// for every reflecting material), its point reflection v -> -v inside the dielectric's solid, where the
// microsurface seen from below is again a heightfield above it with heights -h and the same normals.
struct Path {
  Vec3<double> w;  // travel direction
  double h;        // the last meeting's height h (Gaussian) or ln C1(h) (uniform); Microsurface::start_height() before the first
  bool inside;
  int events = 0;  // facet events so far
  Weights weight;
};

// The microsurface of one walk: Ndf (GGX<double> or Beckmann<double>), the heights, the material.
template <class Ndf> class Microsurface {
public:
  Microsurface(const Ndf& ndf, const Material& material, HeightDistribution heights, WalkFault fault)
      : ndf_(ndf), material_(material), heights_{heights}, log_cdf_(heights == HeightDistribution::uniform), fault_(fault) {}

  const Material& material() const { return material_; }

  // The height state above the surface (h = +inf, C1 = 1).
  double start_height() const { return log_cdf_ ? 0.0 : kInf; }

  // G1(w, h) = C1(h)^Lambda(w) for upward w (sec. 3), 0 for downward or horizontal w. lambda: Lambda(w),
  // which the caller may have at hand (Lambda(-w) = Lambda(w)).
  double escape_probability(const Vec3<double>& w, double h, double lambda) const {
    if (!(w.z() > 0)) return 0.0;
    if (log_cdf_) return h == 0 ? 1.0 : std::exp(lambda * h);
    return std::pow(heights_.cdf(h), lambda);
  }
  double Lambda(const Vec3<double>& w) const { return ndf_.Lambda(w); }

  // The height of the next meeting of a ray leaving height h in w, or nullopt when it escapes; u uniform in
  // [0, 1). C1(h') = C1(h) U^(-1/Lambda) with U = 1 - u in (0, 1] (sec. 3); downward with
  // Lambda(w) = -1 - Lambda(-w). Lambda = 0 upward (no masking) always escapes; Lambda = inf (horizontal)
  // meets the surface at once (h' = h).
  std::optional<double> next_height(const Vec3<double>& w, double h, double u) const {
    const double v = 1 - u, lambda = ndf_.Lambda(w);
    if (log_cdf_) return next_log_cdf(w, h, std::log(v), lambda);
    const double c = heights_.cdf(h);
    double c_next;
    if (w.z() > 0) {
      if (v <= std::pow(c, lambda)) return std::nullopt;
      c_next = c * std::pow(v, -1 / lambda);
    } else {
      c_next = c * std::pow(v, 1 / (1 + lambda));
    }
    return c_next == c ? h : heights_.inverse(std::min(c_next, 1.0));
  }

  // The microfacet a ray travelling in w meets: an upper normal facing -w.
  std::optional<Vec3<double>> normal(const Vec3<double>& w, Vec2<double> u) const {
    return sample_upper_visible_normal(ndf_, Vec3<double>(-w), u);
  }

  // The height a refraction leaves on the other side: -h in that side's frame (ln(1 - C1) for ln C1).
  double other_side_height(double h) const {
    if (fault_ == WalkFault::keep_height_on_refraction) return h;
    return log_cdf_ ? std::clamp(log_one_minus_exp(h), kLogCdfMin, kLogCdfMax) : -h;
  }

  // The facet event at normal m: weights, direction, side (sec. 5).
  void scatter(Path& p, const Vec3<double>& m, Vec2<double> u) const {
    Weights factors;
    const FacetEvent e = scatter_on_facet(material_, Vec3<double>(-p.w), m, p.inside, u,
                                          std::span<double>(factors.data(), std::size_t(material_.channels())));
    for (int c = 0; c < material_.channels(); ++c) p.weight[std::size_t(c)] *= factors[std::size_t(c)];
    ++p.events;
    if (e.refracted) {
      p.inside = !p.inside;
      p.h = other_side_height(p.h);
      p.w = -e.wo;
    } else {
      p.w = e.wo;
    }
  }

  // The phase function of the facet event at a meeting of a ray travelling in w, toward wo (both in the
  // side's frame), per channel into `out`: the density per unit solid angle of wo. Reflection through the
  // half vector m = (wi + wo) / |wi + wo|, wi = -w: F D_wi(m) / (4 <wi, m>) (Walter 2007 eq. 14); a
  // dielectric's refraction through m = -(wi + eta wo) / |.|: (1 - F) D_wi(m) eta^2 |<wo, m>| /
  // (<wi, m> + eta <wo, m>)^2 (Walter 2007 eq. 16-17), eta = n_t / n_i; Lambertian: albedo <wo, m_s>+ / pi
  // at the sampled normal m_s (an unbiased estimate of its phase function, sec. 5.3). Returns whether the
  // event refracts toward wo (wo below this side's horizon), 0 everywhere when it cannot reach wo.
  bool phase(const Path& p, const Vec3<double>& wo, const Vec3<double>& m_sampled, std::span<double> out) const {
    const Vec3<double> wi = -p.w;
    const int channels = material_.channels();
    std::fill(out.begin(), out.begin() + channels, 0.0);
    const bool refraction = wo.z() < 0;
    if (material_.kind() == MaterialKind::lambertian) {
      if (!refraction) out[0] = material_.albedo() * std::max(0.0, wo.dot(m_sampled)) / kPi<double>;
      return false;
    }
    if (refraction) {
      if (material_.kind() == MaterialKind::dielectric) out[0] = refraction_density(wi, wo, p.inside);
      return true;
    }
    const Vec3<double> m = normalized_or_zero(Vec3<double>(wi + wo));
    if (!(m.z() > 0)) return false;
    const double im = wi.dot(m), d = upper_visible_normal_pdf(ndf_, wi, m) / (4 * im);
    if (!(d > 0)) return false;
    for (int c = 0; c < channels; ++c) out[std::size_t(c)] = d * reflectance(im, p.inside, c);
    return false;
  }

private:
  double reflectance(double cos_i, bool inside, int channel) const {
    switch (material_.kind()) {
      case MaterialKind::conductor: return fresnel_conductor(cos_i, material_.ior(channel));
      case MaterialKind::dielectric: return fresnel_dielectric(cos_i, inside ? 1 / material_.eta() : material_.eta());
      default: return 1.0;
    }
  }

  double refraction_density(const Vec3<double>& wi, const Vec3<double>& wo, bool inside) const {
    const double eta = inside ? 1 / material_.eta() : material_.eta();
    Vec3<double> m = normalized_or_zero(Vec3<double>(-(wi + eta * wo)));
    if (m.z() < 0) m = -m;
    const double im = wi.dot(m), om = wo.dot(m);
    if (!(m.z() > 0) || !(im > 0) || !(om < 0)) return 0.0;
    const double denom = sqr(im + eta * om);
    if (!(denom > 0)) return 0.0;
    return (1 - fresnel_dielectric(im, eta)) * upper_visible_normal_pdf(ndf_, wi, m) * eta * eta * -om / denom;
  }

  // next_height for g = ln C1(h), given ln U (<= 0): the rules above. At g = 0 (C1 = 1, only before the
  // first meeting) an upward ray always escapes, as C1^Lambda = 1 says even for Lambda = inf.
  std::optional<double> next_log_cdf(const Vec3<double>& w, double g, double log_u, double lambda) const {
    double g_next;
    if (w.z() > 0) {
      if (g == 0 || log_u <= lambda * g) return std::nullopt;
      g_next = g - log_u / lambda;
    } else {
      g_next = g + log_u / (1 + lambda);
    }
    return g_next == g ? g : std::clamp(g_next, kLogCdfMin, kLogCdfMax);
  }

  Ndf ndf_;
  const Material& material_;
  Heights heights_;
  bool log_cdf_;  // uniform heights: the path's h is ln C1(h)
  WalkFault fault_;
};

// The path of light arriving along -wi (wi global; from inside the solid when wi.z < 0), with weight 1 in
// each of its `channels` (the rest of the array is never read).
Path start_path(const Vec3<double>& wi, int channels, double start_height) {
  Path p;
  p.inside = wi.z() < 0;
  p.w = p.inside ? wi : Vec3<double>(-wi);  // the travel direction -wi, in the side's frame
  p.h = start_height;
  std::fill(p.weight.begin(), p.weight.begin() + channels, 1.0);
  return p;
}

// The direction in the global frame of a direction in the path's side frame.
Vec3<double> global_direction(const Path& p, const Vec3<double>& w) { return p.inside ? Vec3<double>(-w) : w; }

void check_walk(const SmithMicrosurface& surface, const ScatterOptions& o) {
  check_smith_microsurface(surface);
  check_scatter_options(o);
  if (o.wi.z() < 0 && !o.material.transmits()) {
    throw std::invalid_argument(
        fmt::format("smith walk: light from inside (wi.z = {}) needs a dielectric, not {}", o.wi.z(), o.material.describe()));
  }
}

std::string walk_measurement(const SmithMicrosurface& s, const ScatterOptions& o) {
  return fmt::format("smith-walk {} material={} wi={:.17g},{:.17g},{:.17g} max_order={} rows={} paths={}", describe(s),
                     o.material.describe(), o.wi.x(), o.wi.y(), o.wi.z(), o.max_order, o.rows, o.paths);
}

// Calls f(ndf) with the surface's distribution as GGX<double> or Beckmann<double>.
template <class F> decltype(auto) with_ndf(const SmithMicrosurface& s, F&& f) {
  if (s.ndf == NdfKind::beckmann) return f(Beckmann<double>(s.alpha_x, s.alpha_y));
  return f(GGX<double>(s.alpha_x, s.alpha_y));
}

// ---- the walk into the histogram -------------------------------------------------------------------------

// How one path ended, recorded by its block and added to the histogram in block order.
struct WalkEnd {
  enum Kind : int { escaped, unfinished, lost } kind;
  int order;  // facet events
  int bin;    // escaped: the bin, or -1 for a direction the binning cannot place
  Vec3<double> direction = Vec3<double>::Zero();  // escaped: the outgoing direction (global)
};

struct BlockEnds {
  std::vector<WalkEnd> ends;
  std::vector<double> weights;  // channels per end
};

// Follows one path to its end (sec. 4). bins: the histogram's binning (FastDirectionBinner gives exactly
// DirectionBinning::bin_of), or nullptr where the bin is not needed (the sampler's rows): then bin -1.
template <class Ndf>
void walk_path(const Microsurface<Ndf>& surface, const ScatterOptions& o, const FastDirectionBinner* bins,
               CounterRng& rng, BlockEnds& out) {
  Path p = start_path(o.wi, surface.material().channels(), surface.start_height());
  WalkEnd end{WalkEnd::lost, 0, -1};
  for (;;) {
    const std::optional<double> h = surface.next_height(p.w, p.h, rng.uniform());
    if (!h) {
      const Vec3<double> out_direction = global_direction(p, p.w);
      end = {WalkEnd::escaped, p.events, bins ? (*bins)(out_direction) : -1, out_direction};
      break;
    }
    if (p.events == o.max_order) {
      end = {WalkEnd::unfinished, p.events, -1};
      break;
    }
    p.h = *h;
    const double un = rng.uniform(), vn = rng.uniform();
    const std::optional<Vec3<double>> m = surface.normal(p.w, {un, vn});
    if (!m) break;  // no microfacet faces the ray: cannot happen for a ray that met the surface; kept as lost
    const double uf = rng.uniform(), vf = rng.uniform();
    surface.scatter(p, *m, {uf, vf});
  }
  out.ends.push_back(end);
  out.weights.insert(out.weights.end(), p.weight.begin(), p.weight.begin() + surface.material().channels());
}

void add_ends(ScatterHistogram& h, const BlockEnds& block, std::uint64_t paths, int channels) {
  h.add_launched(paths);
  for (std::size_t i = 0; i < block.ends.size(); ++i) {
    const WalkEnd& e = block.ends[i];
    const std::span<const double> w(block.weights.data() + i * std::size_t(channels), std::size_t(channels));
    switch (e.kind) {
      case WalkEnd::escaped:
        if (e.bin >= 0) h.add_escaped(e.order, std::size_t(e.bin), w); else h.add_escaped_unbinned(e.order, w);
        break;
      case WalkEnd::unfinished: h.add_unfinished(w); break;
      case WalkEnd::lost: h.add_lost(w); break;
    }
  }
}

// Blocks computed before their reduction: the default, fewer for many channels (memory, not the result).
std::uint64_t walk_blocks_in_flight(int channels) { return channels > 4 ? std::uint64_t(std::max(16, 1024 / channels)) : 0; }

// The histogram of a walk's blocks: walk_block(bins, block, paths) gives a block's ends, added in block order.
template <class WalkBlock>
ScatterHistogram walk_histogram(const ScatterOptions& o, const std::string& measurement, const WalkBlock& walk_block) {
  ScatterHistogram result = empty_scatter_histogram(o, std::string(kSmithWalkProducer), measurement);
  const DirectionBinning binning = DirectionBinning::hemispheres(o.rows);
  const FastDirectionBinner bins(binning);  // keeps a pointer to binning
  const BlockPlan plan{o.paths, kPathsPerBlock};
  const int channels = o.material.channels();
  const BlockRunStatus status = for_each_block(
      result.provenance.blocks, o.run, {"smith walk", plan, walk_blocks_in_flight(channels)},
      [&](std::uint64_t block) { return walk_block(bins, block, plan.units_in(block)); },
      [&](BlockEnds&& ends, std::uint64_t block) { add_ends(result, ends, plan.units_in(block), channels); });
  result.provenance.blocks = status.done;
  result.partial = status.cancelled;
  return result;
}

template <class Ndf>
ScatterHistogram run_walk(const Ndf& ndf, const SmithMicrosurface& s, const ScatterOptions& o, WalkFault fault) {
  const Microsurface<Ndf> surface(ndf, o.material, s.heights, fault);
  const std::size_t channels = std::size_t(o.material.channels());
  return walk_histogram(o, walk_measurement(s, o), [&](const FastDirectionBinner& bins, std::uint64_t block,
                                                       std::uint64_t n) {
    CounterRng rng(o.seed, block);
    BlockEnds ends;
    ends.ends.reserve(std::size_t(n));
    ends.weights.reserve(std::size_t(n) * channels);
    for (std::uint64_t i = 0; i < n; ++i) walk_path(surface, o, &bins, rng, ends);
    return ends;
  });
}

// ---- the walk in SIMD lanes (smith_walk_lanes.h) ------------------------------------------------------------

walk_lanes::LaneWalk lane_walk(const SmithMicrosurface& s, const ScatterOptions& o) {
  walk_lanes::LaneWalk w;
  w.alpha_x = s.alpha_x;
  w.alpha_y = s.alpha_y;
  w.wi[0] = o.wi.x();
  w.wi[1] = o.wi.y();
  w.wi[2] = o.wi.z();
  w.max_order = o.max_order;
  w.channels = o.material.channels();
  w.conductor = o.material.kind() == MaterialKind::conductor;
  w.dielectric = o.material.kind() == MaterialKind::dielectric;
  if (w.dielectric) w.eta = o.material.eta();
  for (int c = 0; w.conductor && c < w.channels; ++c) {
    w.n[std::size_t(c)] = o.material.ior(c).real();
    w.k[std::size_t(c)] = o.material.ior(c).imag();
  }
  w.seed = o.seed;
  return w;
}

// The block's paths walked in lanes, their ends binned in path order (the same reduction as run_walk's).
BlockEnds walk_block_lanes(const walk_lanes::LaneWalk& walk, const FastDirectionBinner& bins, std::uint64_t block,
                           std::uint64_t n) {
  thread_local std::vector<walk_lanes::LaneEnd> lane_ends;  // reused: a block's scratch, not its result
  thread_local std::vector<int> lane_bins;
  lane_ends.resize(std::size_t(n));
  lane_bins.resize(std::size_t(n));
  BlockEnds ends;
  ends.weights.resize(std::size_t(n) * std::size_t(walk.channels));
  walk_lanes::walk_block(walk, block, n, lane_ends.data(), ends.weights.data());
  walk_lanes::bin_escaped(bins, lane_ends.data(), int(n), lane_bins.data());
  ends.ends.reserve(std::size_t(n));
  for (std::size_t i = 0; i < lane_ends.size(); ++i) {
    const walk_lanes::LaneEnd& e = lane_ends[i];
    const Vec3<double> direction(e.x, e.y, e.z);
    if (e.kind == 0) ends.ends.push_back({WalkEnd::escaped, e.order, lane_bins[i], direction});
    else ends.ends.push_back({e.kind == 1 ? WalkEnd::unfinished : WalkEnd::lost, e.order, -1});
  }
  return ends;
}

ScatterHistogram run_walk_lanes(const SmithMicrosurface& s, const ScatterOptions& o) {
  const walk_lanes::LaneWalk walk = lane_walk(s, o);
  return walk_histogram(o, walk_measurement(s, o) + " kernel=lanes target=" + smith_walk_lanes_target(),
                        [&](const FastDirectionBinner& bins, std::uint64_t block, std::uint64_t n) {
                          return walk_block_lanes(walk, bins, block, n);
                        });
}

// ---- the walk as a sampler -------------------------------------------------------------------------------

template <class Ndf>
WalkSamples run_samples(const Ndf& ndf, const SmithMicrosurface& s, const ScatterOptions& o, WalkFault fault) {
  const Microsurface<Ndf> surface(ndf, o.material, s.heights, fault);
  const BlockPlan plan{o.paths, kPathsPerBlock};
  WalkSamples out;
  out.channels = o.material.channels();
  for (std::uint64_t block = 0; block < plan.blocks(); ++block) {
    if (o.run.cancelled()) throw Cancelled("the walk's samples");
    CounterRng rng(o.seed, block);
    BlockEnds ends;
    for (std::uint64_t i = 0; i < plan.units_in(block); ++i) walk_path(surface, o, nullptr, rng, ends);
    for (std::size_t i = 0; i < ends.ends.size(); ++i) {
      if (ends.ends[i].kind != WalkEnd::escaped) {
        ++out.dropped;
        continue;
      }
      const Vec3<double>& d = ends.ends[i].direction;
      out.rows.insert(out.rows.end(), {d.x(), d.y(), d.z()});
      const auto w = ends.weights.begin() + std::ptrdiff_t(i) * out.channels;
      out.rows.insert(out.rows.end(), w, w + out.channels);
    }
  }
  return out;
}

// ---- the BSDF value by next-event estimation --------------------------------------------------------------

// Per-block sums over paths of each path's estimate and its square: [channel][order bin], then the totals.
struct EvalSums {
  std::vector<double> sum, sum2;  // channels * (kScatterOrderBins + 1)
};

constexpr std::size_t kEvalSlots = kScatterOrderBins + 1;  // the order bins, then the total

// One walk from wi with next-event estimation toward wo (global, unit): adds to `path` (channels * kEvalSlots)
// the walk's estimate of f(wi, wo) |wo.z| per order bin and in total.
template <class Ndf>
void eval_path(const Microsurface<Ndf>& surface, const ScatterOptions& o, const Vec3<double>& wo, CounterRng& rng,
               std::span<double> path) {
  const int channels = surface.material().channels();
  Path p = start_path(o.wi, channels, surface.start_height());
  Weights phase;
  const double lambda_o = surface.Lambda(wo);  // the same for wo and -wo, on either side
  for (;;) {
    const std::optional<double> h = surface.next_height(p.w, p.h, rng.uniform());
    if (!h || p.events == o.max_order) return;
    p.h = *h;
    const double un = rng.uniform(), vn = rng.uniform();
    const std::optional<Vec3<double>> m = surface.normal(p.w, {un, vn});
    if (!m) return;
    // Next event: scatter toward wo (this side's frame) and leave from here (or from the other side).
    const Vec3<double> wo_side = global_direction(p, wo);
    const bool refracts = surface.phase(p, wo_side, *m, std::span<double>(phase.data(), std::size_t(channels)));
    const double leave = refracts ? surface.escape_probability(Vec3<double>(-wo_side), surface.other_side_height(p.h), lambda_o)
                                  : surface.escape_probability(wo_side, p.h, lambda_o);
    const std::size_t order_bin = std::size_t(scatter_order_bin(p.events + 1));
    for (int c = 0; c < channels; ++c) {
      const double contribution = p.weight[std::size_t(c)] * phase[std::size_t(c)] * leave;
      path[std::size_t(c) * kEvalSlots + order_bin] += contribution;
      path[std::size_t(c) * kEvalSlots + kScatterOrderBins] += contribution;
    }
    const double uf = rng.uniform(), vf = rng.uniform();
    surface.scatter(p, *m, {uf, vf});
  }
}

template <class Ndf>
SmithWalkEval run_eval(const Ndf& ndf, const SmithMicrosurface& s, const ScatterOptions& o, const Vec3<double>& wo,
                       WalkFault fault) {
  const Microsurface<Ndf> surface(ndf, o.material, s.heights, fault);
  const BlockPlan plan{o.paths, kPathsPerBlock};
  const std::size_t slots = std::size_t(o.material.channels()) * kEvalSlots;
  EvalSums total{std::vector<double>(slots, 0.0), std::vector<double>(slots, 0.0)};
  const BlockRunStatus status = for_each_block(
      selected_blocks(plan, o.blocks), o.run, {"smith walk eval", plan},
      [&](std::uint64_t block) {
        CounterRng rng(o.seed, block);
        EvalSums sums{std::vector<double>(slots, 0.0), std::vector<double>(slots, 0.0)};
        std::vector<double> path(slots);
        for (std::uint64_t i = 0; i < plan.units_in(block); ++i) {
          std::fill(path.begin(), path.end(), 0.0);
          eval_path(surface, o, wo, rng, path);
          for (std::size_t k = 0; k < slots; ++k) {
            sums.sum[k] += path[k];
            sums.sum2[k] += path[k] * path[k];
          }
        }
        return sums;
      },
      [&](EvalSums&& sums, std::uint64_t) {
        for (std::size_t k = 0; k < slots; ++k) {
          total.sum[k] += sums.sum[k];
          total.sum2[k] += sums.sum2[k];
        }
      });
  SmithWalkEval r;
  r.blocks = status.done;
  r.partial = status.cancelled;
  r.paths = plan.units_in(status.done);
  const double cos_o = std::abs(wo.z());
  for (int c = 0; c < o.material.channels(); ++c) {
    auto slot = [&](std::size_t k) {
      const Estimate e = mean_per_path(total.sum[std::size_t(c) * kEvalSlots + k], total.sum2[std::size_t(c) * kEvalSlots + k], r.paths);
      return Estimate{e.value / cos_o, e.standard_error / cos_o};
    };
    std::array<Estimate, kScatterOrderBins> orders;
    for (int k = 0; k < kScatterOrderBins; ++k) orders[std::size_t(k)] = slot(std::size_t(k));
    r.order.push_back(orders);
    r.total.push_back(slot(kScatterOrderBins));
  }
  return r;
}

}  // namespace

namespace detail {

ScatterHistogram smith_walk_scatter(const SmithMicrosurface& surface, const ScatterOptions& options, WalkFault fault) {
  check_walk(surface, options);
  return with_ndf(surface, [&](const auto& ndf) { return run_walk(ndf, surface, options, fault); });
}

WalkSamples smith_walk_samples(const SmithMicrosurface& surface, const ScatterOptions& options, WalkFault fault) {
  check_walk(surface, options);
  return with_ndf(surface, [&](const auto& ndf) { return run_samples(ndf, surface, options, fault); });
}

SmithWalkEval smith_walk_eval(const SmithMicrosurface& surface, const ScatterOptions& options, const Vec3<double>& wo,
                              WalkFault fault) {
  check_walk(surface, options);
  if (!wo.allFinite() || std::abs(wo.norm() - 1.0) > 1e-9 || wo.z() == 0.0) {
    throw std::invalid_argument(fmt::format("smith walk eval: wo ({}, {}, {}) must be a unit direction off the horizon",
                                            wo.x(), wo.y(), wo.z()));
  }
  return with_ndf(surface, [&](const auto& ndf) { return run_eval(ndf, surface, options, wo, fault); });
}

}  // namespace detail

ScatterHistogram smith_walk_scatter(const SmithMicrosurface& surface, const ScatterOptions& options) {
  return detail::smith_walk_scatter(surface, options, WalkFault::none);
}

bool smith_walk_lanes_support(NdfKind ndf, HeightDistribution heights, const Material& material) {
  return ndf == NdfKind::ggx && heights == HeightDistribution::uniform && material.kind() != MaterialKind::lambertian;
}

bool smith_walk_lanes_support(const SmithMicrosurface& surface, const ScatterOptions& options) {
  return smith_walk_lanes_support(surface.ndf, surface.heights, options.material);
}

ScatterHistogram smith_walk_scatter(const SmithMicrosurface& surface, const ScatterOptions& options, WalkKernel kernel) {
  if (kernel == WalkKernel::scalar) return smith_walk_scatter(surface, options);
  check_walk(surface, options);
  if (!smith_walk_lanes_support(surface, options)) {
    throw std::invalid_argument(fmt::format("smith walk lanes: {} with {} is not supported (GGX, uniform heights, "
                                            "a mirror, a conductor or a dielectric)",
                                            describe(surface), options.material.describe()));
  }
  return run_walk_lanes(surface, options);
}

std::string smith_walk_lanes_target() { return walk_lanes::walk_lanes_target(); }

SmithWalkEval smith_walk_eval(const SmithMicrosurface& surface, const ScatterOptions& options, const Vec3<double>& wo) {
  return detail::smith_walk_eval(surface, options, wo, WalkFault::none);
}

WalkSamples smith_walk_samples(const SmithMicrosurface& surface, const ScatterOptions& options) {
  return detail::smith_walk_samples(surface, options, WalkFault::none);
}

}  // namespace microsim
