// experiment: the rounds of run_experiment split over ranks (ranks.h; `mpirun -n P microsim run`) or taken from
// the stored parts of shard jobs (shards.h). A round is one seed and one range of blocks (core/block_runner.h).
// The root sends it to every rank (a RoundTask), rank r runs its contiguous shard of the range (rank_blocks:
// rank order is block order), the parts (parts.h: exact tallies) are gathered to the root and added there in
// rank order: the one-process round, bit for bit. A part cancelled part way ends the round there (the completed
// prefix, marked partial, resumed like a one-process round). The root alone decides the rounds' sizes and when
// to stop; the other ranks only run what it sends (serve_rounds: Measurement::part) until it stops. On an
// explicit heightfield every rank takes the same tile from its SurfaceCache (DIR/surfaces, or built from the
// same key: a build is a pure function of its key). Which kinds share their rounds, and how, is each kind's
// (measurement.h: Measurement::shared, first_round, part); a kind not shared runs on the root while the
// other ranks wait.
#pragma once

#include "experiment/measures.h"
#include "experiment/parts.h"
#include "experiment/plan.h"
#include "experiment/ranks.h"
#include "experiment/spec.h"
#include "measure/surface_cache.h"
#include "measure/masking.h"
#include "measure/masking_runs.h"
#include "measure/vndf.h"
#include "scatter/albedo_table.h"
#include "scatter/smith_walk.h"
#include "validate/validate.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <optional>
#include <type_traits>
#include <string>
#include <vector>

