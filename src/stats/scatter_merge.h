// stats: the partial results of one scattering run (`microsim scatter --shard K/N`, or runs cancelled part
// way) joined into the whole run, and the part as a file. The sums are exact (core/exact_sum.h), so the
// merge is the single run bit for bit, whatever the order of the parts.
//
// A part (stats/part_json.h): {"provenance": {"producer": "scatter", "parameters": {"producer": the
// histogram's producer ("smith walk", ...), "measurement": its measurement, "binning": the hemispheres
// binning's description, "channels": [names]}, "seed", "blocks", "total_blocks"}, "partial": bool,
// "notes": {KEY: text}, "sums": scatter_sums_json}.
#pragma once

#include "stats/scatter_histogram.h"

#include <nlohmann/json.hpp>

#include <map>
#include <string>
#include <vector>

namespace microsim {

inline constexpr const char* kScatterPartProducer = "scatter";

// Throws HistogramMergeError naming the first part of another run (producer, measurement, seed, total
// blocks, binning or channels differ) and every block range held twice or missing.
ScatterHistogram merge_scatter_parts(const std::vector<ScatterHistogram>& parts);
// Adds one part of the run `sum` holds some blocks of to it, exactly (ScatterHistogram::merge); the blocks are
// the caller's to join. merge_scatter_parts adds its parts with it, the experiment a round's parts in block
// order. Throws HistogramMergeError for a part of another run, binning or channels.
void add_scatter_part(ScatterHistogram& sum, const ScatterHistogram& part);

struct ScatterPart {
  ScatterHistogram histogram;
  std::map<std::string, std::string> notes;  // what the scatter file's "note.KEY" attributes hold
};

// Throws std::invalid_argument unless the histogram's binning is a hemispheres binning whose upper half is
// the reflection side (what a scatter file holds).
nlohmann::json scatter_part_json(const ScatterHistogram& histogram, const std::map<std::string, std::string>& notes);
// The part read back: == the histogram written. Throws HistogramMergeError naming what is missing or
// malformed ("not a scatter part: WHERE ...").
ScatterPart read_scatter_part(const nlohmann::json& report);

}  // namespace microsim
