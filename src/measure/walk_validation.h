// measure: a renderer's multiple-scattering BSDF validated against the Smith model's own multiple scattering
// (`microsim validate --from DUMP --model smith-walk`): its sampled directions and weights (f |cos wo| / pdf,
// one per channel) against the random walk of Heitz, Hanika, d'Eon, Dachsbacher 2016 (scatter/smith_walk.h)
// traced at `paths` paths, both binned over the hemispheres binning as weights per launched path.
// Three tests, Sidak-corrected to the family-wise level: the weighted chi-square homogeneity of the lobes'
// shapes over both hemispheres (Gagunashvili 2010, stats/chi2.h), and the reflected and the transmitted albedo
// each against the walk's (a z-test with both standard errors): a walk that keeps its height after a
// refraction gets R and T wrong while R + T stays 1, and the shapes too.
#pragma once

#include "core/estimate.h"
#include "core/run_control.h"
#include "scatter/smith_walk.h"
#include "stats/chi2.h"
#include "validate/sample_io.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace microsim {

struct WalkValidationOptions {
  std::uint64_t paths = 4'000'000;  // of the walk
  std::uint64_t seed = 1;
  int rows = 8;                     // per hemisphere
  int max_order = 1000;             // the walk's cap (its unfinished weight is reported)
  std::uint64_t dropped = 0;        // samples the renderer dropped (weight 0)
  double significance = 0.01;
  RunControl run;
};

struct WalkValidationReport {
  std::uint64_t rows = 0;      // of the dump (+ dropped)
  std::uint64_t paths = 0;     // of the walk
  int channel = 0;             // the channel tested (the one of least agreement, each Sidak-counted)
  double tv = 0, tv_noise_floor = 0;
  Estimate albedo_reflected_dump, albedo_reflected_walk, albedo_transmitted_dump, albedo_transmitted_walk;
  Estimate walk_unfinished;
  double p_reflected = 1, p_transmitted = 1;
  std::optional<ChiSquareResult> chi2;
  std::string insufficient;    // why the shape test could not run (too little data: never a pass)
  DominantValue dominant;      // the row holding most of the channel's weights' spread (a firefly above kMaxDominantShare)
  int tests = 0;
  double per_test_significance = 0, p_value = 1;  // Sidak-adjusted smallest p
  bool passed = false;
  std::vector<std::string> failures;
};

// The dump's rows must carry one weight per channel of `material`. Throws std::invalid_argument (bad options,
// a dump without weights), SampleFileError (a bad file), InsufficientData (too little data for the shape test),
// Cancelled.
WalkValidationReport validate_dump_against_walk(DirectionSampleReader& dump, const SmithMicrosurface& surface,
                                                const Material& material, const Vec3<double>& wi,
                                                const WalkValidationOptions& options);

nlohmann::json to_json(const WalkValidationReport& report);

}  // namespace microsim
