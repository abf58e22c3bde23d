// scatter: the Smith model's own multiple scattering, as the random walk in height of Heitz, Hanika,
// d'Eon, Dachsbacher 2016, "Multiple-Scattering Microfacet BSDFs with the Smith Model", SIGGRAPH.
//
// The Smith microsurface is a random heightfield whose heights h have the distribution P1 (CDF C1) and
// whose normals have the distribution D (GGX or Beckmann), with height and normal independent (Smith's
// assumption). A ray at height h travelling in w (in the frame of the side it is on, z up):
//   - upward (w.z > 0) leaves the surface with probability G1(w, h) = C1(h)^Lambda(w) (Heitz et al. 2016,
//     sec. 3, masking at a given height; Smith 1967);
//   - otherwise it next meets the surface at the height h' with C1(h') = C1(h) U^(-1/Lambda(w)), U uniform
//     in (0, 1] (the inverse of the distribution of the free path's end in height, sec. 3); downward rays
//     (w.z < 0) always meet it, with the same formula and Lambda(w) = -1 - Lambda(-w) (sec. 3), i.e.
//     C1(h') = C1(h) U^(1 / (1 + Lambda(-w)));
//   - at each meeting the microfacet normal is drawn from the visible normals of -w (the upper normals
//     facing the ray: microfacet/upper_vndf.h; exact samplers: Heitz 2018 for GGX views above the horizon,
//     the Dupuy-Benyoub cap below it, the exact slope inversion for Beckmann), and the facet material acts
//     (microfacet/material.h, scatter_on_facet: mirror, conductor per channel, dielectric, Lambertian;
//     sec. 5);
//   - a dielectric's refraction takes the ray to the other side: the walk continues on the microsurface seen
//     from there, which in that side's frame (the point reflection v -> -v of this one) has heights -h and
//     the same normal distribution; the direction becomes -wo, and eta is inverted (scatter_on_facet's
//     `inside`) (sec. 5.2). Every piece of state follows the side change.
// The height distribution drops out of every result (uniform on [-1, 1] is the default, followed through
// ln C1(h), where each meeting costs one logarithm; the Gaussian follows the heights themselves, a check of
// that).
//
// Output: smith_walk_scatter fills the per-order ScatterHistogram of scatter_setup.h (outgoing directions
// in the global frame; the histogram's "reflected" bins are the upper hemisphere, so for light from inside
// they hold what the dielectric transmits), with the unfinished weight at the order cap; smith_walk_eval estimates the BSDF value f(wi, wo) per order by next-event estimation (sec. 6).
// Both run on the block runner: block b draws from CounterRng(seed, b), so a result depends only on
// (seed, blocks), shards merge into the whole run bit for bit (ScatterHistogram::merge), and a cancelled run
// returns the completed prefix of its blocks, marked partial. Neither prints.
#pragma once

