// tests: a renderer's dump of samples, written as a test needs it: `n` directions drawn by a zoo sampler (the
// talk listing `heitz2018-talk` for a dump that must be rejected, `heitz2018` for one that passes) at GGX
// `alpha` and the view (theta_deg, phi 0), from `seed`, saved as an NPY (N, 3) float64 file as a renderer would.
// Which experiment specs validate (`dump = "..."`, docs/reference/experiments.md); the caller removes the file.
// write_bsdf_dump: a BSDF sampler of the zoo (microfacet/bsdf_samplers.h) dumped as a renderer's sample()
// (wo, pdf, weight per row, text), its lost samples left out as renderers drop them; returns how many.
// write_conductor_bsdf_files: the files of `check-bsdf-files` (a dump and its eval file at the same rows) of the
// zoo's GGX conductor, as a renderer writes them.
#pragma once

#include "core/random.h"
#include "microfacet/bsdf.h"
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

// The zoo's GGX conductor (alpha 0.3, eta 0.2 + 3.9i) sampled 20000 times at 30 deg from seed 3: its dump `dump`
// (x y z pdf weight, its weights times `weight_scale`: 1 a correct BSDF, else a planted weight bug) and its eval file
// `eval` at the same rows (wi wo f|cos wo| pdf), text. Returns the samples lost below the horizon (not in the dump).
inline std::uint64_t write_conductor_bsdf_files(const std::filesystem::path& dump, const std::filesystem::path& eval,
                                                double weight_scale = 1.0) {
  const BsdfSamplerInfo* s = find_bsdf_sampler("conductor_vndf");
  const GGX<double> ggx(0.3, 0.3);
  const Vec3<double> wi = direction_from_degrees(30.0, 0.0);
  std::ofstream d(dump), e(eval);
  std::uint64_t lost = 0;
  for (std::uint64_t i = 0; i < 20000; ++i) {
    CounterRng rng(3, i);
    const double u0 = rng.uniform(), u1 = rng.uniform(), u2 = rng.uniform();
    const BsdfSampleResult r = s->sample(ggx, kZooConductorIor, wi, {u0, u1, u2});
    if (!r && ++lost) continue;
    const double f = conductor_brdf(ggx, kZooConductorIor, wi, r->wo) * r->wo.z();
    d << fmt::format("{:.17g} {:.17g} {:.17g} {:.17g} {:.17g}\n", r->wo.x(), r->wo.y(), r->wo.z(), r->pdf,
                     r->weight * weight_scale);
    e << fmt::format("{:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g}\n", wi.x(), wi.y(), wi.z(), r->wo.x(),
                     r->wo.y(), r->wo.z(), f, conductor_vndf_pdf(ggx, kZooConductorIor, wi, r->wo));
  }
  return lost;
}

}  // namespace microsim::test
