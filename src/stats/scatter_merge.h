// stats: the partial results of one scattering run (`microsim scatter --shard K/N`, or runs cancelled part
// way) joined into the whole run. The sums are exact (core/exact_sum.h), so the merge is the single run
// bit for bit, whatever the order of the parts.
#pragma once

#include "stats/scatter_histogram.h"

#include <vector>

namespace microsim {

// Throws HistogramMergeError naming the first part of another run (producer, measurement, seed, total
// blocks, binning or channels differ) and every block range held twice or missing.
ScatterHistogram merge_scatter_parts(const std::vector<ScatterHistogram>& parts);

}  // namespace microsim
