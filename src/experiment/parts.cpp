// experiment: the parts of a split round (parts.h): JSON parts with provenance, exact sums added in block order.
#include "experiment/parts.h"

#include "core/errors.h"
#include "stats/part_json.h"

#include <fmt/core.h>

#include <stdexcept>

namespace microsim::experiment {
namespace {

using nlohmann::json;

constexpr const char* kProducer = "microsim run";

// What defines a round besides its seed and blocks (a part's provenance parameters).
json round_parameters(const RoundTask& task) {
  return {{"measurement", task.measurement}, {"units", task.units}, {"surface_seed", task.surface_seed}};
}

}  // namespace

std::string round_part(const RoundTask& task, const BlockRange& blocks, bool partial, json sums) {
  const Provenance provenance{kProducer, "", task.seed, task.blocks.end, blocks};
  json part{{"provenance", provenance_json(provenance, round_parameters(task))}, {"partial", partial}};
  if (!sums.is_null()) part["sums"] = std::move(sums);
  return part.dump();
}

namespace {

[[noreturn]] void malformed(int rank, const std::string& what) {
  throw InternalError(fmt::format("the part of rank {} of a split round is malformed: {}", rank, what));
}

// Checks that a part's blocks are rank r's shard of the round (a prefix of it when cancelled part way).
void check_shard(const BlockRange& got, bool partial, const BlockRange& round, int rank, int ranks) {
  const BlockRange want = rank_blocks(round, rank, ranks);
  if (got.begin != want.begin || got.end > want.end || got.end < got.begin || (!partial && got.end != want.end))
    throw InternalError(fmt::format("the part of rank {} of a split round holds blocks {} where rank {} of {} runs {} "
                                    "(parts out of block order, missing or overlapping)",
                                    rank, got.to_string(), rank, ranks, want.to_string()));
}

struct Part {
  BlockRange blocks;
  bool partial = false;
  json sums;  // null: cancelled before measuring anything
};

// Rank r's part of `task`: its provenance the round's parameters and total blocks, its blocks rank r's shard
// (check_shard), its seed the round's: a part of another seed's round is malformed, never added.
Part read_part(const std::string& text, const RoundTask& task, int rank, int ranks) {
  Part part;
  try {
    const json j = json::parse(text);
    const PartReader reader(kProducer);
    json parameters;
    const Provenance p = reader.provenance(j, parameters);
    if (p.total_blocks != task.blocks.end || parameters != round_parameters(task))
      malformed(rank, fmt::format("a part of another round ({}, blocks to {})", parameters.dump(), p.total_blocks));
    if (p.seed != task.seed)
      malformed(rank, fmt::format("a part of seed {}, not the round's {}", p.seed, task.seed));
    part = {p.blocks, reader.flag(j, "partial", ""), j.value("sums", json())};
  } catch (const json::exception& e) {
    malformed(rank, e.what());
  } catch (const HistogramMergeError& e) {
    malformed(rank, e.what());
  }
  check_shard(part.blocks, part.partial, task.blocks, rank, ranks);
  return part;
}

}  // namespace

bool add_parts(const std::vector<std::string>& parts, const RoundTask& task, int first, const AddPart& add) {
  const int ranks = int(parts.size());  // checked: one part per rank
  for (int r = first; r < ranks; ++r) {
    const Part part = read_part(parts[std::size_t(r)], task, r, ranks);
    try {
      if (!part.sums.is_null()) add(part.sums, part.blocks, r);
    } catch (const json::exception& e) {
      malformed(r, e.what());
    } catch (const HistogramMergeError& e) {
      malformed(r, e.what());
    } catch (const std::invalid_argument& e) {
      malformed(r, e.what());
    }
    if (part.partial) return false;
  }
  return true;
}

void check_start(const BlockRange& own, bool partial, const BlockRange& round, int first, int ranks) {
  if (first == 1) return check_shard(own, partial, round, 0, ranks);
  if (own != BlockRange{round.begin, round.begin} || partial)
    throw InternalError(fmt::format("a round's start holds blocks {}", own.to_string()));
}

BlockRange rank_blocks(const BlockRange& round, int rank, int ranks) {
  const BlockRange shard = shard_range(round.size(), std::uint64_t(rank) + 1, std::uint64_t(ranks));
  return {round.begin + shard.begin, round.begin + shard.end};
}

bool part_is_partial(const std::string& part) {
  try {
    return json::parse(part).at("partial").get<bool>();
  } catch (const json::exception& e) {
    malformed(0, e.what());
  }
}

void check_whole_part(const std::string& part, const RoundTask& task, int rank, int ranks) {
  if (read_part(part, task, rank, ranks).partial) malformed(rank, "cancelled part way");
}

std::string cancelled_part(const RoundTask& task, const BlockRange& mine) {
  return round_part(task, BlockRange{mine.begin, mine.begin}, true, nullptr);
}

json round_task_json(const RoundTask& task) {
  json j{{"measurement", task.measurement}, {"units", task.units}, {"seed", task.seed},
         {"blocks", {task.blocks.begin, task.blocks.end}}};
  if (task.surface_seed != 0) j["surface_seed"] = task.surface_seed;
  return j;
}

RoundTask round_task_from_json(const json& task) {
  return {task.at("measurement").get<std::size_t>(), task.at("units").get<std::uint64_t>(),
          task.at("seed").get<std::uint64_t>(),
          BlockRange{task.at("blocks").at(0).get<std::uint64_t>(), task.at("blocks").at(1).get<std::uint64_t>()},
          task.value("surface_seed", std::uint64_t(0))};
}

// ---- validation parts (a drawn validation's tally, in validate's part form) ----------------------------------

ValidationRun drawn_validation_run(const ValidationCase& validation, const ValidationOptions& options) {
  ValidationRun run;
  run.cases = {validation};
  run.options = options;
  run.seed = validation.seed;
  run.family_significance = options.significance;
  return run;
}

std::optional<ValidationPart> own_validation_part(const ValidationRun& run, const BlockRange& blocks) {
  try {
    return sample_validation_part(run, blocks, nullptr);
  } catch (const Cancelled&) {
    return std::nullopt;
  }
}

std::string validation_round_part(const RoundTask& task, const BlockRange& blocks, const std::optional<ValidationPart>& part) {
  return part ? round_part(task, blocks, false, validation_part_json(*part)) : cancelled_part(task, blocks);
}

// The tallies in rank order as one (merge_tallies): `own` (rank 0's; none for the parts of shard jobs, whose
// first part is then rank 0's) and the parts after it. Cancelled when any part was cancelled.
battery::Tally merged_validation_tally(const std::optional<ValidationPart>& own, const std::vector<std::string>& parts,
                                       const RoundTask& task, int first) {
  std::vector<ValidationPart> in_order;
  if (first == 1) {
    if (!own) throw Cancelled("validation");
    in_order.push_back(*own);
  }
  const bool complete = add_parts(parts, task, first, [&](const json& s, const BlockRange& blocks, int) {
    in_order.push_back(read_validation_part(s));
    if (in_order.back().provenance.blocks != blocks || in_order.back().tallies.size() != 1)
      throw std::invalid_argument("not one validation's tally of its blocks");
  });
  if (!complete) throw Cancelled("validation");
  std::vector<const battery::Tally*> tallies;
  for (const ValidationPart& p : in_order) tallies.push_back(&p.tallies.front());
  return merge_tallies(tallies);
}

// ---- heightfield masking parts (every light's exact sums of a shard of the round's blocks) ---------------------

std::string masking_round_part(const RoundTask& task, const BlockRange& blocks,
                               const std::optional<std::vector<SurfaceMasking>>& round) {
  if (!round) return cancelled_part(task, blocks);
  json lights = json::array();
  for (const SurfaceMasking& light : *round) lights.push_back(masking_part_json(light));
  return round_part(task, blocks, false, lights);
}

// The parts from `first` on added to `own` (rank 0's, or the stored round's start) in rank order; nullopt when
// any part was cancelled.
std::optional<std::vector<SurfaceMasking>> combine_masking_parts(std::optional<std::vector<SurfaceMasking>> own,
                                                                 const std::vector<std::string>& parts,
                                                                 const RoundTask& task, int first) {
  if (!own) return std::nullopt;
  const bool complete = add_parts(parts, task, first, [&](const json& s, const BlockRange& blocks, int) {
    if (!s.is_array() || s.size() != own->size()) throw std::invalid_argument("not one part per light");
    for (std::size_t k = 0; k < own->size(); ++k) {
      add_masking_part((*own)[k], read_masking_part(s[k]));
      (*own)[k].provenance.blocks.end = blocks.end;
    }
  });
  return complete ? own : std::nullopt;
}

}  // namespace microsim::experiment
