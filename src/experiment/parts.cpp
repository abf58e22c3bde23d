// experiment: the parts of a split round (parts.h): JSON parts with provenance, exact sums added in block order.
#include "experiment/parts.h"

#include "core/errors.h"
#include "stats/part_json.h"
#include "validate/validation_part.h"

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

namespace {

// Adds counts of the same size element by element.
void add_counts(std::vector<std::uint64_t>& to, const json& from) {
  if (!from.is_array() || from.size() != to.size())
    throw std::invalid_argument(fmt::format("{} counts where the root has {}", from.size(), to.size()));
  for (std::size_t k = 0; k < to.size(); ++k) to[k] += from[k].get<std::uint64_t>();
}
}  // namespace

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

// ---- VNDF parts -------------------------------------------------------------------------------------------

namespace {
// The traced sums of a VNDF round: counts and the heightfield tracer's diagnostics (0 on the ellipsoid).
struct VndfSums {
  TraceResult trace;
  HeightfieldVndfDiagnostics diagnostics;
};

std::vector<std::uint64_t*> diagnostic_counts(HeightfieldVndfDiagnostics& d) {
  return {&d.backfacing, &d.edge_grazes, &d.leaked, &d.unresolved};
}
}  // namespace

std::string vndf_part(const RoundTask& task, const TraceResult& trace, const HeightfieldVndfDiagnostics& diagnostics) {
  HeightfieldVndfDiagnostics d = diagnostics;
  json diagnostic = json::array();
  for (const std::uint64_t* count : diagnostic_counts(d)) diagnostic.push_back(*count);
  return round_part(task, trace.blocks, trace.partial,
                    {{"rays", trace.rays}, {"hits", trace.hits}, {"counts", trace.counts},
                     {"unbinned", trace.unbinned}, {"diagnostics", diagnostic}});
}

namespace {
std::string joined_counts(const std::vector<std::uint64_t>& v) {
  std::string s;
  for (std::size_t k = 0; k < v.size(); ++k) {
    if (k > 0) s += ',';
    s += std::to_string(v[k]);
  }
  return s;
}

// The parts (from `first` on; the root's own is rank 0's) added to `own` in rank order: the one-process round's
// sums, timed `seconds`.
VndfSums combine_vndf_sums(VndfSums own, const std::vector<std::string>& parts, const RoundTask& task, int first,
                           double seconds) {
  TraceResult& t = own.trace;
  check_start(t.blocks, t.partial, task.blocks, first, int(parts.size()));
  const auto add = [&](const json& s, const BlockRange& blocks, int) {
    t.rays += s.at("rays").get<std::uint64_t>();
    t.hits += s.at("hits").get<std::uint64_t>();
    if (s.at("counts").size() != t.counts.size()) throw std::invalid_argument("its binnings differ from the root's");
    for (std::size_t b = 0; b < t.counts.size(); ++b) add_counts(t.counts[b], s["counts"][b]);
    add_counts(t.unbinned, s.at("unbinned"));
    const std::vector<std::uint64_t*> d = diagnostic_counts(own.diagnostics);
    if (s.at("diagnostics").size() != d.size()) throw std::invalid_argument("not the tracer's diagnostics");
    for (std::size_t k = 0; k < d.size(); ++k) *d[k] += s["diagnostics"][k].get<std::uint64_t>();
    t.blocks.end = blocks.end;
  };
  if (!t.partial && !add_parts(parts, task, first, add)) t.partial = true;
  t.seconds = seconds;
  return own;
}

// The root's histogram (binnings, run attributes) holding the combined sums: the counts, and the per-part
// attributes (blocks, unbinned, rate; a tile's diagnostics) those of the whole.
TracedHistogram combined_histogram(TracedHistogram h, const VndfSums& sums) {
  const TraceResult& t = sums.trace;
  h.counts = t.counts;
  h.rays = t.rays;
  h.hits = t.hits;
  h.partial = t.partial;
  h.attributes["blocks"] = fmt::format("{},{}", t.blocks.begin, t.blocks.end);
  h.attributes["unbinned"] = joined_counts(t.unbinned);
  h.attributes["rays_per_second"] = fmt::format("{:.17g}", t.rays_per_second());
  if (h.attributes.count("backfacing")) {
    const HeightfieldVndfDiagnostics& d = sums.diagnostics;
    h.attributes["backfacing"] = std::to_string(d.backfacing);
    h.attributes["edge_grazes"] = std::to_string(d.edge_grazes);
    h.attributes["leaked"] = std::to_string(d.leaked);
    h.attributes["unresolved"] = std::to_string(d.unresolved);
  }
  return h;
}
}  // namespace

EllipsoidVndf combine_vndf_parts(EllipsoidVndf own, const std::vector<std::string>& parts, const RoundTask& task,
                                 int first, double seconds) {
  VndfSums sums = combine_vndf_sums({std::move(own.trace), {}}, parts, task, first, seconds);
  EllipsoidVndf combined = analyse_ellipsoid_vndf(combined_histogram(std::move(own.histogram), sums), sums.trace.unbinned);
  combined.trace = std::move(sums.trace);
  combined.expected_hit_fraction = own.expected_hit_fraction;
  return combined;
}

