// stats: the pieces of the SVG figures (figure.h, scatter_figure.h): colour scales, equal-area bin maps
// of a DirectionBinning's parameter space, their axes and colour bars. Text only, no font or image library.
#pragma once

#include "stats/binning.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

namespace microsim::svg {

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
// Diverging scale for residuals in [-kResidualClip, kResidualClip]: blue (observed below expected), white, red (above).
constexpr std::array<ColorStop, 3> kDiverging{{{0.0, {35, 85, 170}}, {0.5, {247, 247, 247}}, {1.0, {180, 25, 45}}}};
constexpr double kResidualClip = 4;

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

// Geometry of one panel: the bins as cells of cell x cell pixels.
struct Panel {
  double x, y;  // top-left corner of the map
  int rows, cols;
  double cell;
  double width() const { return cols * cell; }
  double height() const { return rows * cell; }
};

// theta (degrees) of the parameter-space z at a row edge k in [0, rows].
double edge_theta_deg(const DirectionBinning& b, int k);
// The frame of a panel, its title, and phi and theta ticks.
std::string axes(const Panel& p, const DirectionBinning& b, const std::string& title);
// A horizontal colour bar of the gradient `gradient_id`, labelled at both ends and in the middle.
std::string colorbar(double x, double y, double width, const std::string& gradient_id, const std::string& low,
                     const std::string& high, const std::string& label);
// `s` with the XML special characters escaped.
std::string escape(const std::string& s);
// The opening <svg> tag of a width x height figure, the gradients "sequential" and "diverging", the white
// background, the title and the subtitle's lines (at x = margin).
std::string document_header(double width, double height, double margin, const std::string& title,
                            const std::vector<std::string>& lines);
// The subtitle's lines ('\n' separates them; each takes 17 px).
std::vector<std::string> subtitle_lines(const std::string& subtitle);

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

}  // namespace microsim::svg
