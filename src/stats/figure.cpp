// SVG figures of binned direction histograms (figure.h).
#include "stats/figure.h"

#include "stats/svg_parts.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

namespace microsim {
namespace {

using namespace svg;

constexpr double kPooledBelow = 5;  // the chi-square tests pool cells expected below 5 (chi2.h)

constexpr double kMargin = 50, kGap = 60, kHeader = 60, kRowGap = 95, kPanelWidth = 330;

// One row of three panels per comparison, below the header: the first panel of each row, and the
// figure's size.
struct Layout {
  std::vector<Panel> rows;
  double width = 0, height = 0;
};

Layout layout_rows(const std::vector<BinnedComparison>& comparisons, std::size_t subtitle_lines) {
  Layout l;
  l.height = kHeader + 17.0 * (double(subtitle_lines) - 1);
  for (const BinnedComparison& c : comparisons) {
    const int n = c.binning.size();
    if (int(c.observed.size()) != n || int(c.expected.size()) != n)
      throw std::invalid_argument(fmt::format("histogram_figure_svg: {} binning has {} bins, got {} observed and {} expected",
                                              c.binning.name(), n, c.observed.size(), c.expected.size()));
    const double cell = kPanelWidth / c.binning.cols();
    const Panel p{kMargin, l.height + 25, c.binning.rows(), c.binning.cols(), cell};
    l.rows.push_back(p);
    l.height = p.y + p.height() + kRowGap;
    l.width = std::max(l.width, kMargin + 3 * p.width() + 2 * kGap + 20);
  }
  return l;
}

// One comparison's row: observed, expected and residual panels with their axes and colour bars.
std::string comparison_row(const BinnedComparison& c, const Panel& base) {
  const Panel observed{base.x, base.y, base.rows, base.cols, base.cell};
  const Panel expected{base.x + base.width() + kGap, base.y, base.rows, base.cols, base.cell};
  const Panel residual{base.x + 2 * (base.width() + kGap), base.y, base.rows, base.cols, base.cell};
  double scale = 0;
  for (int i = 0; i < c.binning.size(); ++i) scale = std::max({scale, c.observed[i], c.expected[i]});
  auto residual_color = [&](int i) -> std::string {
    const double e = c.expected[i], o = c.observed[i];
    if (e <= 0) return o > 0 ? "#000000" : "#ffffff";  // samples where the pdf is zero: black
    if (e < kPooledBelow) return "#c8c8c8";            // pooled by the test: not shown bin by bin
    return color_at(kDiverging, 0.5 + (o - e) / std::sqrt(e) / (2 * kResidualClip));
  };
  std::string svg = cell_map(observed, [&](int i) { return color_at(kSequential, c.observed[i] / scale); });
  svg += cell_map(expected, [&](int i) { return color_at(kSequential, c.expected[i] / scale); });
  svg += cell_map(residual, residual_color);
  const std::string space = c.binning.kind() == BinningKind::sphere ? "theta (deg)" : "theta in lobe space (deg)";
  svg += axes(observed, c.binning, c.binning.name() + " bins: observed");
  svg += axes(expected, c.binning, c.binning.name() + " bins: " + c.expected_label);
  svg += axes(residual, c.binning, "(observed - expected) / sqrt(expected)");
  svg += fmt::format(R"~(<text x="{}" y="{}" text-anchor="middle" font-size="10" transform="rotate(-90 {} {})">{}</text>)~",
                     observed.x - 32, observed.y + observed.height() / 2, observed.x - 32,
                     observed.y + observed.height() / 2, space);
  const double bar_y = base.y + base.height() + 36;
  svg += colorbar(observed.x, bar_y, 2 * base.width() + kGap, "sequential", "0", fmt::format("{:.4g}", scale),
                  "counts per bin (both panels)");
  svg += colorbar(residual.x, bar_y, base.width(), "diverging", "-4", "+4", "grey: pooled (expected < 5); black: pdf 0");
  return svg + "\n";
}

}  // namespace

std::string histogram_figure_svg(const std::string& title, const std::string& subtitle,
                                 const std::vector<BinnedComparison>& comparisons) {
  const std::vector<std::string> lines = subtitle_lines(subtitle);
  const Layout layout = layout_rows(comparisons, lines.size());
  std::string svg = document_header(layout.width, layout.height, kMargin, title, lines);
  for (std::size_t k = 0; k < comparisons.size(); ++k) svg += comparison_row(comparisons[k], layout.rows[k]);
  return svg + "</svg>\n";
}

}  // namespace microsim
