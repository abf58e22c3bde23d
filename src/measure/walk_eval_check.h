// measure: an eval file (validate/eval_check.h's rows: wi, wo, f(wi, wo) |cos wo| per channel, [pdf]) checked
// against the Smith multiple-scattering BSDF (`check-eval --model smith-walk`): per pair, the next-event estimate
// of the walk (scatter/smith_walk.h smith_walk_eval, Heitz et al. 2016 sec. 6) from `paths` walks with its
// standard error, compared to the file by a chi-square over pairs and channels,
//   X = sum (given - walk)^2 / (se_walk^2 + se_file^2),
// se_file the file's storage precision (eps_v |given|: the file's values are taken as exact otherwise), with
// as many degrees of freedom as terms, at the stated level; the pairs with the largest |z| are named. The walk's
// f is in importance transport; a file in radiance transport gets (n_wi / n_wo)^2 on a refraction. Pairs within
// 1e-3 of the horizon are skipped (counted). Pair i walks from CounterRng(seed + i, ...): the result depends
// only on the file, the seed and `paths`.
#pragma once

#include "core/estimate.h"
#include "core/run_control.h"
#include "microfacet/bsdf_convention.h"
#include "microfacet/material.h"
#include "scatter/smith_walk.h"
#include "validate/eval_check.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace microsim {

struct WalkEvalCheckOptions {
  BsdfConvention convention;
  SampleFrame frame = SampleFrame::z_up;
  std::uint64_t paths = 32768;  // walks per pair (fewer: the walk's standard error is underestimated where rare long paths dominate)
  std::uint64_t seed = 1;
  int max_order = 100;
  double level = 0.01;
  std::size_t worst = 10;
  RunControl run;
};

struct WalkEvalPair {
  std::uint64_t row = 0;
  int channel = 0;
  Vec3<double> wi, wo;
  double given = 0;
  Estimate walk;
  double z = 0;
};

struct WalkEvalCheckReport {
  std::string file, storage;
  std::uint64_t rows = 0, skipped = 0;
  double statistic = 0, p_value = 1;
  std::uint64_t dof = 0;
  std::vector<WalkEvalPair> worst;  // largest |z| first
  bool passed = false;
};

// Throws SampleFileError for a file that cannot be read as `columns` say, std::invalid_argument for a material
// the walk does not take, Cancelled.
WalkEvalCheckReport check_eval_file_against_walk(const std::filesystem::path& file, const EvalColumns& columns,
                                                 const Material& material, const SmithMicrosurface& surface,
                                                 const WalkEvalCheckOptions& options);

nlohmann::json to_json(const WalkEvalCheckReport& report);

}  // namespace microsim
