// microsim: the options the whole-BSDF commands share (check-eval, check-bsdf, bsdf-queries).
#pragma once

#include "command.h"

#include "core/parse.h"
#include "microfacet/material.h"
#include "validate/validate.h"

#include <fmt/core.h>

#include <string>

namespace microsim::app {

// --bsdf SPEC: a microfacet BSDF (mirror, conductor:ETA,K[;...], dielectric:ETA); UsageError for another.
inline Material microfacet_bsdf_option(const std::string& text) {
  const Material m = parse_material("--bsdf", text);
  if (m.kind() == MaterialKind::lambertian)
    throw UsageError("--bsdf: a microfacet BSDF is compared: mirror, conductor:ETA,K or dielectric:ETA");
  return m;
}

// --arithmetic float32|float64: the renderer's, which the eval tolerances follow; UsageError for another.
inline Precision arithmetic_option(const std::string& text) {
  if (text != "float32" && text != "float64")
    throw UsageError(fmt::format("--arithmetic {}: float32 or float64 (the renderer's)", quote_excerpt(text)));
  return text == "float32" ? Precision::float32 : Precision::float64;
}

}  // namespace microsim::app
