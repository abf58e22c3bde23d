// stats: the figure of a scattering comparison (`microsim compare-scattering --svg`): one row per order,
// each with the lobes of the inputs side by side (expected weight per launched path per bin, one colour
// scale per row) and the residual map of every pair, (p_a - p_b) / sigma per bin of the normalised lobes
// p = lobe / albedo, clipped to +-4 on a diverging scale (noise of unit size when the shapes agree; grey
// where a bin has too few effective entries to say). Every panel is the hemispheres binning as an equal-area
// map: reflection above the equator (theta < 90), transmission below, phi 0 to 360 degrees left to right.
#pragma once

#include "stats/binning.h"

#include <string>
#include <vector>

namespace microsim {

struct BinMap {
  std::string label;
  std::vector<double> values;  // per bin; NaN: not shown (grey)
};

struct ScatterFigureRow {
  std::string title;              // "order 1", "total", ...
  std::vector<BinMap> lobes;      // per input
  std::vector<BinMap> residuals;  // per pair
};

// The SVG text. Throws std::invalid_argument when a map does not have binning.size() values.
std::string scatter_figure_svg(const std::string& title, const std::string& subtitle, const DirectionBinning& binning,
                               const std::vector<ScatterFigureRow>& rows);

}  // namespace microsim
