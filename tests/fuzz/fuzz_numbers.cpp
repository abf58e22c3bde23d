// libFuzzer target: the strict number parsing of file attributes (microsim/strict_parse.h) and its
// message excerpts.
//
// TODO(lead): fuzz the command-line number parser src/microsim/parse.h (worktree `numbers`) here once it
// is on main: parse_double, parse_int, parse_uint, split_list, parse_double_list, quote_excerpt, with the
// same properties (accepted tokens round-trip, rejected ones give short messages).
#include "fuzz_common.h"
#include "microsim/strict_parse.h"

#include <cmath>
#include <string>

namespace {
bool all_digits(std::string_view s) {
  if (s.empty()) return false;
  for (char c : s)
    if (c < '0' || c > '9') return false;
  return true;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace microsim::reader;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
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
