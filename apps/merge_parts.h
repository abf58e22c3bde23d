// microsim CLI: the JSON parts of a merge, read and joined with the errors a user can act on: a part that
// cannot be read names its file ("part 'p2.json': ..."), parts that do not make one run are refused
// ("cannot merge: ..."), both bad usage (exit 2, nothing written).
#pragma once

#include "command.h"

#include "stats/histogram.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace microsim::app {

// read(part) for each part; a HistogramMergeError of part i names paths[i].
template <class Read>
auto read_json_parts(const std::vector<nlohmann::json>& parts, const std::vector<std::string>& paths, Read&& read) {
  std::vector<decltype(read(parts.front()))> out;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    try {
      out.push_back(read(parts[i]));
    } catch (const HistogramMergeError& e) {
      throw UsageError(fmt::format("part '{}': {}", paths[i], e.what()));
    }
  }
  return out;
}

// merge(), a HistogramMergeError turned into "cannot merge: ...".
template <class Merge> auto merged_or_usage_error(Merge&& merge) {
  try {
    return merge();
  } catch (const HistogramMergeError& e) {
    throw UsageError(fmt::format("cannot merge: {}", e.what()));
  }
}

}  // namespace microsim::app
