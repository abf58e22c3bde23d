#pragma once
// Small JSON spellings shared by the reports: a number that may be NaN or infinite, and an estimate.

#include "core/estimate.h"

#include <nlohmann/json.hpp>

#include <cmath>

namespace microsim {

// JSON has no NaN or infinity: a non-finite value is written as null.
inline nlohmann::json finite_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

// {"value": v, "standard_error": se}.
inline nlohmann::json estimate_json(const Estimate& e) {
  return {{"value", e.value}, {"standard_error", e.standard_error}};
}

}  // namespace microsim
