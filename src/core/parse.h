// core: the one parser of numbers written as text: command-line options (every numeric flag of every
// command goes through it) and, where a library reader wants the same rules, numbers inside files.
//
// The rules, in one place:
// - A token is consumed whole: no leading or trailing white space, nothing after the number, not empty.
// - Reals: decimal or scientific notation ("0.3", "-2", "1e-3", ".5", "+4"), rounded as strtod rounds;
//   finite only ("nan", "inf" are errors), no hexadecimal floats, nothing out of a double's range
//   (overflow, or a non-zero value that underflows to a subnormal or zero).
// - Integers: decimal, with an optional exponent when the value is exact ("1e6", "2.5e3" = 2500; "1.5"
//   and "1e-3" are not integers). Out of range is an error, never clamped or wrapped: "-1" for an
//   unsigned count or seed, "99999999999999999999" for any 64-bit integer.
// - Lists: items separated by ',', none of them empty ("0.3," ",0.3" "0.3,,0.5" are errors that say
//   where the empty item is).
// - Every error is a ParseError whose message names the option (`what`) and quotes the bad token as a
//   short excerpt: at most kExcerptBytes characters as printed, bytes outside printable ASCII as \xNN,
//   and when cut "..." and the token's total length. A 10 MB token is never echoed.
//
// The supported roughness, parsed with these rules, is microfacet/roughness.h.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace microsim {

// A malformed or out-of-range number; the message names the option and quotes an excerpt of the token.
struct ParseError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

inline constexpr std::size_t kExcerptBytes = 40;  // the same as reader::kExcerptBytes (strict_parse.h)

// `text` quoted for a message: 'text' with ', \ and bytes outside printable ASCII escaped (\', \\, \xNN);
// cut after at most kExcerptBytes printed characters (escapes included), with "..." and "(N bytes)".
std::string quote_excerpt(std::string_view text);

// A range of reals for checks and messages: [lo, hi], or open at either end.
struct Interval {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false, hi_open = false;
  bool contains(double x) const;
  std::string to_string() const;  // "[0, 90)"
};

// A finite real; throws ParseError("WHAT 'TOKEN': not a number" etc.).
double parse_double(std::string_view what, std::string_view text);
// A finite real in `range`; throws ParseError naming the token and the range otherwise.
double parse_double(std::string_view what, std::string_view text, const Interval& range);
// The same rules without an exception: nullopt for anything parse_double rejects.
std::optional<double> try_parse_double(std::string_view text);

// An integer in [min, max]; throws ParseError naming the token and the bounds otherwise.
std::int64_t parse_int(std::string_view what, std::string_view text, std::int64_t min, std::int64_t max);
// A non-negative integer in [min, max] (a sign '-' is an error, even on "-0").
std::uint64_t parse_uint(std::string_view what, std::string_view text, std::uint64_t min = 0,
                         std::uint64_t max = std::numeric_limits<std::uint64_t>::max());

// The items of a ','-separated list, each non-empty, between min_items and max_items of them.
std::vector<std::string_view> split_list(std::string_view what, std::string_view text, std::size_t min_items = 1,
                                         std::size_t max_items = std::numeric_limits<std::size_t>::max());
// "WHAT 'LIST' item K:" (K from 1): the name under which item k's own error is reported.
std::string list_item_name(std::string_view what, std::string_view list, std::size_t k);
// A list of finite reals, each in `range`.
std::vector<double> parse_double_list(std::string_view what, std::string_view text, const Interval& range = {},
                                      std::size_t max_items = std::numeric_limits<std::size_t>::max());
// A list of non-negative integers, each <= max.
std::vector<std::uint64_t> parse_uint_list(std::string_view what, std::string_view text,
                                           std::uint64_t max = std::numeric_limits<std::uint64_t>::max());

// "K/N": shard K of N (1-based, 1 <= K <= N <= max_shards), e.g. "--shard 3/8"; throws ParseError.
struct ShardSpec {
  std::uint64_t index = 1, count = 1;
};
ShardSpec parse_shard(std::string_view what, std::string_view text, std::uint64_t max_shards);

// ---- documented maxima of counts given on the command line (README, "Numbers on the command line") ----
inline constexpr std::uint64_t kMaxRays = 1'000'000'000'000;     // --rays, --vndf-rays: 1e12
inline constexpr std::uint64_t kMaxSamples = 1'000'000'000'000;  // --samples: 1e12
inline constexpr int kMaxThreads = 4096;                         // --threads

}  // namespace microsim
