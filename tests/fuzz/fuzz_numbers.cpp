// libFuzzer target: the number parsers. The command-line parser (src/core/parse.h: reals, integers,
// lists, the supported alpha) must either return a finite value inside the asked range or throw
// ParseError with a short, printable message; the strict attribute parsing of file readers
// (src/core/strict_parse.h) must round-trip what it accepts.
#include "fuzz_common.h"
#include "core/parse.h"
#include "microfacet/roughness.h"
#include "core/strict_parse.h"

#include <cmath>
#include <string>

namespace {
bool all_digits(std::string_view s) {
  if (s.empty()) return false;
  for (char c : s)
    if (c < '0' || c > '9') return false;
  return true;
}

// A rejection must be a ParseError whose message is short and printable (it quotes an excerpt only).
template <class F> void expect_value_or_short_error(F&& parse) {
  try {
    parse();
  } catch (const microsim::ParseError& e) {
    const std::string_view m = e.what();
    if (m.size() > 400) microsim::fuzz::finding("a ParseError message is longer than 400 bytes");
    for (char c : m)
      if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f)
        microsim::fuzz::finding("a ParseError message has a non-printable byte");
  }
}

void fuzz_command_line_parser(std::string_view text) {
  expect_value_or_short_error([&] {
    const double v = microsim::parse_double("--x", text, microsim::Interval{0, 90, false, true});
    if (!(v >= 0 && v < 90)) microsim::fuzz::finding("parse_double returned a value outside its interval");
  });
  expect_value_or_short_error([&] {
    const auto v = microsim::parse_uint("--x", text, 1, 1000000);
    if (v < 1 || v > 1000000) microsim::fuzz::finding("parse_uint returned a value outside its range");
  });
  expect_value_or_short_error([&] {
    const auto v = microsim::parse_int("--x", text, -5, 5);
    if (v < -5 || v > 5) microsim::fuzz::finding("parse_int returned a value outside its range");
  });
  expect_value_or_short_error([&] {
    for (double v : microsim::parse_double_list("--x", text))
      if (!std::isfinite(v)) microsim::fuzz::finding("parse_double_list returned a non-finite value");
  });
  expect_value_or_short_error([&] {
    const auto [ax, ay] = microsim::parse_alpha("--alpha", text);
    if (!(ax >= microsim::kMinAlpha && ay >= microsim::kMinAlpha && ax <= microsim::kMaxSupportedAlpha &&
          ay <= microsim::kMaxSupportedAlpha))
      microsim::fuzz::finding("parse_alpha returned an alpha outside the supported range");
  });
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace microsim::reader;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  fuzz_command_line_parser(text);
  if (const auto v = parse_uint64(text)) {
    if (!all_digits(text)) microsim::fuzz::finding("parse_uint64 accepted something other than digits");
    const std::string back = std::to_string(*v);
    const std::size_t zeros = text.find_first_not_of('0');
    const std::string_view significant = zeros == std::string_view::npos ? "0" : text.substr(zeros);
    if (back != significant) microsim::fuzz::finding("parse_uint64 does not round-trip");
  } else if (all_digits(text) && text.find_first_not_of('0') != std::string_view::npos &&
             text.size() - text.find_first_not_of('0') < 20) {
    microsim::fuzz::finding("parse_uint64 rejected a number below 10^19");
  }
  if (const auto v = parse_finite_double(text)) {
    if (!std::isfinite(*v)) microsim::fuzz::finding("parse_finite_double accepted a non-finite value");
    if (text.front() == '+' || text.find_first_of(" \t\n\r\v\fxXiInN") != std::string_view::npos)
      microsim::fuzz::finding("parse_finite_double accepted blanks, a leading '+', hex, inf or nan");
  }
  std::size_t fields = 0, bytes = 0;
  for (const auto f : split_commas(text)) {
    ++fields;
    bytes += f.size();
  }
  if (bytes + fields - 1 != text.size()) microsim::fuzz::finding("split_commas lost bytes");
  const std::string q = quote_excerpt(text);
  if (q.size() > 4 * kExcerptBytes + 40) microsim::fuzz::finding("quote_excerpt is long");
  for (char c : q)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f)
      microsim::fuzz::finding("quote_excerpt left a non-printable byte");
  return 0;
}