namespace microsim::experiment {


// Whether a decision's rounds are block ranges split over ranks and shards (Measurement::split), and whether
// the ranks share its work at all (Measurement::shared: also a validation's one round).
bool is_split(const ExperimentSpec& spec, const Decision& decision);
bool is_shared_by_ranks(const ExperimentSpec& spec, const Decision& decision);

// Parts of rounds run elsewhere (shard jobs, shards.h): parts[t] holds task t's parts in shard order.
struct StoredRounds {
  std::vector<RoundTask> tasks;
  std::vector<std::vector<std::string>> parts;
};

// Where the root's rounds come from: its own work only (null, or one rank), shared with ranks, or, for a
// round that `stored` holds, those parts (the other ranks then have nothing to do for it).
struct RoundSplit {
  Ranks* ranks = nullptr;
  const StoredRounds* stored = nullptr;
};

// A round's blocks: those selected, else every block of `units` in blocks of `block_size`; a request with its
// blocks replaced (a rank's shard, or none of a stored round), or as it is (nullopt).
inline BlockRange round_blocks(const std::optional<BlockRange>& selected, std::uint64_t units, std::uint64_t block_size) {
  return selected ? *selected : BlockRange{0, BlockPlan{units, block_size}.blocks()};
}
template <class Request>
Request with_blocks(Request request, const std::optional<BlockRange>& blocks) {
  if (blocks) request.blocks = *blocks;
  return request;
}

// What split_round needs of the split: the stored parts of `task` (a merge of shard jobs), or null; the
// message that sends a task to the ranks; a check that the gathered parts are one per rank (else InternalError).
const std::vector<std::string>* stored_parts(const StoredRounds* stored, const RoundTask& task);
std::string task_message(const RoundTask& task);
void check_part_count(const std::vector<std::string>& parts, int ranks);

// The shape of every split round. Stored parts (a merge of shard jobs): `measure` of no block (the binnings and
// attributes) and every part combined from the first; alone: `measure` of the whole round (`Own` as the result,
// else combined with no part); with ranks: the task broadcast, rank 0's shard measured, every rank's part
// (`encode(own, its blocks)`) gathered and combined from the second (`combine(own, parts, first)`).
template <class Own, class Result = Own>
Result split_round(const RoundSplit& split, const RoundTask& task,
                   const std::type_identity_t<std::function<Own(const std::optional<BlockRange>&)>>& measure,
                   const std::type_identity_t<std::function<std::string(const Own&, const BlockRange&)>>& encode,
                   const std::type_identity_t<std::function<Result(Own, const std::vector<std::string>&, int)>>& combine) {
  if (const std::vector<std::string>* stored = stored_parts(split.stored, task))
    return combine(measure(BlockRange{task.blocks.begin, task.blocks.begin}), *stored, 0);
  if (split.ranks == nullptr || split.ranks->size() == 1) {
    if constexpr (std::is_same_v<Own, Result>) return measure(std::nullopt);
    else return combine(measure(std::nullopt), {}, 0);
  }
  split.ranks->broadcast(task_message(task));
  const BlockRange mine = rank_blocks(task.blocks, 0, split.ranks->size());
  Own own = measure(mine);
  const std::vector<std::string> parts = split.ranks->gather(encode(own, mine));
  check_part_count(parts, split.ranks->size());
  return combine(std::move(own), parts, 1);
}

// A tile's VNDF round (trace_heightfield_vndf on `scene()`, `field`'s; `label` names the tile: surface_label),
// split (measurement_vndf.cpp): the round's counts and diagnostics, not analysed (the caller analyses its sum).
// `measurement` is the decision's index in the plan the other ranks received (send_plan). `scene` gives
// `field`'s scene (SurfaceCache::scene_for); the root asks for it after sending the round, so that the ranks
// build theirs at the same time.
using SceneOf = std::function<const HeightfieldScene&()>;
HeightfieldVndf split_heightfield_vndf_round(const RoundSplit& split, std::size_t measurement, const SceneOf& scene,
                                             const microgeom::Heightfield& field, const std::string& label,
                                             const VndfRequest& request);
// A heightfield masking round (blocks `blocks` of h's run, every light), split: each rank measures its shard
// (the surface of `surface_seed`, the run's, from its own cache), the sums added in rank order: h's own
// measure_round, bit for bit. nullopt when any part was cancelled (the round is dropped, as in one process).
std::optional<std::vector<SurfaceMasking>> split_masking_round(const RoundSplit& split, std::size_t measurement,
                                                               const MaskingRuns& h, std::uint64_t surface_seed,
                                                               const BlockRange& blocks, const RunControl& run);
// validate_sampler of `validation` (its seed options.seed) over the ranks (split.ranks; alone without them).
// Throws Cancelled when any rank's part was cancelled (after every rank has answered), InsufficientData as
// validate_sampler.
ValidationReport split_validation(const RoundSplit& split, std::size_t measurement, const ValidationCase& validation,
                                  const ValidationOptions& options);

// Rank `rank`'s part of a round (`ranks` ranks) run in this process: its tallies, in the split's encoding. A
// heightfield's tile comes from `surfaces` (a build cancelled there: a part cancelled before its first block).
std::string run_part(const ExperimentSpec& spec, const ExperimentPlan& plan, const RoundTask& task, int rank, int ranks,
                     const RunControl& run, SurfaceCache& surfaces);

// The root starts the other ranks with the plan (and the spec's digest, which theirs must match), and stops
// them with the exit code they are to return (also before the plan: a run that stops early). No-ops alone.
void send_plan(Ranks& ranks, const ExperimentSpec& spec, const ExperimentPlan& plan);
void send_stop(Ranks& ranks, int exit_code);

// A rank other than the root: waits for the plan (or a stop), loads the spec (load_spec: called only when a
// plan came, so a bad spec is reported once, by the root), checks that it is the root's (digest), then runs
// its shard of every round the root sends until the root stops (tiles from `surfaces`: run_part); returns the
// exit code the root sent. Throws std::invalid_argument when the spec differs from the root's, InternalError on
// a malformed message.
int serve_rounds(Ranks& ranks, const std::function<ExperimentSpec()>& load_spec, const RunControl& run,
                 SurfaceCache& surfaces);

}  // namespace microsim::experiment
