// validate: the stability sweep in parts (`microsim stability --shard K/N`, joined by `microsim merge`). A
// shard sweeps a range of the sweep's blocks (stability.h: its views, then the non-finite inputs) and its
// part records the table's rows exactly: every count, every worst figure as the bits of its double, every
// worst configuration. The parts of one sweep, reduced in block order (merge_metrics), are the whole
// sweep's table bit for bit: its markdown and its JSON.
//
// A part: {"provenance": {"producer": "stability", "parameters": {"grid": {...}, "subjects": [...]}, "seed",
//          "blocks", "total_blocks"}, "rows": [{"subject", "regime", counts..., exact reals..., configs...}]}.
#pragma once

#include "stats/part_json.h"
#include "validate/stability.h"

#include <nlohmann/json.hpp>

#include <vector>

namespace microsim {

// A sweep of the registry's samplers and the analytic functions (what `microsim stability` sweeps).
nlohmann::json stability_part_json(const StabilityTable& table);
bool is_stability_part(const nlohmann::json& report);
// Throws HistogramMergeError naming what is missing or malformed (a subject this build does not have).
StabilityTable read_stability_part(const nlohmann::json& report);
// The parts of one sweep joined (any order), their rows reduced in block order. Throws HistogramMergeError
// naming parts of different sweeps (the first parameter that differs, the seed) and missing or repeated
// blocks.
StabilityTable merge_stability_parts(const std::vector<StabilityTable>& parts);

}  // namespace microsim
