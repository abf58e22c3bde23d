// measure: the validations of `microsim validate` (one sampler at one configuration, against its claimed
// pdf or a traced histogram; or the whole zoo over the standard grid, --all) as a run that can be split
// over machines. A shard (--shard K/N) draws block range K of N of every validation's samples (blocks of
// kSampleBlock, validate.h) and records their tallies exactly (validation_part.h) with the run's
// provenance; `microsim merge` joins the parts, computes the expected counts (the cubature of the claimed
// pdfs, which the shards skip) and reports every validation exactly as the single run does.
//
// A part: {"provenance": {"producer": "validate", "parameters": {...}, "seed", "blocks", "total_blocks"},
//          "tallies": [one per validation, in the run's order], "seconds": [per validation]}.
#pragma once

#include "stats/part_json.h"
#include "validate/bsdf_validation.h"
#include "validate/validation_part.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace microsim {

// One validation of a run: a sampler of the registry at one configuration, with its own seed.
struct ValidationCase {
  const SamplerInfo* sampler = nullptr;
  double alpha_x = 0, alpha_y = 0, theta_deg = 0, phi_deg = 0;
  std::uint64_t seed = 1;
  GGX<double> ggx() const { return GGX<double>(alpha_x, alpha_y); }
  Vec3<double> wi() const { return direction_from_degrees(theta_deg, phi_deg); }
};

// The --all grid: views at these zenith angles, for each roughness (isotropic ones
// seen from phi = 0, anisotropic pairs from phi = 30 degrees so that both axes matter).
inline constexpr double kZooThetas[] = {0, 30, 60, 80, 89};
struct ZooRoughness {
  double alpha_x, alpha_y, phi_deg;
};
inline constexpr ZooRoughness kZooRoughness[] = {{1e-3, 1e-3, 0}, {0.05, 0.05, 0}, {0.3, 0.3, 0},    {1, 1, 0},
                                                 {2, 2, 0},       {0.05, 0.5, 30}, {0.5, 0.05, 30}, {1e-3, 0.3, 30}};
inline constexpr int kZooConfigurations = int(std::size(kZooRoughness) * std::size(kZooThetas));
// Every sampler of the registry at every configuration of the grid, in the batch's order (roughness, then
// zenith angle, then the registry's order), validation i with seed `seed` + i (independent streams).
std::vector<ValidationCase> zoo_cases(std::uint64_t seed);

// The BSDF samplers of the zoo (bsdf_samplers.h) in --all: each at these roughnesses and zenith angles
// (phi = 0), the dielectric ones from outside and from inside, with the zoo's materials
// (zoo_bsdf_material). Validation i has seed `seed` + i + 1000000 (streams apart from the direction zoo's).
inline constexpr double kBsdfZooAlphas[] = {0.05, 0.3, 1};
inline constexpr double kBsdfZooThetas[] = {0, 60, 89};
struct BsdfValidationCase {
  const BsdfSamplerInfo* sampler = nullptr;
  double alpha = 0, theta_deg = 0;
  bool inside = false;  // a dielectric seen from inside (mirrored, eta 1 / 1.5)
  std::uint64_t seed = 1;
  GGX<double> ggx() const { return GGX<double>(alpha, alpha); }
  Vec3<double> wi() const { return direction_from_degrees(theta_deg, 0.0); }
  Material material() const { return zoo_bsdf_material(*sampler, inside); }
  // A negative control whose bug has an effect `samples` samples can see here (BsdfSamplerInfo::
  // bug_has_effect): it must be rejected. False for correct samplers (they must pass) and for bugs without effect here (no expectation).
  bool expects_rejection(std::uint64_t samples) const;
};
std::vector<BsdfValidationCase> bsdf_zoo_cases(std::uint64_t seed);

// A validation run: its validations and what they share.
struct ValidationRun {
  bool batch = false;                // --all: the zoo over the grid
  std::vector<ValidationCase> cases;
  ValidationOptions options;         // samples, rows, precision, significance of each validation; its seed and
                                     // blocks are set per case and per shard
  std::uint64_t seed = 1;            // --seed
  double family_significance = 0.01; // --significance (a batch: each validation runs at its Sidak share)
  std::string against;               // a traced histogram's path (one case, compare.h), or "" for the claimed pdf
};

struct ValidationPart {
  Provenance provenance;                // "validate", the run's parameters, seed, blocks (of every case)
  nlohmann::json parameters;
  std::vector<battery::Tally> tallies;  // one per case, over provenance.blocks
  std::vector<double> seconds;          // per case: sampling time (summed over merged parts)
};

// The blocks of kSampleBlock samples of each validation of the run.
std::uint64_t validation_blocks(const ValidationRun& run);

// Draws and tallies blocks `blocks` of every validation of the run (against `traced` when run.against is
// given; it must be that histogram). run.options.run reports progress (stage "validations": cases done) and
// cancels (Cancelled). Throws std::invalid_argument for blocks outside the run or a histogram of another
// configuration.
ValidationPart sample_validation_part(const ValidationRun& run, BlockRange blocks, const TracedHistogram* traced);

nlohmann::json validation_part_json(const ValidationPart& part);
bool is_validation_part(const nlohmann::json& report);
// Throws HistogramMergeError naming what is missing or malformed (a sampler the registry does not have).
ValidationPart read_validation_part(const nlohmann::json& report);
// The parts of one run joined (any order): tallies merged in block order. Throws HistogramMergeError naming
// parts of different runs (the first parameter that differs, the seed) and missing or repeated blocks.
ValidationPart merge_validation_parts(const std::vector<ValidationPart>& parts);
// The run a part's parameters describe (no blocks). Throws HistogramMergeError.
ValidationRun validation_run_of(const ValidationPart& part);

// FNV-1a (64 bits) of a traced histogram's binnings, counts, rays and hits: its identity in the parameters.
std::string traced_histogram_digest(const TracedHistogram& traced);

}  // namespace microsim
