// core: strict parsing of numbers and names stored as text inside input files (EXR string attributes,
// heightmap metadata), and short escaped excerpts of bad input for error messages. Implemented in
// parse.cpp with the command-line parser's rules (parse.h), in their plain form.
//
// The rules: a token is consumed whole (no blanks, nothing after the number, not empty); unsigned
// integers are plain decimal digits (no sign, no exponent) and never wrap or clamp; reals are decimal or
// scientific notation, finite ("nan", "inf", out-of-range and hexadecimal are errors).
//
// The command-line parser (parse.h) accepts more spellings (a leading '+', integers with an exact
// exponent such as 1e6); files hold numbers as microsim writes them, so their readers accept only these.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace microsim::reader {

inline constexpr std::size_t kExcerptBytes = 40;

// `text` quoted for a message: 'text' with ', \ and bytes outside printable ASCII escaped (\', \\, \xNN),
// cut after at most kExcerptBytes printed characters (escapes included), with "..." and "(N bytes)".
// The one implementation: microsim::quote_excerpt (parse.h) forwards here.
std::string quote_excerpt(std::string_view text);

// Plain decimal digits, the whole of `text`, no overflow; nullopt otherwise ("-1", "+1", " 1", "1x",
// "", "1e3" and anything above 2^64 - 1 are all rejected).
std::optional<std::uint64_t> parse_uint64(std::string_view text);

// A finite real in decimal or scientific notation, the whole of `text` (an optional leading '-'; no
// '+', no blanks, no hexadecimal, no "nan"/"inf", nothing beyond a double's range); nullopt otherwise.
std::optional<double> parse_finite_double(std::string_view text);

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
