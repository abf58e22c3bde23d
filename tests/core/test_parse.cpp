// The one number parser (src/core/parse.h): reals, integers, lists, ranges, the supported alpha, and
// the messages (option named, bad token quoted as a short escaped excerpt).
#include "core/parse.h"
#include "microfacet/roughness.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <limits>
#include <string>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_parse {

namespace {

using namespace microsim;

// The message of the ParseError that `f` throws ("" if it throws none).
template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const ParseError& e) {
    return e.what();
  }
  return "";
}

TEST(Parse, RealsParseExactlyAsStrtod) {
  for (const char* t : {"0.3", "-2", "1e-3", ".5", "5.", "89.99", "0.1", "1e308", "2.2250738585072014e-308",
                        "0.30000000000000004", "123456789.123456789", "-0", "7E2"}) {
    EXPECT_EQ(parse_double("--x", t), std::strtod(t, nullptr)) << t;
  }
  EXPECT_EQ(parse_double("--x", "+4"), 4.0);
  EXPECT_TRUE(std::signbit(parse_double("--x", "-0")));
}

TEST(Parse, RealsRejectEverythingButAWholeFiniteNumber) {
  struct Case {
    const char* text;
    const char* problem;
  };
  for (const Case& c : {Case{"", "empty"},
                        Case{" 0.3", "white space"},
                        Case{"0.3 ", "white space"},
                        Case{"\t1", "white space"},
                        Case{"nan", "not finite"},
                        Case{"NaN", "not finite"},
                        Case{"inf", "not finite"},
                        Case{"-infinity", "not finite"},
                        Case{"0x1p3", "not a number"},
                        Case{"0x10", "not a number"},
                        Case{"1e", "not a number"},
                        Case{"0.3,", "not a number"},
                        Case{"0.3x", "not a number"},
                        Case{"abc", "not a number"},
                        Case{"+-1", "not a number"},
                        Case{"++1", "not a number"},
                        Case{"+", "not a number"},
                        Case{"-", "not a number"},
                        Case{"1e309", "out of the range"},
                        Case{"-1e99999", "out of the range"},
                        Case{"1e-400", "out of the range"},
                        Case{"1e-310", "out of the range"},
                        Case{"1,5", "not a number"}}) {
    const std::string m = error_of([&] { parse_double("--theta", c.text); });
    EXPECT_NE(m.find("--theta " + quote_excerpt(c.text) + ": "), std::string::npos) << c.text << ": " << m;
    EXPECT_NE(m.find(c.problem), std::string::npos) << c.text << ": " << m;
    EXPECT_FALSE(try_parse_double(c.text)) << c.text;
  }
  EXPECT_EQ(try_parse_double("0.25"), 0.25);
}

TEST(Parse, RangesNameTheTokenAndTheRange) {
  const Interval view{0, 90, false, true};
  EXPECT_EQ(parse_double("--theta", "0", view), 0.0);
  EXPECT_EQ(parse_double("--theta", "89.99", view), 89.99);
  const std::string m = error_of([&] { parse_double("--theta", "90", view); });
  EXPECT_NE(m.find("--theta '90': outside [0, 90)"), std::string::npos) << m;
  EXPECT_NE(error_of([&] { parse_double("--x", "0", Interval{0, 1, true, false}); }).find("(0, 1]"), std::string::npos);
  EXPECT_TRUE(Interval{}.contains(-1e308));
}

