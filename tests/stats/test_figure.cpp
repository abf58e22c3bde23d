// Figures of binned histograms (figure.h): well-formed SVG, one row of three panels per binning, the
// residual colours that carry the verdict (black where the pdf is 0 but samples fell, grey where the test
// pools), and errors on inconsistent input.
#include "stats/figure.h"

#include <gtest/gtest.h>

#include <regex>
#include <stdexcept>
#include <string>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_figure {

using namespace microsim;

namespace {

std::size_t occurrences(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + what.size())) ++n;
  return n;
}

BinnedComparison uniform_comparison(int rows, double per_bin) {
  const DirectionBinning b = DirectionBinning::sphere(rows);
  return {b, std::vector<double>(b.size(), per_bin), std::vector<double>(b.size(), per_bin), "analytic pdf"};
}

}  // namespace

TEST(Figure, WellFormedWithThreePanelsPerBinning) {
  const std::vector<BinnedComparison> c = {uniform_comparison(5, 100), uniform_comparison(7, 100)};
  const std::string svg = histogram_figure_svg("title <&>", "sub", c);
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  EXPECT_NE(svg.find("</svg>"), std::string::npos);
  EXPECT_EQ(occurrences(svg, "<g "), occurrences(svg, "</g>"));
  EXPECT_EQ(occurrences(svg, "<g shape-rendering"), 6u);  // 2 binnings x (observed, expected, residual)
  EXPECT_NE(svg.find("title &lt;&amp;&gt;"), std::string::npos);  // text is escaped
  // Equal observed and expected counts: residual 0 everywhere, drawn as the diverging scale's white
  // midpoint (#f7f7f7); the count panels are uniform too, so each row is one run.
  EXPECT_EQ(occurrences(svg, R"(fill="#f7f7f7")"), 5u + 7u);
  EXPECT_EQ(occurrences(svg, "<rect x=\"0\" y="), 3u * (5 + 7));
}

TEST(Figure, MarksSamplesWherePdfIsZeroAndPooledCells) {
  BinnedComparison c = uniform_comparison(3, 100);
  c.expected[0] = 0;   // pdf 0 ...
  c.observed[0] = 3;   // ... but samples fell there: black
  c.expected[1] = 2;   // pooled by the chi-square test (expected < 5): grey
  c.observed[2] = 160; // +6 sigma: clipped to the red end of the scale
  c.observed[3] = 40;  // -6 sigma: clipped to the blue end
  const std::string svg = histogram_figure_svg("t", "s", {c});
  EXPECT_EQ(occurrences(svg, R"(fill="#000000")"), 1u);
  EXPECT_EQ(occurrences(svg, R"(fill="#c8c8c8")"), 1u);
  EXPECT_EQ(occurrences(svg, R"(fill="#b4192d")"), 1u);  // kDiverging's last stop, (180, 25, 45)
  EXPECT_EQ(occurrences(svg, R"(fill="#2355aa")"), 1u);  // its first stop, (35, 85, 170)
}

TEST(Figure, RejectsVectorsOfTheWrongSize) {
  BinnedComparison c = uniform_comparison(3, 1);
  c.expected.pop_back();
  EXPECT_THROW(histogram_figure_svg("t", "s", {c}), std::invalid_argument);
}

}  // namespace test_figure
