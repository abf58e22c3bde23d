// A line chart of curves with error bars (curve_figure.h).
#include "stats/curve_figure.h"

#include "stats/svg_parts.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace microsim {
namespace {

using namespace svg;

constexpr double kCurveMargin = 60, kPlotWidth = 520, kPlotHeight = 300, kLegendWidth = 170, kTicks = 5;
// Colour-blind-safe qualitative colours (Okabe & Ito 2008), cycled.
constexpr std::array<const char*, 8> kColors{"#0072b2", "#d55e00", "#009e73", "#cc79a7",
                                             "#e69f00", "#56b4e9", "#000000", "#f0e442"};

struct Range {
  double lo = std::numeric_limits<double>::infinity(), hi = -std::numeric_limits<double>::infinity();
  void add(double v) {
    if (!std::isfinite(v)) return;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  // Padded by 5% (a flat range by 1% of its value, or 1), so no point sits on the frame.
  Range padded() const {
    const double span = hi > lo ? hi - lo : std::max(std::abs(hi) * 0.01, 1e-12);
    return {lo - 0.05 * span, hi + 0.05 * span};
  }
  double at(double v, double length) const { return length * (v - lo) / (hi - lo); }
};

std::pair<Range, Range> ranges_of(const std::vector<Curve>& curves) {
  Range x, y;
  for (const Curve& c : curves) {
    if (c.x.size() != c.y.size() || (!c.error.empty() && c.error.size() != c.y.size()))
      throw std::invalid_argument(fmt::format("curve_figure_svg: curve '{}' has {} x, {} y and {} errors", c.label,
                                              c.x.size(), c.y.size(), c.error.size()));
    for (std::size_t i = 0; i < c.x.size(); ++i) {
      if (!std::isfinite(c.x[i]) || !std::isfinite(c.y[i])) continue;
      x.add(c.x[i]);
      const double e = c.error.empty() || !std::isfinite(c.error[i]) ? 0 : c.error[i];
      y.add(c.y[i] - e);
      y.add(c.y[i] + e);
    }
  }
  if (!(x.hi >= x.lo)) throw std::invalid_argument("curve_figure_svg: no curve has a point");
  return {x.padded(), y.padded()};
}

std::string frame_and_ticks(double x0, double y0, const Range& x, const Range& y, const CurveAxes& a) {
  std::string out = fmt::format(R"(<rect x="{}" y="{}" width="{}" height="{}" fill="none" stroke="#444"/>)", x0, y0,
                                kPlotWidth, kPlotHeight);
  for (int k = 0; k <= kTicks; ++k) {
    const double vx = x.lo + (x.hi - x.lo) * k / kTicks, px = x0 + x.at(vx, kPlotWidth);
    const double vy = y.lo + (y.hi - y.lo) * k / kTicks, py = y0 + kPlotHeight - y.at(vy, kPlotHeight);
    out += fmt::format(R"(<line x1="{0}" x2="{0}" y1="{1}" y2="{2}" stroke="#444"/>)", px, y0 + kPlotHeight,
                       y0 + kPlotHeight + 4);
    out += fmt::format(R"(<text x="{}" y="{}" text-anchor="middle" font-size="10">{:.3g}</text>)", px,
                       y0 + kPlotHeight + 15, vx);
    out += fmt::format(R"(<line x1="{0}" x2="{1}" y1="{2}" y2="{2}" stroke="#ddd"/>)", x0, x0 + kPlotWidth, py);
    out += fmt::format(R"(<text x="{}" y="{}" text-anchor="end" font-size="10">{:.4g}</text>)", x0 - 6, py + 3.5, vy);
  }
  out += fmt::format(R"(<text x="{}" y="{}" text-anchor="middle" font-size="11">{}</text>)", x0 + kPlotWidth / 2,
                     y0 + kPlotHeight + 32, escape(a.x_label));
  out += fmt::format(R"~(<text x="{0}" y="{1}" text-anchor="middle" font-size="11" transform="rotate(-90 {0} {1})">{2}</text>)~",
                     x0 - 46, y0 + kPlotHeight / 2, escape(a.y_label));
  return out;
}

std::string curve_path(const Curve& c, const char* color, double x0, double y0, const Range& x, const Range& y) {
  std::string points, bars;
  for (std::size_t i = 0; i < c.x.size(); ++i) {
    if (!std::isfinite(c.x[i]) || !std::isfinite(c.y[i])) continue;
    const double px = x0 + x.at(c.x[i], kPlotWidth), py = y0 + kPlotHeight - y.at(c.y[i], kPlotHeight);
    points += fmt::format("{:.2f},{:.2f} ", px, py);
    const double e = c.error.empty() || !std::isfinite(c.error[i]) ? 0 : c.error[i];
    if (e > 0)
      bars += fmt::format(R"(<line x1="{0:.2f}" x2="{0:.2f}" y1="{1:.2f}" y2="{2:.2f}" stroke="{3}"/>)", px,
                          y0 + kPlotHeight - y.at(c.y[i] - e, kPlotHeight),
                          y0 + kPlotHeight - y.at(c.y[i] + e, kPlotHeight), color);
    bars += fmt::format(R"(<circle cx="{:.2f}" cy="{:.2f}" r="2.2" fill="{}"/>)", px, py, color);
  }
  return fmt::format(R"(<polyline points="{}" fill="none" stroke="{}" stroke-width="1.4"/>)", points, color) + bars +
         "\n";
}

}  // namespace

std::string curve_figure_svg(const std::string& title, const std::string& subtitle, const CurveAxes& axes,
                             const std::vector<Curve>& curves) {
  const auto [x, y] = ranges_of(curves);
  const std::vector<std::string> lines = subtitle_lines(subtitle);
  const double y0 = 50 + 17.0 * double(lines.size());
  const double height = y0 + kPlotHeight + 50;
  std::string svg = document_header(kCurveMargin + kPlotWidth + kLegendWidth, height, kCurveMargin - 40, title, lines);
  svg += frame_and_ticks(kCurveMargin, y0, x, y, axes);
  for (std::size_t i = 0; i < curves.size(); ++i) {
    const char* color = kColors[i % kColors.size()];
    svg += curve_path(curves[i], color, kCurveMargin, y0, x, y);
    const double ly = y0 + 12 + 16.0 * double(i);
    svg += fmt::format(R"(<line x1="{0}" x2="{1}" y1="{2}" y2="{2}" stroke="{3}" stroke-width="2"/>)",
                       kCurveMargin + kPlotWidth + 12, kCurveMargin + kPlotWidth + 30, ly, color);
    svg += fmt::format(R"(<text x="{}" y="{}" font-size="11">{}</text>)", kCurveMargin + kPlotWidth + 35, ly + 4,
                       escape(curves[i].label));
  }
  return svg + "</svg>\n";
}

}  // namespace microsim