TEST(Parse, IntegersAreExactOrAnError) {
  EXPECT_EQ(parse_uint("--rays", "1000"), 1000u);
  EXPECT_EQ(parse_uint("--rays", "1e6"), 1'000'000u);
  EXPECT_EQ(parse_uint("--rays", "1E12"), 1'000'000'000'000u);
  EXPECT_EQ(parse_uint("--rays", "2.5e3"), 2500u);
  EXPECT_EQ(parse_uint("--rays", "+7"), 7u);
  EXPECT_EQ(parse_uint("--rays", "007"), 7u);
  EXPECT_EQ(parse_uint("--rays", "0e999999999999999999"), 0u);
  EXPECT_EQ(parse_uint("--rays", "120e-1"), 12u);
  EXPECT_EQ(parse_uint("--seed", "18446744073709551615"), std::numeric_limits<std::uint64_t>::max());
  EXPECT_EQ(parse_int("--n", "-9223372036854775808", std::numeric_limits<std::int64_t>::min(), 0),
            std::numeric_limits<std::int64_t>::min());
  EXPECT_EQ(parse_int("--n", "9223372036854775807", 0, std::numeric_limits<std::int64_t>::max()),
            std::numeric_limits<std::int64_t>::max());
  EXPECT_EQ(parse_int("--phi", "-5", -10, 10), -5);
  EXPECT_EQ(parse_int("--phi", "-0", -10, 10), 0);

  struct Case {
    const char* text;
    const char* problem;
  };
  for (const Case& c : {Case{"-1", "negative"},
                        Case{"-0", "negative"},
                        Case{"18446744073709551616", "too large"},
                        Case{"99999999999999999999", "too large"},
                        Case{"1e20", "too large"},
                        Case{"1e999999999999999999999", "too large"},
                        Case{"1.5", "not an integer"},
                        Case{"1e-3", "not an integer"},
                        Case{"0x10", "not an integer"},
                        Case{"inf", "not an integer"},
                        Case{"nan", "not an integer"},
                        Case{"", "empty"},
                        Case{" 1", "white space"},
                        Case{"1 ", "white space"},
                        Case{"1e", "not an integer"},
                        Case{"1e+", "not an integer"},
                        Case{".", "not an integer"},
                        Case{"1..2", "not an integer"},
                        Case{"--1", "not an integer"},
                        Case{"1,000", "not an integer"},
                        Case{"1_000", "not an integer"}}) {
    const std::string m = error_of([&] { parse_uint("--seed", c.text); });
    EXPECT_NE(m.find("--seed '" + std::string(c.text) + "'"), std::string::npos) << c.text << ": " << m;
    EXPECT_NE(m.find(c.problem), std::string::npos) << c.text << ": " << m;
  }
  const std::string rays = error_of([] { parse_uint("--rays", "99999999999999999999", 1, kMaxRays); });
  EXPECT_NE(rays.find("'99999999999999999999'"), std::string::npos) << rays;
  EXPECT_NE(rays.find("1000000000000 (1e12)"), std::string::npos) << rays;
  EXPECT_NE(error_of([] { parse_uint("--rays", "0", 1, kMaxRays); }).find("too small"), std::string::npos);
  EXPECT_NE(error_of([] { parse_int("--rows", "46341", 1, 501); }).find("too large: an integer in [1, 501]"),
            std::string::npos);
  EXPECT_NE(error_of([] { parse_int("--rows", "-3", 1, 501); }).find("too small"), std::string::npos);
  EXPECT_NE(error_of([] {
              parse_int("--n", "-9223372036854775809", std::numeric_limits<std::int64_t>::min(), 0);
            }).find("too small"),
            std::string::npos);
}

TEST(Parse, ListsNameTheEmptyItem) {
  EXPECT_EQ(parse_double_list("--thetas", "30,60,75"), (std::vector<double>{30, 60, 75}));
  EXPECT_EQ(parse_uint_list("--seeds", "1,2,3"), (std::vector<std::uint64_t>{1, 2, 3}));
  EXPECT_NE(error_of([] { parse_double_list("--alpha", "0.3,"); }).find("'0.3,': empty item after '0.3'"),
            std::string::npos);
  EXPECT_NE(error_of([] { parse_double_list("--alpha", ",0.3"); }).find("empty item before '0.3'"), std::string::npos);
  EXPECT_NE(error_of([] { parse_double_list("--alpha", "0.3,,0.5"); }).find("empty item between '0.3' and '0.5'"),
            std::string::npos);
  EXPECT_NE(error_of([] { parse_double_list("--alpha", ","); }).find("empty item"), std::string::npos);
  EXPECT_NE(error_of([] { parse_double_list("--alpha", ""); }).find("empty"), std::string::npos);
  EXPECT_NE(error_of([] { parse_double_list("--alpha", "1,2,3", {}, 2); }).find("3 items, 1 to 2 expected"),
            std::string::npos);
  const std::string item = error_of([] { parse_double_list("--thetas", "30,abc", Interval{0, 90}); });
  EXPECT_NE(item.find("--thetas '30,abc' item 2: 'abc': not a number"), std::string::npos) << item;
  EXPECT_NE(error_of([] { parse_uint_list("--seeds", "1,-2"); }).find("'-2': negative"), std::string::npos);
  // The old message for "0.3," was "'' is not a number": the empty item is now named by its place.
  EXPECT_EQ(error_of([] { parse_double_list("--alpha", "0.3,"); }).find("''"), std::string::npos);
}

