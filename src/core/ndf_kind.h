// core: which normal distribution a microsurface has (GGX or Beckmann), its name and its parser: the one
// NDF type of every module. It lives in core, not microfacet, because microgeom (which builds surfaces to
// have either NDF) and microfacet are siblings over core (docs/architecture.md): core is the one module
// both may use.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace microsim {

// GGX: Trowbridge & Reitz 1975, Walter et al. 2007 eq. 33; Beckmann: Beckmann & Spizzichino 1963,
// Walter et al. 2007 eq. 25.
enum class NdfKind { ggx, beckmann };

std::string to_string(NdfKind ndf);  // "ggx", "beckmann"
// The NDF of that name ("ggx", "beckmann", exactly); nullopt for any other text.
std::optional<NdfKind> ndf_kind_from_string(std::string_view name);
// The NDF of that name, or a ParseError naming `what` and quoting the text.
NdfKind parse_ndf_kind(std::string_view what, std::string_view text);

}  // namespace microsim
