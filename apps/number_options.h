// microsim: numeric command-line options, all read by the one number parser (src/core/parse.h).
//
// CLI11 never converts a number itself (it clamps or wraps some out-of-range integers): each numeric
// option is bound to its text, and a callback parses that text when the command line is read and stores
// the value. A bad number is then a usage error (exit 2) that names the option and quotes a short
// excerpt of the token, before any work is done.
#pragma once

#include "command.h"

#include "stats/binning.h"
#include "core/parse.h"

#include <fmt/core.h>

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>

namespace microsim::app {

namespace detail {
template <class T>
struct OptionValue {
  using type = T;
};
template <class T>
struct OptionValue<std::optional<T>> {
  using type = T;
};
}  // namespace detail

// Adds `name` to `sub`: its text goes through parse(name, text) and the result is stored in `target`
// (a number, or an optional one). `target` must outlive the parse (a member of the command's shared args).
template <class T, class Parse>
CLI::Option* add_number_option(CLI::App* sub, const std::string& name, T& target, Parse parse,
                               const std::string& help) {
  using Value = typename detail::OptionValue<T>::type;
  CLI::Option* option = sub->add_option_function<std::string>(
      name,
      [&target, parse, name](const std::string& text) {
        try {
          target = static_cast<Value>(parse(name, text));
        } catch (const ParseError& e) {
          throw CLI::ValidationError(e.what());
        }
      },
      help);
  option->type_name(std::is_floating_point_v<Value> ? "FLOAT" : "INT");
  return option;
}

// The parsers to pass to add_number_option.
// A finite real, optionally in `range`.
inline auto real(Interval range = {}) {
  return [range](std::string_view what, std::string_view text) { return parse_double(what, text, range); };
}
// A significance level: a real in (0, 1) (at 0 nothing is rejected, at 1 everything).
inline auto level() { return real({0, 1, true, true}); }
// An integer in [min, max].
inline auto integer(std::int64_t min, std::int64_t max) {
  return [min, max](std::string_view what, std::string_view text) { return parse_int(what, text, min, max); };
}
// A count, a seed: a non-negative integer in [min, max] ("-1" is an error, never 2^64 - 1).
inline auto whole(std::uint64_t min = 0, std::uint64_t max = std::numeric_limits<std::uint64_t>::max()) {
  return [min, max](std::string_view what, std::string_view text) { return parse_uint(what, text, min, max); };
}
// --rows of the sphere and lobe binnings: odd, in [min_rows, kMaxBinningRows] (binning.h), one rule for
// every command.
inline auto binning_rows(int min_rows) {
  return [min_rows](std::string_view what, std::string_view text) {
    const std::int64_t rows = parse_int(what, text, min_rows, kMaxBinningRows);
    if (rows % 2 == 0)
      throw ParseError(
          fmt::format("{} {}: must be odd (the equator lies inside the middle band)", what, quote_excerpt(text)));
    return rows;
  };
}

// A power of two in [min, max] (a heightfield resolution).
inline auto power_of_two(std::int64_t min, std::int64_t max) {
  return [min, max](std::string_view what, std::string_view text) {
    const std::int64_t n = parse_int(what, text, min, max);
    if ((n & (n - 1)) != 0)
      throw ParseError(fmt::format("{} {}: not a power of two (one in [{}, {}] is needed)", what, quote_excerpt(text),
                                   min, max));
    return n;
  };
}

// The help text of a count option: "... (at most 1e12)".
inline std::string at_most(std::string help, std::uint64_t max) {
  int exponent = 0;
  std::uint64_t power = 1;
  while (power < max && power <= std::numeric_limits<std::uint64_t>::max() / 10) power *= 10, ++exponent;
  return help + (max >= 1'000'000 && power == max ? fmt::format(" (at most 1e{})", exponent)
                                                  : fmt::format(" (at most {})", max));
}

}  // namespace microsim::app
