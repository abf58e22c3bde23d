// experiment: a whole experiment split into the shards of a job array, without MPI:
//   microsim run SPEC --out PART_K --shard K/N      (K = 1..N, anywhere, in any order)
//   microsim run SPEC --out DIR --merge PART_1 ... PART_N
//
// A round's size follows from the previous round's combined estimate (the sequential stop), so only the first
// round of each measurement is known before any shard has run: its size is the plan's (the pilots draw from the
// seed, so every shard plans the same) and its seed and blocks are run_experiment's (first_split_rounds:
// Measurement::first_round of every measurement the ranks share). A shard job runs block shard K of N of those
// first rounds (run_part: Measurement::part, the exact tallies of parts.h; on an explicit heightfield each shard
// job builds the tile in memory) and writes them to PART (shard.json, part-I.bin); nothing else. The merge
// checks the shards (one spec, seed, plan and N, each K once) and hands their parts to run_experiment
// (RunOptions::stored), which combines each first round in shard order (the one-process round, bit for bit),
// decides the stop on it, and runs any further round and the measurements that are not shared (analytic tables
// and lobes, dumps, analytic masking) itself: the merged run is the one-process run, bit for bit. What shards
// cannot do: the later rounds (they depend on the combined first round) and the unshared measurements; run the
// merge under mpirun to split those rounds too.
#pragma once

#include "experiment/plan.h"
#include "experiment/split_rounds.h"
#include "experiment/spec.h"

#include <filesystem>
#include <string>
#include <vector>

namespace microsim::experiment {

// What one shard job ran and wrote.
struct ShardParts {
  std::uint64_t k = 1, n = 1;   // shard k of n (1-based)
  std::uint64_t seed = 0;       // the run's seed
  std::string spec_digest;
  nlohmann::json inputs;        // input_digests(spec) when it ran: the files its parts were measured from
  nlohmann::json plan;          // plan_json of the plan it ran
  std::vector<RoundTask> tasks; // first_split_rounds
  std::vector<std::string> parts;  // per task: shard k's part
};

// Shard k of n of the first rounds of `plan` at `seed` (an explicit heightfield's tile from `surfaces`: the
// plan's, or built). Throws Cancelled when cancelled (a shard keeps nothing: run it again).
ShardParts run_shard(const ExperimentSpec& spec, const ExperimentPlan& plan, std::uint64_t seed, std::uint64_t k,
                     std::uint64_t n, const RunControl& run, SurfaceCache& surfaces);

// PART: shard.json (spec name and digest, its input files' digests, seed, K/N, the version of its parts' form, plan,
// tasks, part files and their sizes) and part-I.bin, each written atomically, shard.json last. PART must be new or empty
// (std::invalid_argument: nothing written).
void write_shard_directory(const std::filesystem::path& dir, const ExperimentSpec& spec, const ShardParts& shard);
// Throws std::invalid_argument naming PART and the problem: no shard.json, parts of another version (another
// microsim's), another spec (digest) or seed, an input file changed since the shard ran (its digest against
// `inputs`, the merge's input_digests), a malformed member, a part file missing or of another size.
ShardParts read_shard_directory(const std::filesystem::path& dir, const ExperimentSpec& spec, std::uint64_t seed,
                                const nlohmann::json& inputs);

// The shards (named for messages) as one job's first rounds. Throws std::invalid_argument naming the problem:
// shards of different N, plans or tasks, a shard missing or given twice.
StoredRounds merge_shards(const std::vector<ShardParts>& shards, const std::vector<std::string>& names);

}  // namespace microsim::experiment
