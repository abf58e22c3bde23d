// microsim validate --from DUMP --model smith-walk: a renderer's multiple-scattering BSDF against the Smith
// random walk (measure/walk_validation.h).
#pragma once

#include <optional>
#include <string>

namespace microsim::app {

struct WalkValidationArgs {
  std::string from, columns, frame, material, alpha, json;
  double theta = 0, phi = 0, significance = 0.01;
  std::optional<long long> paths, dropped;
  unsigned long long seed = 1;
};

// Exit 0 passed, 1 rejected; UsageError for bad input.
int run_walk_validation(const WalkValidationArgs& args);

}  // namespace microsim::app
