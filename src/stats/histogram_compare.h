// stats: two traced direction histograms compared (`microsim compare-scattering A.exr B.exr` on two files of
// `microsim trace vndf`): the visible normals of two assemblies of the same NDF, two meshings, two seeds.
// Per binning both files hold with the same description, the counts become lobes per launched ray (mean
// c / rays, variance c / rays^2: a histogram of unit weights) and are compared as scattering lobes are
// (stats/scatter_compare.h): the total-variation distance of the shapes with its noise floor, the fraction of
// rays that hit with its binomial standard error, and the chi-square homogeneity test of the shapes
// (Gagunashvili 2010; for unit weights the two-sample chi-square test of two multinomial samples).
#pragma once

#include "stats/histogram_io.h"
#include "stats/scatter_compare.h"

#include <string>
#include <vector>

namespace microsim {

// The counts of binning `index` of a traced histogram as a lobe per launched ray; its albedo is the
// fraction of rays that hit.
ScatterLobe traced_lobe(const TracedHistogram& h, int index);

struct TracedComparison {
  std::string binning;  // "sphere" or "lobe"
  LobeComparison lobe;  // channel 0, order bin 0 (the first hit)
};

// One comparison per binning the two files share with the same description. Throws std::invalid_argument
// naming both files when they share none (different rows, another view's lobe binning).
std::vector<TracedComparison> compare_traced_histograms(const TracedHistogram& a, const std::string& a_name,
                                                        const TracedHistogram& b, const std::string& b_name,
                                                        const ChiSquareOptions& options);

}  // namespace microsim