HeightfieldVndf combine_vndf_parts(HeightfieldVndf own, const std::vector<std::string>& parts,
                                   const RoundTask& task, int first, double seconds) {
  VndfSums sums = combine_vndf_sums({std::move(own.trace), own.diagnostics}, parts, task, first, seconds);
  HeightfieldVndf combined;
  combined.histogram = combined_histogram(std::move(own.histogram), sums);
  combined.trace = std::move(sums.trace);
  combined.diagnostics = sums.diagnostics;
  return combined;
}

// ---- scattering parts -------------------------------------------------------------------------------------

// Every exact sum of the histogram (stats/part_json.h scatter_sums_json).
std::string scatter_part(const RoundTask& task, const ScatterHistogram& h) {
  return round_part(task, h.provenance.blocks, h.partial, scatter_sums_json(h));
}

// The parts (from `first` on, as combine_vndf_parts) added to `own` in rank order: the one-process round.
ScatterHistogram combine_scatter_parts(ScatterHistogram own, const std::vector<std::string>& parts,
                                       const RoundTask& task, int first) {
  check_start(own.provenance.blocks, own.partial, task.blocks, first, int(parts.size()));
  const auto add = [&](const json& s, const BlockRange& blocks, int) {
    add_scatter_sums(own, s, PartReader("scattering part"), "sums");
    own.provenance.blocks.end = blocks.end;
  };
  if (!own.partial && !add_parts(parts, task, first, add)) own.partial = true;
  return own;
}

// ---- walk albedo parts (a shard of a table's cells) -----------------------------------------------------------

// Per cell, its estimates [value, standard error] as their bits (exact_real_json).
std::string albedo_part(const RoundTask& task, const BlockRange& cells, const std::optional<AlbedoCells>& estimates) {
  if (!estimates) return cancelled_part(task, cells);
  json out = json::array();
  for (const std::vector<Estimate>& cell : *estimates) {
    json values = json::array();
    for (const Estimate& e : cell) values.push_back({exact_real_json(e.value), exact_real_json(e.standard_error)});
    out.push_back(values);
  }
  return round_part(task, cells, false, out);
}

// A round cut short: no row (it is run again whole on resumption).
AlbedoTable cancelled_albedo_table(const AlbedoTableRequest& request) {
  AlbedoTable cancelled;
  cancelled.request = request;
  cancelled.partial = true;
  return cancelled;
}

// The parts from `first` on, in rank order, after `cells` (rank 0's, or none): the whole table, or a partial
// one (no row) when a part was cancelled.
AlbedoTable combine_albedo_parts(const AlbedoTableRequest& request, AlbedoCells cells,
                                 const std::vector<std::string>& parts, const RoundTask& task, int first,
                                 double seconds) {
  const PartReader reader("albedo part");
  const bool complete = add_parts(parts, task, first, [&](const json& s, const BlockRange& blocks, int) {
    if (s.size() != blocks.size()) throw std::invalid_argument("not one estimate list per cell");
    for (const json& values : s) {
      std::vector<Estimate>& cell = cells.emplace_back();
      for (const json& e : values) cell.push_back({reader.exact_real(e.at(0), "cell"), reader.exact_real(e.at(1), "cell")});
    }
  });
  return complete ? albedo_table_from_cells(request, cells, seconds) : cancelled_albedo_table(request);
}

// ---- validation parts (a drawn validation's tally) ---------------------------------------------------------

std::string validation_part(const RoundTask& task, const BlockRange& blocks, const std::optional<battery::Tally>& tally) {
  return tally ? round_part(task, blocks, false, tally_json(*tally)) : cancelled_part(task, blocks);
}

// This rank's tally of its blocks of a validation, or nullopt when cancelled.
std::optional<battery::Tally> own_tally(const SamplerInfo& sampler, const ReferenceDistribution& reference,
                                        ValidationOptions options, const BlockRange& blocks) {
  options.blocks = blocks;
  try {
    return tally_drawn_samples(sampler, reference, options);
  } catch (const Cancelled&) {
    return std::nullopt;
  }
}

std::vector<std::size_t> tally_cells(const battery::Tally& tally) {
  std::vector<std::size_t> cells;
  for (const auto& counts : tally.counts) cells.push_back(counts.size());
  return cells;
}

// The tallies in rank order as one (merge_tallies): `own` (rank 0's; none for the parts of shard jobs, whose
// first part is then rank 0's) and the parts after it. Cancelled when any part was cancelled.
battery::Tally merged_validation_tally(const std::optional<battery::Tally>& own, const std::vector<std::size_t>& cells,
                                       const std::vector<std::string>& parts, const RoundTask& task, int first) {
  std::vector<battery::Tally> tallies;
  if (first == 1) {
    if (!own) throw Cancelled("validation");
    tallies.push_back(*own);
  }
  const bool complete = add_parts(parts, task, first, [&](const json& s, const BlockRange& blocks, int rank) {
    tallies.push_back(tally_from_json(s, cells, blocks.size(), PartReader("validation part"), fmt::format("rank {}", rank)));
  });
  if (!complete) throw Cancelled("validation");
  std::vector<const battery::Tally*> in_order;
  for (const battery::Tally& t : tallies) in_order.push_back(&t);
  return merge_tallies(in_order);
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
      const MaskingPart light = read_masking_part(s[k]);
      (*own)[k].result.sums += light.sums;
      (*own)[k].result.rays += light.sums.rays;
      (*own)[k].provenance.blocks.end = blocks.end;
    }
  });
  return complete ? own : std::nullopt;
}

}  // namespace microsim::experiment
