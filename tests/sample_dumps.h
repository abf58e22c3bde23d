// tests: a renderer's dump of samples, written as a test needs it: `n` directions drawn by a zoo sampler (the
// talk listing `heitz2018-talk` for a dump that must be rejected, `heitz2018` for one that passes) at GGX
// `alpha` and the view (theta_deg, phi 0), from `seed`, saved as an NPY (N, 3) float64 file as a renderer would.
// Which experiment specs validate (`dump = "..."`, docs/reference/experiments.md); the caller removes the file.
#pragma once

#include "microfacet/samplers.h"
#include "validate/sample_io.h"
#include "validate/validate.h"

#include <cstdint>
#include <filesystem>
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

}  // namespace microsim::test
