// microfacet: the supported roughness of the Smith-GGX model (docs/reference/conventions.md), one rule every command
// and reader applies: alpha in [kMinAlpha, kMaxSupportedAlpha] per axis (ggx.h) and anisotropy
// max/min <= kMaxSupportedAnisotropy. Parsed with the number rules of core/parse.h.
#pragma once

#include "core/parse.h"
#include "microfacet/ggx.h"

#include <string_view>
#include <utility>

namespace microsim {

// Throws ParseError naming the values and the supported range unless both are in [kMinAlpha,
// kMaxSupportedAlpha] and max/min <= kMaxSupportedAnisotropy.
void check_supported_alpha(std::string_view what, double alpha_x, double alpha_y);
// "AX" or "AX,AY" (AY = AX when omitted), checked by check_supported_alpha.
std::pair<double, double> parse_alpha(std::string_view what, std::string_view text);

}  // namespace microsim
