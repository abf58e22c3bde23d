// microsim merge of `scatter --shard K/N` parts (scatter EXR files), dispatched to by apps/cmd_merge.cpp: the
// merged histogram, JSON and table are the single run's, bit for bit (stats/scatter_merge.h).
#pragma once

#include <string>
#include <vector>

namespace microsim::app {

// Whether `path` is an EXR file of format microsim-scatter-1.
bool is_scatter_part(const std::string& path);
// Merges the parts (all scatter histograms of one run, every block once) into `out` (required, .exr) and
// `json` (optional); UsageError naming the part and the problem otherwise. `surface` must be empty.
int merge_scatter(const std::vector<std::string>& paths, const std::string& out, const std::string& json,
                  const std::string& surface);

}  // namespace microsim::app
