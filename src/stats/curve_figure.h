// stats: a line chart of curves with error bars (the albedo tables of an experiment report, E(mu) per
// alpha): one SVG, axes with ticks, one colour per curve and a legend. Built on the pieces of svg_parts.h
// (header, escaping), like the histogram figures (figure.h). Text only, no font or image library.
#pragma once

#include <string>
#include <vector>

namespace microsim {

struct Curve {
  std::string label;
  std::vector<double> x, y;
  std::vector<double> error;  // per point, drawn as +-error bars; empty: none
};

struct CurveAxes {
  std::string x_label, y_label;
};

// The SVG text. The axes span the points (and their error bars) of every curve, padded; a curve with a
// non-finite value skips that point. Throws std::invalid_argument when a curve's x, y (or a non-empty error)
// differ in size, or when no curve has a point.
std::string curve_figure_svg(const std::string& title, const std::string& subtitle, const CurveAxes& axes,
                             const std::vector<Curve>& curves);

}  // namespace microsim