#include "core/math.h"
#include "core/ndf_kind.h"
#include "scatter/scatter_setup.h"
#include "stats/scatter_histogram.h"

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace microsim {

enum class HeightDistribution { uniform, gaussian };

// The Smith microsurface of a walk.
struct SmithMicrosurface {
  NdfKind ndf = NdfKind::ggx;
  double alpha_x = 0.5, alpha_y = 0.5;  // each in [kMinAlpha, kMaxSupportedAlpha] (microfacet/roughness.h)
  HeightDistribution heights = HeightDistribution::uniform;
};

std::string to_string(HeightDistribution heights);  // "uniform", "gaussian"
// Parse "uniform" / "gaussian"; ParseError naming `what` and quoting the text (the NDF: parse_ndf_kind).
HeightDistribution parse_height_distribution(std::string_view what, std::string_view text);
// "ggx alpha=0.5,0.5 heights=uniform": the canonical description (part of a run's measurement string).
std::string describe(const SmithMicrosurface& surface);
// Throws std::invalid_argument (ParseError) naming the bad alpha (microfacet/roughness.h's supported range).
void check_smith_microsurface(const SmithMicrosurface& surface);

inline constexpr std::string_view kSmithWalkProducer = "scatter smith-walk";

// The random walk of options.paths paths arriving along -options.wi (from inside the dielectric when
// wi.z < 0: only a dielectric allows that), each followed until it leaves or has met the surface
// options.max_order times. Throws std::invalid_argument for bad options (check_scatter_options, light from
// inside on a material that does not transmit, check_smith_microsurface).
ScatterHistogram smith_walk_scatter(const SmithMicrosurface& surface, const ScatterOptions& options);

// Which code walks the paths of smith_walk_scatter. scalar: one path after another (the reference, and the
// default). lanes: paths in SIMD lanes (scatter/smith_walk_lanes.h), each path with its own random stream,
// for the case smith_walk_lanes_support accepts; the same walk, not the same numbers: it agrees with the
// scalar walk statistically (tests/scatter/test_smith_walk_lanes.cpp), and its measurement string names it and
// the SIMD target it ran on (" kernel=lanes target=AVX3"): bits are only promised within one target (and one
// build), so shards of the two kernels, or of two targets, never merge.
enum class WalkKernel { scalar, lanes };
std::string to_string(WalkKernel kernel);  // "scalar", "lanes"
// Parse "scalar" / "lanes"; ParseError naming `what` and quoting the text.
WalkKernel parse_walk_kernel(std::string_view what, std::string_view text);
// Whether the lanes kernel walks a case: GGX, uniform heights, a mirror, a conductor or a dielectric (every
// material but the Lambertian). The one statement of that rule: the commands and an experiment's spec ask it.
bool smith_walk_lanes_support(NdfKind ndf, HeightDistribution heights, const Material& material);
bool smith_walk_lanes_support(const SmithMicrosurface& surface, const ScatterOptions& options);
// As above with the kernel chosen; lanes where smith_walk_lanes_support is false throws std::invalid_argument.
ScatterHistogram smith_walk_scatter(const SmithMicrosurface& surface, const ScatterOptions& options, WalkKernel kernel);
// The SIMD target the lanes kernel runs on this CPU ("AVX3", "AVX2", ...).
std::string smith_walk_lanes_target();

// The BSDF value by next-event estimation (Heitz et al. 2016 sec. 6): along each walk from wi, every meeting
// with the surface adds the path weight times the facet's phase function toward wo times the probability of
// leaving from there in wo (on the other side, at the other side's height, for a refraction). Its mean over
// walks is f(wi, wo) |wo.z|, reported per order and in total as f (the cosine divided out; for a dielectric
// the BTDF of Walter et al. 2007 eq. 21 with its eta_o^2, as microfacet/bsdf.h). Uses options' wi,
// material, paths, seed, max_order, blocks, run (rows is ignored). wo: unit, off the horizon.
struct SmithWalkEval {
  std::uint64_t paths = 0;  // walks launched in the blocks that ran
  BlockRange blocks;
  bool partial = false;
  // [channel][order bin] (orders 1, 2, 3, 4, 5+) and [channel] for every order: f(wi, wo).
  std::vector<std::array<Estimate, kScatterOrderBins>> order;
  std::vector<Estimate> total;

  // order_bin in [0, kScatterOrderBins), or -1 for every order (ScatterHistogram::albedo's convention).
  Estimate value(int channel, int order_bin = -1) const;
};
SmithWalkEval smith_walk_eval(const SmithMicrosurface& surface, const ScatterOptions& options, const Vec3<double>& wo);

// The walk as a renderer's sampler of a multiple-scattering BSDF (what `validate --model smith-walk` tests):
// per path that leaves, its outgoing direction (global) then its weight per channel, a row of 3 + channels
// values in `rows`; the paths at the order cap and the lost ones are `dropped` (renderers drop them). Uses
// options' wi, material, paths, seed, max_order, rows, run (cancellation: Cancelled). One thread.
struct WalkSamples {
  std::vector<double> rows;
  int channels = 1;
  std::uint64_t dropped = 0;
};
WalkSamples smith_walk_samples(const SmithMicrosurface& surface, const ScatterOptions& options);

namespace detail {
// Deliberate defects, for the negative controls of the tests only.
enum class WalkFault {
  none,
  keep_height_on_refraction,  // oracle.md section 6: R and T go wrong while R + T = 1 still holds
};
ScatterHistogram smith_walk_scatter(const SmithMicrosurface& surface, const ScatterOptions& options, WalkFault fault);
SmithWalkEval smith_walk_eval(const SmithMicrosurface& surface, const ScatterOptions& options, const Vec3<double>& wo,
                              WalkFault fault);
WalkSamples smith_walk_samples(const SmithMicrosurface& surface, const ScatterOptions& options, WalkFault fault);
}  // namespace detail

}  // namespace microsim
