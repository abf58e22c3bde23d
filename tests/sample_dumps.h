// tests: a renderer's dump of samples, written as a test needs it: `n` directions drawn by a zoo sampler (the
// talk listing `heitz2018-talk` for a dump that must be rejected, `heitz2018` for one that passes) at GGX
// `alpha` and the view (theta_deg, phi 0), from `seed`, saved as an NPY (N, 3) float64 file as a renderer would.
// Which experiment specs validate (`dump = "..."`, docs/reference/experiments.md); the caller removes the file.
// write_bsdf_dump: a BSDF sampler of the zoo (microfacet/bsdf_samplers.h) dumped as a renderer's sample()
// (wo, pdf, weight per row, text), its lost samples left out as renderers drop them; returns how many.
#pragma once

#include "core/random.h"
#include "microfacet/bsdf_samplers.h"

#include "microfacet/samplers.h"
#include "validate/sample_io.h"
#include "validate/validate.h"

#include <fmt/core.h>

#include <complex>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

namespace microsim::test {

inline void write_sampler_dump(const std::filesystem::path& path, const std::string& sampler, double alpha,
                               double theta_deg, std::uint64_t n, std::uint64_t seed = 3) {
  ValidationOptions o;
  o.samples = n;
  o.seed = seed;
  const SampleSet s = draw_samples(*find_sampler(sampler), GGX<double>(alpha), direction_from_degrees(theta_deg, 0.0), o);
  write_npy(path, s.directions, false);
}

inline long long write_bsdf_dump(const std::filesystem::path& path, const char* sampler, const GGX<double>& ggx,
                                 std::complex<double> ior, const Vec3<double>& wi, int n, std::uint64_t seed = 7) {
  const BsdfSamplerInfo* s = find_bsdf_sampler(sampler);
  std::ofstream out(path);
  long long lost = 0;
  for (int i = 0; i < n; ++i) {
    CounterRng rng(seed, std::uint64_t(i));
    const Vec3<double> u(rng.uniform(), rng.uniform(), rng.uniform());
    const auto r = s->sample(ggx, ior, wi, u);
    if (!r) {  // a lost sample (a reflection below the horizon, a refraction back up): renderers emit nothing
      ++lost;
      continue;
    }
    out << fmt::format("{:.17g} {:.17g} {:.17g} {:.17g} {:.17g}\n", r->wo.x(), r->wo.y(), r->wo.z(), r->pdf, r->weight);
  }
  return lost;
}

}  // namespace microsim::test
