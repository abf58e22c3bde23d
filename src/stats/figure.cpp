// SVG figures of binned direction histograms (figure.h).
#include "stats/figure.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

namespace microsim {
namespace {

struct Rgb {
  double r, g, b;
};
struct ColorStop {
  double at;  // position in [0, 1]
  Rgb color;
};

// Sequential scale for counts: white (0) through yellow and orange to dark red (the maximum).
constexpr std::array<ColorStop, 5> kSequential{{{0.0, {255, 255, 255}},
                                                {0.15, {254, 232, 150}},
                                                {0.4, {250, 150, 60}},
                                                {0.7, {195, 30, 40}},
                                                {1.0, {70, 0, 35}}}};
// Diverging scale for residuals in [-4, 4]: blue (observed below expected), white, red (above).
constexpr std::array<ColorStop, 3> kDiverging{{{0.0, {35, 85, 170}}, {0.5, {247, 247, 247}}, {1.0, {180, 25, 45}}}};
constexpr double kResidualClip = 4;
constexpr double kPooledBelow = 5;
constexpr double kDegree = 3.14159265358979323846 / 180;  // the chi-square tests pool cells expected below 5 (chi2.h)

template <std::size_t N> std::string color_at(const std::array<ColorStop, N>& stops, double t) {
  t = std::isfinite(t) ? std::clamp(t, 0.0, 1.0) : 0.0;  // NaN (0/0 scale) draws as the low end
  std::size_t i = 1;
  while (i + 1 < N && stops[i].at < t) ++i;
  const ColorStop &lo = stops[i - 1], &hi = stops[i];
  const double f = (t - lo.at) / (hi.at - lo.at);
  auto mix = [&](double a, double b) { return int(std::lround(a + f * (b - a))); };
  return fmt::format("#{:02x}{:02x}{:02x}", mix(lo.color.r, hi.color.r), mix(lo.color.g, hi.color.g),
                     mix(lo.color.b, hi.color.b));
}

template <std::size_t N> std::string gradient(const std::string& id, const std::array<ColorStop, N>& stops) {
  std::string out = fmt::format(R"(<linearGradient id="{}" x1="0" x2="1" y1="0" y2="0">)", id);
  for (const ColorStop& s : stops)
    out += fmt::format(R"(<stop offset="{}" stop-color="{}"/>)", s.at, color_at(stops, s.at));
  return out + "</linearGradient>";
}

std::string escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

// Geometry of one panel: the bins as cells of cell x cell pixels.
struct Panel {
  double x, y;  // top-left corner of the map
  int rows, cols;
  double cell;
  double width() const { return cols * cell; }
  double height() const { return rows * cell; }
};

// theta (degrees) of the parameter-space z at a row edge k in [0, rows].
double edge_theta_deg(const DirectionBinning& b, int k) {
  const double z = b.z_max() - (b.z_max() - b.z_min()) * k / b.rows();
  return std::acos(std::clamp(z, -1.0, 1.0)) / kDegree;
}

std::string axes(const Panel& p, const DirectionBinning& b, const std::string& title) {
  std::string out;
  out += fmt::format(R"(<rect x="{}" y="{}" width="{}" height="{}" fill="none" stroke="#444" stroke-width="0.8"/>)",
                     p.x, p.y, p.width(), p.height());
  out += fmt::format(R"(<text x="{}" y="{}" text-anchor="middle" font-size="13">{}</text>)", p.x + p.width() / 2,
                     p.y - 8, escape(title));
  for (int deg = 0; deg <= 360; deg += 90) {
    const double x = p.x + p.width() * deg / 360.0;
    out += fmt::format(R"(<line x1="{0}" x2="{0}" y1="{1}" y2="{2}" stroke="#444"/>)", x, p.y + p.height(),
                       p.y + p.height() + 4);
    out += fmt::format(R"(<text x="{}" y="{}" text-anchor="middle" font-size="10">{}</text>)", x,
                       p.y + p.height() + 15, deg);
  }
  out += fmt::format(R"(<text x="{}" y="{}" text-anchor="middle" font-size="10">phi (deg)</text>)",
                     p.x + p.width() / 2, p.y + p.height() + 27);
  // theta ticks every 30 degrees inside the parameter space's z range (rows are equal in z, not theta).
  const double theta_top = edge_theta_deg(b, 0), theta_bottom = edge_theta_deg(b, b.rows());
  double last_y = -1e9;
  for (int deg = 0; deg <= 180; deg += 30) {
    if (deg < theta_top - 1e-9 || deg > theta_bottom + 1e-9) continue;
    const double z = std::cos(deg * kDegree);
    const double y = p.y + p.height() * (b.z_max() - z) / (b.z_max() - b.z_min());
    if (y - last_y < 11) continue;  // labels would overlap (near the poles, z changes slowly)
    last_y = y;
    out += fmt::format(R"(<line x1="{0}" x2="{1}" y1="{2}" y2="{2}" stroke="#444"/>)", p.x - 4, p.x, y);
    out += fmt::format(R"(<text x="{}" y="{}" text-anchor="end" font-size="10">{}</text>)", p.x - 6, y + 3.5, deg);
  }
  return out;
}

std::string colorbar(double x, double y, double width, const std::string& gradient_id, const std::string& low,
                     const std::string& high, const std::string& label) {
  std::string out = fmt::format(R"~(<rect x="{}" y="{}" width="{}" height="8" fill="url(#{})" stroke="#444" stroke-width="0.5"/>)~",
                                x, y, width, gradient_id);
  out += fmt::format(R"(<text x="{}" y="{}" font-size="10">{}</text>)", x, y + 19, escape(low));
  out += fmt::format(R"(<text x="{}" y="{}" text-anchor="end" font-size="10">{}</text>)", x + width, y + 19,
                     escape(high));
  out += fmt::format(R"(<text x="{}" y="{}" text-anchor="middle" font-size="10">{}</text>)", x + width / 2, y + 19,
                     escape(label));
  return out;
}

// The bins of one panel, in cell units (one bin = 1 x 1 after the group's scale); runs of equal colour
// along a row become one rectangle and white (the background) is not drawn, which keeps files small.
template <class ColorOf> std::string cell_map(const Panel& p, ColorOf color_of) {
  std::string out = fmt::format(R"~(<g shape-rendering="crispEdges" transform="translate({} {}) scale({})">)~", p.x,
                                p.y, p.cell);
  for (int row = 0; row < p.rows; ++row) {
    int start = 0;
    std::string run = color_of(row * p.cols);
    for (int col = 1; col <= p.cols; ++col) {
      const std::string next = col < p.cols ? color_of(row * p.cols + col) : std::string();
      if (next == run) continue;
      if (run != "#ffffff")  // overlap by 0.02 cells so that no hairline gaps show between cells
        out += fmt::format(R"(<rect x="{}" y="{}" width="{}" height="1.02" fill="{}"/>)", start, row,
                           col - start + 0.02, run);
      start = col;
      run = next;
    }
  }
  return out + "</g>\n";
}

constexpr double kMargin = 50, kGap = 60, kHeader = 60, kRowGap = 95, kPanelWidth = 330;

// The subtitle's lines ('\n' separates them; each takes 17 px).
std::vector<std::string> subtitle_lines(const std::string& subtitle) {
  std::vector<std::string> lines;
  for (std::size_t start = 0;;) {
    const std::size_t end = subtitle.find('\n', start);
    lines.push_back(subtitle.substr(start, end == std::string::npos ? std::string::npos : end - start));
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return lines;
}

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

// The opening tag, the gradients, the background, the title and the subtitle's lines.
std::string svg_header(const Layout& l, const std::string& title, const std::vector<std::string>& lines) {
  std::string svg = fmt::format(
      R"(<svg xmlns="http://www.w3.org/2000/svg" width="{0}" height="{1}" viewBox="0 0 {0} {1}" font-family="sans-serif">)"
      "\n",
      std::ceil(l.width), std::ceil(l.height));
  svg += "<defs>" + gradient("sequential", kSequential) + gradient("diverging", kDiverging) + "</defs>\n";
  svg += fmt::format(R"(<rect width="100%" height="100%" fill="white"/>)"
                     R"(<text x="{}" y="22" font-size="15" font-weight="bold">{}</text>)",
                     kMargin, escape(title));
  for (std::size_t i = 0; i < lines.size(); ++i)
    svg += fmt::format(R"(<text x="{}" y="{}" font-size="12">{}</text>)", kMargin, 42 + 17 * i, escape(lines[i]));
  return svg + "\n";
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
  std::string svg = svg_header(layout, title, lines);
  for (std::size_t k = 0; k < comparisons.size(); ++k) svg += comparison_row(comparisons[k], layout.rows[k]);
  return svg + "</svg>\n";
}

}  // namespace microsim
