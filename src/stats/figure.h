// microsim: pictures of binned direction histograms, for people who would rather look than read.
//
// One figure (SVG: text, scales and labels without a font or image library; viewable in any browser
// and embeddable in Markdown) shows, per binning, three panels side by side over the binning's own
// parameter space, drawn as an equal-area map (rows = bands of equal z, top = z_max; columns = equal
// phi, 0 to 360 degrees left to right):
//   1. observed counts per bin,
//   2. expected counts per bin (the analytic pdf times the sample count, or a traced oracle rescaled),
//      on the same colour scale as 1,
//   3. the Pearson residual (observed - expected) / sqrt(expected) per bin, clipped to +-4 on a diverging
//      scale (a correct sampler shows noise of unit size; a wrong one shows structure). Bins the
//      chi-square test pools (expected below 5) are grey; bins with expected 0 but observed > 0 (samples
//      where the pdf is zero) are marked black.
#pragma once

#include "stats/binning.h"

#include <string>
#include <vector>

namespace microsim {

struct BinnedComparison {
  DirectionBinning binning;
  std::vector<double> observed;  // binning.size() counts
  std::vector<double> expected;  // binning.size() expected counts under the reference
  std::string expected_label = "expected";  // e.g. "analytic D_v", "traced oracle (rescaled)"
};

// The SVG text of a figure with one row of three panels per comparison. `title` and `subtitle` head the
// figure (e.g. the sampler and configuration; the verdict and p-values). Throws std::invalid_argument
// when a comparison's vectors do not have binning.size() entries.
std::string histogram_figure_svg(const std::string& title, const std::string& subtitle,
                                 const std::vector<BinnedComparison>& comparisons);

}  // namespace microsim