TEST(Parse, ExcerptsAreShortAndEscaped) {
  EXPECT_EQ(quote_excerpt("0.3"), "'0.3'");
  EXPECT_EQ(quote_excerpt(std::string("a\x01\xff'\\b", 6)), "'a\\x01\\xFF\\'\\\\b'");
  const std::string huge(10'000'000, '7');
  const std::string q = quote_excerpt(huge);
  EXPECT_EQ(q, "'" + std::string(kExcerptBytes, '7') + "...' (10000000 bytes)");
  const std::string m = error_of([&] { parse_uint("--rays", huge, 1, kMaxRays); });
  EXPECT_LT(m.size(), 200u) << m.substr(0, 300);
  EXPECT_NE(m.find("(10000000 bytes)"), std::string::npos);
  const std::string binary = error_of([] { parse_double("--phi", std::string("1\x00\x1b[2J", 6)); });
  EXPECT_NE(binary.find("'1\\x00\\x1B[2J'"), std::string::npos) << binary;
  EXPECT_EQ(binary.find('\x1b'), std::string::npos);
}

TEST(Parse, AlphaHasOneSupportedRange) {
  EXPECT_EQ(parse_alpha("--alpha", "0.3"), (std::pair<double, double>{0.3, 0.3}));
  EXPECT_EQ(parse_alpha("--alpha", "0.05,0.5"), (std::pair<double, double>{0.05, 0.5}));
  EXPECT_EQ(parse_alpha("--alpha", "1e-4"), (std::pair<double, double>{1e-4, 1e-4}));
  EXPECT_EQ(parse_alpha("--alpha", "10"), (std::pair<double, double>{10, 10}));
  // The stability sweep's 1:1000 pairs are inside.
  for (double a : {1e-4, 1e-3, 0.01}) {
    EXPECT_NO_THROW(check_supported_alpha("--alpha", a, a * 1000));
    EXPECT_NO_THROW(check_supported_alpha("--alpha", a * 1000, a));
  }
  EXPECT_NO_THROW(parse_alpha("--alpha", "0.0001,0.1"));
  struct Case {
    const char* text;
    const char* needle;
  };
  for (const Case& c :
       {Case{"1e30", "'1e30': outside the supported roughness range [0.0001, 10]"}, Case{"0", "'0': outside"},
        Case{"-0", "'-0': outside"}, Case{"-0.3", "'-0.3': outside"}, Case{"10.000001", "outside"},
        Case{"9e-5", "outside"}, Case{"0.5,-1", "item 2: '-1': outside"},
        Case{"1e-4,1", "anisotropy 1:1e+04 beyond the supported 1:1000"}, Case{"0.0001,0.1001", "anisotropy"},
        Case{"0.3,", "empty item after '0.3'"}, Case{"0.3,0.3,0.3", "3 items"}, Case{"nan", "not finite"},
        Case{"0.3,inf", "not finite"}, Case{"abc", "not a number"}}) {
    const std::string m = error_of([&] { parse_alpha("--alpha", c.text); });
    EXPECT_NE(m.find(c.needle), std::string::npos) << c.text << ": " << m;
    EXPECT_EQ(m.rfind("--alpha", 0), 0u) << m;
  }
  EXPECT_NE(error_of([] { check_supported_alpha("alpha", 20, 20); }).find("alpha 20: outside"), std::string::npos);
}

}  // namespace

}  // namespace test_parse
