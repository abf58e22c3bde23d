// experiment: the parts of a split round (split_rounds.h): what one rank, thread or shard job measured of a
// round's block range, in the JSON part form `microsim merge` reads (stats/part_json.h): the round's
// provenance (producer "microsim run"; its measurement, units and surface seed as the parameters; its seed;
// the blocks the part holds, a prefix of its shard when cancelled part way), whether it was, and as "sums"
// (absent when nothing was measured) the kind's own part, the one its command writes for --shard:
// measure/vndf.h vndf_part_json (trace vndf), stats/scatter_merge.h scatter_part_json (scatter),
// measure/masking.h masking_part_json per light (trace masking), measure/validation.h validation_part_json
// (validate), measure/albedo.h albedo_part_json (albedo). The combine functions add the parts from `first` on
// (0: the parts of shard jobs onto a measurement of no block; 1: the ranks' parts after the root's own, rank
// 0's) in block order through the library's own additions (add_vndf_part, add_scatter_part, add_masking_part,
// merge_tallies, read_albedo_part's cells): the one-process
// round, bit for bit. A part that is not rank r's shard of the round (another round, out of block order,
// missing, overlapping) or is malformed is a bug: InternalError.
#pragma once

#include "core/block_runner.h"
#include "measure/masking.h"
#include "measure/validation.h"
#include "measure/vndf.h"
#include "scatter/albedo_table.h"
#include "stats/scatter_histogram.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace microsim::experiment {

// One round: a measurement's (its index in the plan), of `units` units of `seed`, over these blocks; a masking
// round on a heightfield also names the run's seed, which its assembly is built from (0 otherwise).
struct RoundTask {
  std::size_t measurement = 0;
  std::uint64_t units = 0, seed = 0;
  BlockRange blocks;
  std::uint64_t surface_seed = 0;
  bool operator==(const RoundTask&) const = default;
};
nlohmann::json round_task_json(const RoundTask& task);
RoundTask round_task_from_json(const nlohmann::json& task);  // throws nlohmann::json::exception

// What every kind's parts share. A part of `task` holding `blocks`, cancelled part way or not, with the kind's
// sums (null: nothing measured).
std::string round_part(const RoundTask& task, const BlockRange& blocks, bool partial, nlohmann::json sums);
// Gives the sums of the parts from `first` on, in rank order, to add(sums, blocks, rank) (a part cancelled
// before measuring anything has none) until a part cancelled part way; whether every part was whole. Sums
// that are not the kind's (add throws nlohmann::json::exception, HistogramMergeError, std::invalid_argument)
// are a malformed part.
using AddPart = std::function<void(const nlohmann::json& sums, const BlockRange& blocks, int rank)>;
bool add_parts(const std::vector<std::string>& parts, const RoundTask& task, int first, const AddPart& add);
// Checks the measurement the parts are added to: the root's own part (first = 1: rank 0's shard), or nothing
// yet (first = 0, the parts of shard jobs: no block at all, at the round's start).
void check_start(const BlockRange& own, bool partial, const BlockRange& round, int first, int ranks);

// A part cancelled before its first block with nothing measured (a tile's build cancelled on that rank).
std::string cancelled_part(const RoundTask& task, const BlockRange& mine);

// A drawn validation as the library's run of one validation (measure/validation.h: `microsim validate`'s),
// whose parts are validate's; a rank's part of its blocks (nullopt: cancelled) and that part in a round's.
ValidationRun drawn_validation_run(const ValidationCase& validation, const ValidationOptions& options);
std::optional<ValidationPart> own_validation_part(const ValidationRun& run, const BlockRange& blocks);
std::string validation_round_part(const RoundTask& task, const BlockRange& blocks, const std::optional<ValidationPart>& part);
// The parts' tallies in rank order as one (merge_tallies); Cancelled when any part was cancelled.
battery::Tally merged_validation_tally(const std::optional<ValidationPart>& own, const std::vector<std::string>& parts,
                                       const RoundTask& task, int first);

// A heightfield masking round: every light's exact sums (masking_part_json; nullopt: cancelled).
std::string masking_round_part(const RoundTask& task, const BlockRange& blocks,
                               const std::optional<std::vector<SurfaceMasking>>& round);
std::optional<std::vector<SurfaceMasking>> combine_masking_parts(std::optional<std::vector<SurfaceMasking>> own,
                                                                 const std::vector<std::string>& parts,
                                                                 const RoundTask& task, int first);

// Whether a part was cancelled part way (a prefix of its blocks).
bool part_is_partial(const std::string& part);
// Checks that a part holds rank `rank`'s shard of `task`, whole; InternalError naming what it holds.
void check_whole_part(const std::string& part, const RoundTask& task, int rank, int ranks);
// Rank `rank`'s shard of `round` (rank 0 .. ranks - 1): shard rank + 1 of `ranks`, offset to round.begin.
BlockRange rank_blocks(const BlockRange& round, int rank, int ranks);

}  // namespace microsim::experiment
