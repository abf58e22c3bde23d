// Synthetic scattering measurements for the tests of scatter files, comparisons and merges: a run whose
// order 1 has exactly the analytic single scattering as its expectation, built without a tracer.
//
// Path k of block b (CounterRng(seed, b)) draws a visible normal m of wi (Heitz 2018's sampler) and leaves
// along wo = reflect(wi, m). With pdf(wo) = G1(wi) D(m) / (4 cos i) and f cos o = F D G2 / (4 cos i), the
// weight f cos o / pdf = F(wi . m) G2(wi, wo) / G1(wi) (0 when wo is below the horizon) makes the expected
// order-1 weight per path of every bin the analytic E_bin (scatter/analytic_scatter.h). What the path does
// not carry out at order 1 leaves at order 2, uniformly over the upper hemisphere, so that orders 1 and 2 hold
// weights that vary from path to path (a weighted histogram, as a real measurement).
#pragma once

#include "core/block_runner.h"
#include "core/random.h"
#include "microfacet/bsdf.h"
#include "microfacet/samplers.h"
#include "scatter/scatter_setup.h"

#include <string>
#include <vector>

namespace microsim::test {

inline void synthetic_path(ScatterHistogram& h, const DirectionBinning& binning, const GGX<double>& ggx,
                           const ScatterOptions& o, CounterRng& rng) {
  const int channels = o.material.channels();
  std::vector<double> first(std::size_t(channels), 0.0), second(std::size_t(channels), 0.0);
  const auto s = sample_heitz2018(ggx, o.wi, Vec2<double>(rng.uniform(), rng.uniform()));
  const Vec3<double> wo = s ? reflect(o.wi, s->direction) : Vec3<double>(0, 0, -1);
  const double shadowing = wo.z() > 0 ? ggx.G2(o.wi, wo) / ggx.G1(o.wi) : 0.0;
  for (int c = 0; c < channels; ++c) {
    const double f = o.material.kind() == MaterialKind::conductor && s
                         ? fresnel_conductor(o.wi.dot(s->direction), o.material.ior(c))
                         : 1.0;
    first[std::size_t(c)] = f * shadowing;
    second[std::size_t(c)] = 1.0 - first[std::size_t(c)];
  }
  if (shadowing > 0) h.add_escaped(1, std::size_t(*binning.bin_of(wo)), first);
  const double z = rng.uniform(), phi = 2 * kPi<double> * rng.uniform(), r = std::sqrt(std::max(0.0, 1 - z * z));
  const auto bin = binning.bin_of(Vec3<double>(r * std::cos(phi), r * std::sin(phi), std::max(z, 1e-9)));
  h.add_escaped(2, std::size_t(*bin), second);
}

// The synthetic run of `o` (paths, seed, rows, wi, material, blocks: a shard) at GGX roughness `alpha`.
inline ScatterHistogram synthetic_scatter(const ScatterOptions& o, double alpha, const std::string& producer = "test synthetic") {
  ScatterHistogram h = empty_scatter_histogram(o, producer, "synthetic alpha " + std::to_string(alpha));
  const DirectionBinning binning = DirectionBinning::hemispheres(o.rows);
  const GGX<double> ggx(alpha);
  const BlockPlan plan{o.paths, kPathsPerBlock};
  const BlockRange range = h.provenance.blocks;
  for (std::uint64_t b = range.begin; b < range.end; ++b) {
    CounterRng rng(o.seed, b);
    for (std::uint64_t k = 0; k < plan.units_in(b); ++k) synthetic_path(h, binning, ggx, o, rng);
    h.add_launched(plan.units_in(b));
  }
  return h;
}

}  // namespace microsim::test
