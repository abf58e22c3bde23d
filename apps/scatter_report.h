// microsim CLI: the report of a scattering result (`scatter` of every model, and `merge` of its parts): the
// scatter EXR, the JSON summary (stats/scatter_io.h) and the albedo table on stdout. One renderer, so a
// merged run reports exactly what the single run would.
#pragma once

#include "stats/scatter_io.h"

#include <map>
#include <string>

namespace microsim::app {

struct ScatterOutputs {
  std::string out;    // scatter EXR, or the part (JSON) when `part`
  std::string json;   // JSON summary ("" for none)
  bool part = false;  // a shard: `out` is its part for `microsim merge` (stats/scatter_merge.h)
};

// Writes the EXR (with `notes`; a shard: its part) and the JSON, prints the table; returns kExitOk, or kExitInterrupted when
// the histogram is partial.
int report_scatter(const ScatterHistogram& histogram, const std::map<std::string, std::string>& notes,
                   const ScatterOutputs& outputs);
int report_scatter(const ScatterExpectation& expectation, const std::map<std::string, std::string>& notes,
                   const ScatterOutputs& outputs);

}  // namespace microsim::app
