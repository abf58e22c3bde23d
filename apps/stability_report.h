// microsim CLI: the report of `microsim stability` (the markdown table on stdout, the verdict line, the
// JSON), and the merge of its parts (`stability --shard K/N`, joined by `microsim merge`): one renderer, so
// a merged sweep prints and writes exactly what the single sweep would.
#pragma once

#include "validate/stability.h"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace microsim::app {

// Prints the table (only the rows over their bound with `failures_only`) and the verdict line, writes
// `json` ("" for none); returns 0 when every row is within its bound, 1 otherwise.
int report_stability(const StabilityTable& table, bool failures_only, const std::string& json);

// `microsim merge` of stability parts (merged by measure/merge.h from `parts` parts): reported as the
// single sweep.
int report_merged_stability(const StabilityTable& merged, std::size_t parts, const std::string& json);

}  // namespace microsim::app
