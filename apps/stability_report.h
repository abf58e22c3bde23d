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

// `microsim merge` of stability parts (their JSON, read from `paths`). UsageError when the parts do not
// make one sweep.
int merge_stability(const std::vector<nlohmann::json>& parts, const std::vector<std::string>& paths,
                    const std::string& json);

}  // namespace microsim::app
