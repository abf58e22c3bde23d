#include "stats/scatter_merge.h"

#include <fmt/core.h>

namespace microsim {

ScatterHistogram merge_scatter_parts(const std::vector<ScatterHistogram>& parts) {
  if (parts.empty()) throw HistogramMergeError("nothing to merge");
  std::vector<BlockRange> ranges;
  ScatterHistogram merged = parts.front();
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const ScatterHistogram& p = parts[i];
    try {
      merged.provenance.check_same_run(p.provenance);
      if (i > 0) merged.merge(p);
    } catch (const HistogramMergeError& e) {
      throw HistogramMergeError(fmt::format("part {}: {}", i + 1, e.what()));
    }
    ranges.push_back(p.provenance.blocks);
  }
  merged.provenance.blocks = merge_block_ranges(ranges, merged.provenance.total_blocks, /*require_complete=*/true);
  merged.partial = false;
  return merged;
}

}  // namespace microsim
