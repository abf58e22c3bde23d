// The figure of a scattering comparison (scatter_figure.h).
#include "stats/scatter_figure.h"

#include "stats/svg_parts.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace microsim {
namespace {

using namespace svg;

constexpr double kScatterMargin = 50, kScatterGap = 45, kScatterHeader = 60, kScatterRowGap = 110;

struct ScatterLayout {
  double panel_width = 0, width = 0, height = 0;
  std::vector<double> row_y;  // top of each row's maps
};

ScatterLayout layout(const DirectionBinning& b, const std::vector<ScatterFigureRow>& rows, std::size_t subtitle_lines) {
  ScatterLayout l;
  std::size_t panels = 1;
  for (const ScatterFigureRow& r : rows) {
    panels = std::max(panels, r.lobes.size() + r.residuals.size());
    for (const auto* maps : {&r.lobes, &r.residuals})
      for (const BinMap& m : *maps)
        if (int(m.values.size()) != b.size())
          throw std::invalid_argument(fmt::format("scatter_figure_svg: map '{}' has {} values for {} bins", m.label,
                                                  m.values.size(), b.size()));
  }
  l.panel_width = panels > 4 ? 240 : 300;
  const double cell = l.panel_width / b.cols();
  double y = kScatterHeader + 17.0 * (double(subtitle_lines) - 1) + 25;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    l.row_y.push_back(y + 20);
    y += 20 + b.rows() * cell + kScatterRowGap;
  }
  l.height = y;
  l.width = kScatterMargin + double(panels) * (l.panel_width + kScatterGap) + 20;
  return l;
}

std::string residual_color(double r) {
  if (std::isnan(r)) return "#c8c8c8";
  return color_at(kDiverging, 0.5 + std::clamp(r, -kResidualClip, kResidualClip) / (2 * kResidualClip));
}

// One order: the lobes on one sequential scale, then the residual maps.
std::string figure_row(const ScatterFigureRow& row, const DirectionBinning& b, const ScatterLayout& l, double y) {
  const double cell = l.panel_width / b.cols();
  double scale = 0;
  for (const BinMap& m : row.lobes)
    for (double v : m.values)
      if (std::isfinite(v)) scale = std::max(scale, v);
  std::string svg = fmt::format(R"(<text x="{}" y="{}" font-size="14" font-weight="bold">{}</text>)", kScatterMargin, y - 28,
                                escape(row.title));
  double x = kScatterMargin;
  for (const BinMap& m : row.lobes) {
    const Panel p{x, y, b.rows(), b.cols(), cell};
    svg += cell_map(p, [&](int i) { return color_at(kSequential, m.values[std::size_t(i)] / scale); });
    svg += axes(p, b, m.label);
    x += l.panel_width + kScatterGap;
  }
  const double bar_y = y + b.rows() * cell + 36;
  svg += colorbar(kScatterMargin, bar_y, x - kScatterGap - kScatterMargin, "sequential", "0", fmt::format("{:.4g}", scale),
                  "weight per launched path per bin");
  const double residual_x = x;
  for (const BinMap& m : row.residuals) {
    const Panel p{x, y, b.rows(), b.cols(), cell};
    svg += cell_map(p, [&](int i) { return residual_color(m.values[std::size_t(i)]); });
    svg += axes(p, b, m.label);
    x += l.panel_width + kScatterGap;
  }
  if (!row.residuals.empty())
    svg += colorbar(residual_x, bar_y, x - kScatterGap - residual_x, "diverging", "-4", "+4",
                    "shape residual / sigma (grey: too few entries)");
  return svg + "\n";
}

}  // namespace

std::string scatter_figure_svg(const std::string& title, const std::string& subtitle, const DirectionBinning& binning,
                               const std::vector<ScatterFigureRow>& rows) {
  const std::vector<std::string> lines = subtitle_lines(subtitle);
  const ScatterLayout l = layout(binning, rows, lines.size());
  std::string svg = document_header(l.width, l.height, kScatterMargin, title, lines);
  for (std::size_t k = 0; k < rows.size(); ++k) svg += figure_row(rows[k], binning, l, l.row_y[k]);
  return svg + "</svg>\n";
}

}  // namespace microsim
