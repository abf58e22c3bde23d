// microsim: strict parsing of numbers and names stored as text inside input files (EXR string attributes,
// heightmap metadata), and short escaped excerpts of bad input for error messages. Header-only, so that
// both libraries (microgeom, microsim_core) and the fuzz targets use the same rules.
//
// The rules: a token is consumed whole (no blanks, nothing after the number, not empty); unsigned
// integers are plain decimal digits (no sign, no exponent) and never wrap or clamp; reals are decimal or
// scientific notation, finite ("nan", "inf", out-of-range and hexadecimal are errors).
//
// Header-only because microgeom reads attributes too and may not depend on the oracle's library; the
// command-line parser (parse.h) shares its excerpt rule (quote_excerpt below).
#pragma once

#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

namespace microsim::reader {

inline constexpr std::size_t kExcerptBytes = 40;

// `text` quoted for a message: 'text' with ', \ and bytes outside printable ASCII escaped (\', \\, \xNN),
// cut after at most kExcerptBytes printed characters (escapes included), with "..." and "(N bytes)".
// The one implementation: microsim::quote_excerpt (parse.h) forwards here.
inline std::string quote_excerpt(std::string_view text) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string out = "'";
  std::size_t shown = 0;
  for (; shown < text.size(); ++shown) {
    const auto c = static_cast<unsigned char>(text[shown]);
    std::string piece;
    if (c == '\'' || c == '\\') piece = {'\\', char(c)};
    else if (c >= 0x20 && c < 0x7f) piece = std::string(1, char(c));
    else piece = {'\\', 'x', kHex[c >> 4], kHex[c & 15]};
    if (out.size() - 1 + piece.size() > kExcerptBytes) break;  // the excerpt as printed stays short
    out += piece;
  }
  out += shown < text.size() ? "...' (" + std::to_string(text.size()) + " bytes)" : std::string("'");
  return out;
}

// Plain decimal digits, the whole of `text`, no overflow; nullopt otherwise ("-1", "+1", " 1", "1x",
// "", "1e3" and anything above 2^64 - 1 are all rejected).
inline std::optional<std::uint64_t> parse_uint64(std::string_view text) {
  if (text.empty() || text.front() < '0' || text.front() > '9') return std::nullopt;
  std::uint64_t v = 0;
  const auto r = std::from_chars(text.data(), text.data() + text.size(), v);
  if (r.ec != std::errc() || r.ptr != text.data() + text.size()) return std::nullopt;
  return v;
}

// A finite real in decimal or scientific notation, the whole of `text` (an optional leading '-'; no
// '+', no blanks, no hexadecimal, no "nan"/"inf", nothing beyond a double's range); nullopt otherwise.
inline std::optional<double> parse_finite_double(std::string_view text) {
  const std::size_t digits_at = (!text.empty() && text.front() == '-') ? 1 : 0;
  if (text.size() <= digits_at) return std::nullopt;
  const char first = text[digits_at];
  if (!((first >= '0' && first <= '9') || first == '.')) return std::nullopt;  // "inf", "nan", "+1", " 1"
  double v = 0;
  const auto r = std::from_chars(text.data(), text.data() + text.size(), v, std::chars_format::general);
  if (r.ec != std::errc() || r.ptr != text.data() + text.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

// The ','-separated fields of `text`, empty ones included ("a,,b" has three fields, "" has one).
inline std::vector<std::string_view> split_commas(std::string_view text) {
  std::vector<std::string_view> fields;
  for (;;) {
    const std::size_t comma = text.find(',');
    fields.push_back(text.substr(0, comma));
    if (comma == std::string_view::npos) return fields;
    text.remove_prefix(comma + 1);
  }
}

}  // namespace microsim::reader
