#include "core/ndf_kind.h"

#include "core/parse.h"

#include <fmt/core.h>

namespace microsim {

std::string to_string(NdfKind ndf) { return ndf == NdfKind::ggx ? "ggx" : "beckmann"; }

std::optional<NdfKind> ndf_kind_from_string(std::string_view name) {
  for (const NdfKind n : {NdfKind::ggx, NdfKind::beckmann})
    if (to_string(n) == name) return n;
  return std::nullopt;
}

NdfKind parse_ndf_kind(std::string_view what, std::string_view text) {
  if (const std::optional<NdfKind> n = ndf_kind_from_string(text)) return *n;
  throw ParseError(fmt::format("{} {}: unknown distribution (expected ggx or beckmann)", what, quote_excerpt(text)));
}

}  // namespace microsim
