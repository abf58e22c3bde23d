// microsim: the one parser of numbers written as text (see parse.h for the rules).
#include "core/parse.h"
#include "core/strict_parse.h"

#include <fmt/core.h>

#include <algorithm>
#include <charconv>
#include <cmath>

namespace microsim {
namespace {

constexpr std::uint64_t kU64Max = std::numeric_limits<std::uint64_t>::max();

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v'; }

[[noreturn]] void fail(std::string_view what, std::string_view text, const std::string& problem) {
  throw ParseError(fmt::format("{} {}: {}", what, quote_excerpt(text), problem));
}

// The problem with a token that cannot be a number at all (shared by reals and integers), or "".
std::string shape_problem(std::string_view text) {
  if (text.empty()) return "empty (a number is needed)";
  if (is_space(text.front()) || is_space(text.back())) return "leading or trailing white space";
  return "";
}

// A finite real, or the reason why not.
std::string to_double(std::string_view text, double& out) {
  if (std::string p = shape_problem(text); !p.empty()) return p;
  std::string_view body = text;
  if (body.front() == '+') {  // from_chars takes no '+'; strtod did (but not "+-1" or "++1")
    body.remove_prefix(1);
    if (body.empty() || body.front() == '+' || body.front() == '-') return "not a number";
  }
  double v = 0;
  const auto [end, ec] = std::from_chars(body.data(), body.data() + body.size(), v, std::chars_format::general);
  if (ec == std::errc::result_out_of_range)
    return "out of the range of a double (magnitude above 1.8e308, or non-zero below 2.2e-308)";
  if (ec != std::errc() || end != body.data() + body.size()) return "not a number";
  if (!std::isfinite(v)) return "not finite (a finite number is needed)";
  if (v != 0 && std::abs(v) < std::numeric_limits<double>::min())
    return "out of the range of a double (magnitude above 1.8e308, or non-zero below 2.2e-308)";
  out = v;
  return "";
}

// A decimal integer with optional fraction and exponent, exact: its sign and magnitude (saturated at
// 2^64 - 1 plus `overflow`), or the reason why it is not an integer.
struct Magnitude {
  bool negative = false;
  bool overflow = false;  // the magnitude exceeds 2^64 - 1
  std::uint64_t value = 0;
};

// Digits of a mantissa "123.4500" without leading zeros of the integer part or trailing zeros overall,
// and the power of ten that scales them to the value.
struct Decimal {
  std::string digits;         // significant digits, no leading or trailing zeros; "" for zero
  std::int64_t exponent = 0;  // value = digits * 10^exponent
};

std::string to_decimal(std::string_view body, Decimal& d) {
  std::size_t i = 0, n_digits = 0;
  std::int64_t fraction_digits = 0;
  bool point = false;
  for (; i < body.size(); ++i) {
    const char c = body[i];
    if (c >= '0' && c <= '9') {
      ++n_digits;
      if (point) ++fraction_digits;
      if (!(d.digits.empty() && c == '0')) d.digits += c;  // leading zeros only move the point
    } else if (c == '.' && !point) {
      point = true;
    } else {
      break;
    }
  }
  if (n_digits == 0) return "not an integer";
  std::int64_t exp10 = 0;
  if (i < body.size()) {
    if (body[i] != 'e' && body[i] != 'E') return "not an integer";
    ++i;
    bool exp_negative = false;
    if (i < body.size() && (body[i] == '+' || body[i] == '-')) exp_negative = body[i++] == '-';
    if (i == body.size()) return "not an integer";
    for (; i < body.size(); ++i) {
      if (body[i] < '0' || body[i] > '9') return "not an integer";
      exp10 = std::min<std::int64_t>(exp10 * 10 + (body[i] - '0'), 1'000'000'000);  // saturates: far beyond 2^64
    }
    if (exp_negative) exp10 = -exp10;
  }
  d.exponent = exp10 - fraction_digits;
  while (!d.digits.empty() && d.digits.back() == '0') {
    d.digits.pop_back();
    ++d.exponent;
  }
  return "";
}

std::string to_magnitude(std::string_view text, Magnitude& m) {
  if (std::string p = shape_problem(text); !p.empty()) return p;
  std::string_view body = text;
  if (body.front() == '+' || body.front() == '-') {
    m.negative = body.front() == '-';
    body.remove_prefix(1);
  }
  Decimal d;
  if (std::string p = to_decimal(body, d); !p.empty()) return p;
  if (d.digits.empty()) return "";  // zero, whatever the exponent
  if (d.exponent < 0) return "not an integer";
  if (std::int64_t(d.digits.size()) + d.exponent > 20) {
    m.overflow = true;
    return "";
  }
  std::uint64_t v = 0;
  for (char c : d.digits) {
    const auto digit = std::uint64_t(c - '0');
    if (v > (kU64Max - digit) / 10) return m.overflow = true, "";
    v = v * 10 + digit;
  }
  for (std::int64_t k = 0; k < d.exponent; ++k) {
    if (v > kU64Max / 10) return m.overflow = true, "";
    v *= 10;
  }
  m.value = v;
  return "";
}

// "1000000000000 (1e12)" for a power of ten from 1e6 on, else the plain number.
std::string integer_text(std::uint64_t v) {
  std::string s = std::to_string(v);
  std::uint64_t p = 1;
  int k = 0;
  while (p < v && p <= kU64Max / 10) p *= 10, ++k;
  if (v >= 1'000'000 && p == v) s += fmt::format(" (1e{})", k);
  return s;
}
std::string integer_text(std::int64_t v) { return v < 0 ? std::to_string(v) : integer_text(std::uint64_t(v)); }

}  // namespace

std::string quote_excerpt(std::string_view text) { return reader::quote_excerpt(text); }

// ---- the plain forms, for numbers inside files (strict_parse.h) ------------------------------------------

namespace reader {

std::string quote_excerpt(std::string_view text) {
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

std::optional<std::uint64_t> parse_uint64(std::string_view text) {
  if (text.empty() || text.front() < '0' || text.front() > '9') return std::nullopt;
  std::uint64_t v = 0;
  const auto r = std::from_chars(text.data(), text.data() + text.size(), v);
  if (r.ec != std::errc() || r.ptr != text.data() + text.size()) return std::nullopt;
  return v;
}

// The command line's reals without the leading '+': decimal or scientific, finite, within a double's range.
std::optional<double> parse_finite_double(std::string_view text) {
  if (!text.empty() && text.front() == '+') return std::nullopt;
  double v = 0;
  if (!to_double(text, v).empty()) return std::nullopt;
  return v;
}

}  // namespace reader

bool Interval::contains(double x) const {
  const bool above = lo_open ? x > lo : x >= lo;
  const bool below = hi_open ? x < hi : x <= hi;
  return above && below;
}

std::string Interval::to_string() const {
  return fmt::format("{}{:g}, {:g}{}", lo_open ? '(' : '[', lo, hi, hi_open ? ')' : ']');
}

double parse_double(std::string_view what, std::string_view text) {
  double v = 0;
  if (std::string p = to_double(text, v); !p.empty()) fail(what, text, p);
  return v;
}

double parse_double(std::string_view what, std::string_view text, const Interval& range) {
  const double v = parse_double(what, text);
  if (!range.contains(v)) fail(what, text, "outside " + range.to_string());
  return v;
}

std::optional<double> try_parse_double(std::string_view text) {
  double v = 0;
  if (!to_double(text, v).empty()) return std::nullopt;
  return v;
}

std::int64_t parse_int(std::string_view what, std::string_view text, std::int64_t min, std::int64_t max) {
  Magnitude m;
  if (std::string p = to_magnitude(text, m); !p.empty()) fail(what, text, p);
  const std::string bounds = fmt::format("an integer in [{}, {}] is needed", integer_text(min), integer_text(max));
  std::int64_t v = 0;
  if (!m.negative) {
    if (m.overflow || max < 0 || m.value > std::uint64_t(max)) fail(what, text, "too large: " + bounds);
    v = std::int64_t(m.value);
  } else {
    const std::uint64_t limit = min >= 0 ? 0 : std::uint64_t(-(min + 1)) + 1;  // |min|, without overflow
    if (m.overflow || m.value > limit) fail(what, text, "too small: " + bounds);
    v = m.value == 0 ? 0 : -std::int64_t(m.value - 1) - 1;
  }
  if (v < min) fail(what, text, "too small: " + bounds);
  if (v > max) fail(what, text, "too large: " + bounds);
  return v;
}

std::uint64_t parse_uint(std::string_view what, std::string_view text, std::uint64_t min, std::uint64_t max) {
  Magnitude m;
  if (std::string p = to_magnitude(text, m); !p.empty()) fail(what, text, p);
  const std::string bounds = fmt::format("an integer in [{}, {}] is needed", integer_text(min), integer_text(max));
  if (m.negative) fail(what, text, "negative: " + bounds);
  if (m.overflow || m.value > max) fail(what, text, "too large: " + bounds);
  if (m.value < min) fail(what, text, "too small: " + bounds);
  return m.value;
}

std::vector<std::string_view> split_list(std::string_view what, std::string_view text, std::size_t min_items,
                                         std::size_t max_items) {
  if (text.empty()) fail(what, text, "empty (a list of values separated by ',' is needed)");
  std::vector<std::string_view> items;
  for (std::size_t start = 0;;) {
    const std::size_t comma = text.find(',', start);
    items.push_back(text.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  for (std::size_t k = 0; k < items.size(); ++k) {
    if (!items[k].empty()) continue;
    if (items.size() == 1) fail(what, text, "empty");
    if (k == 0) fail(what, text, fmt::format("empty item before {}", quote_excerpt(items[1])));
    if (k + 1 == items.size()) fail(what, text, fmt::format("empty item after {}", quote_excerpt(items[k - 1])));
    fail(what, text,
         fmt::format("empty item between {} and {}", quote_excerpt(items[k - 1]), quote_excerpt(items[k + 1])));
  }
  if (items.size() < min_items || items.size() > max_items) {
    const std::string wanted = min_items == max_items ? fmt::format("{}", min_items)
                               : max_items == std::numeric_limits<std::size_t>::max()
                                   ? fmt::format("at least {}", min_items)
                                   : fmt::format("{} to {}", min_items, max_items);
    fail(what, text, fmt::format("{} items, {} expected", items.size(), wanted));
  }
  return items;
}

std::string list_item_name(std::string_view what, std::string_view list, std::size_t k) {
  return fmt::format("{} {} item {}:", what, quote_excerpt(list), k + 1);
}

std::vector<double> parse_double_list(std::string_view what, std::string_view text, const Interval& range,
                                      std::size_t max_items) {
  const std::vector<std::string_view> items = split_list(what, text, 1, max_items);
  std::vector<double> values;
  for (std::size_t k = 0; k < items.size(); ++k)
    values.push_back(items.size() == 1 ? parse_double(what, items[k], range)
                                       : parse_double(list_item_name(what, text, k), items[k], range));
  return values;
}

std::vector<std::uint64_t> parse_uint_list(std::string_view what, std::string_view text, std::uint64_t max) {
  const std::vector<std::string_view> items = split_list(what, text);
  std::vector<std::uint64_t> values;
  for (std::size_t k = 0; k < items.size(); ++k)
    values.push_back(items.size() == 1 ? parse_uint(what, items[k], 0, max)
                                       : parse_uint(list_item_name(what, text, k), items[k], 0, max));
  return values;
}

ShardSpec parse_shard(std::string_view what, std::string_view text, std::uint64_t max_shards) {
  const std::size_t slash = text.find('/');
  if (slash == std::string_view::npos)
    throw ParseError(fmt::format("{} {}: not a shard K/N (e.g. 2/8)", what, quote_excerpt(text)));
  const std::string name(what);
  const std::uint64_t n = parse_uint(name + " (N)", text.substr(slash + 1), 1, max_shards);
  const std::uint64_t k = parse_uint(name + " (K)", text.substr(0, slash), 1, n);
  return {k, n};
}

}  // namespace microsim
