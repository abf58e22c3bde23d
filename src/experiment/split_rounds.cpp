// experiment: the rounds of run_experiment split over ranks (split_rounds.h).
#include "experiment/split_rounds.h"
#include "experiment/surface_albedo.h"
#include "core/wall_clock.h"

#include "core/errors.h"
#include "experiment/heightfield_measures.h"
#include "experiment/masking_runs.h"
#include "experiment/masking_surface.h"
#include "experiment/measures.h"
#include "experiment/run.h"
#include "core/run_control.h"
#include "scatter/surface_scatter.h"
#include "stats/part_json.h"
#include "validate/validation_part.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <bit>
#include <chrono>
#include <cstring>
#include <optional>
#include <stdexcept>

namespace microsim::experiment {
namespace {

// ---- a part as words (exact integers: counts, and ExactSum's two halves) -------------------------------------

using Words = std::vector<std::uint64_t>;

std::string words_to_bytes(const Words& words) {
  std::string bytes(words.size() * sizeof(std::uint64_t), '\0');
  if (!words.empty()) std::memcpy(bytes.data(), words.data(), bytes.size());
  return bytes;
}

// Reads a part's words in order; a part shorter or longer than its header says is a bug (InternalError).
class PartReader {
public:
  PartReader(const std::string& bytes, int rank) : rank_(rank) {
    if (bytes.size() % sizeof(std::uint64_t) != 0) fail("not whole words");
    words_.resize(bytes.size() / sizeof(std::uint64_t));
    if (!words_.empty()) std::memcpy(words_.data(), bytes.data(), bytes.size());
  }
  std::uint64_t next() {
    if (at_ >= words_.size()) fail("truncated");
    return words_[at_++];
  }
  ExactSum next_sum() {
    const std::uint64_t high = next();
    return ExactSum::from_bits(high, next());
  }
  void expect(std::uint64_t value, const char* what) {
    if (next() != value) fail(fmt::format("its {} differ from the root's", what));
  }
  void finish() {
    if (at_ != words_.size()) fail("longer than its content");
  }
  bool at_end() const { return at_ == words_.size(); }
  // The next `length` bytes as text, read in whole words (the padding after them skipped), then the end.
  std::string next_text(std::uint64_t length) {
    const std::uint64_t words = (length + sizeof(std::uint64_t) - 1) / sizeof(std::uint64_t);
    if (words > words_.size() - at_) fail("truncated");
    std::string text(reinterpret_cast<const char*>(words_.data() + at_), length);
    at_ += words;
    finish();
    return text;
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw InternalError(fmt::format("the part of rank {} of a split round is malformed: {}", rank_, what));
  }

private:
  Words words_;
  std::size_t at_ = 0;
  int rank_ = 0;
};

void put_sum(Words& w, const ExactSum& s) {
  w.push_back(s.high_bits());
  w.push_back(s.low_bits());
}

// The header of every part: its blocks and whether it was cancelled part way.
void put_header(Words& w, const BlockRange& blocks, bool partial) {
  // push_back, not insert of a list: GCC 12 at -O3 warns (-Wstringop-overflow) on a list inserted into the
  // empty vector of a text part, a false alarm.
  w.push_back(blocks.begin);
  w.push_back(blocks.end);
  w.push_back(std::uint64_t(partial));
}

// Checks that a part's blocks are rank r's shard of the round (a prefix of it when cancelled part way).
void check_shard(const BlockRange& got, bool partial, const BlockRange& round, int rank, int ranks) {
  const BlockRange want = rank_blocks(round, rank, ranks);
  if (got.begin != want.begin || got.end > want.end || got.end < got.begin || (!partial && got.end != want.end))
    throw InternalError(fmt::format("the part of rank {} of a split round holds blocks {} where rank {} of {} runs {} "
                                    "(parts out of block order, missing or overlapping)",
                                    rank, got.to_string(), rank, ranks, want.to_string()));
}

// Reads a part's header (its blocks, checked: check_shard) and whether it was cancelled part way.
BlockRange read_header(PartReader& in, const BlockRange& round, int rank, int ranks, bool& partial) {
  const BlockRange got{in.next(), in.next()};
  partial = in.next() != 0;
  check_shard(got, partial, round, rank, ranks);
  return got;
}

// ---- VNDF parts -------------------------------------------------------------------------------------------

// The traced sums of a VNDF round: counts and the heightfield tracer's diagnostics (0 on the ellipsoid).
struct VndfSums {
  TraceResult trace;
  HeightfieldVndfDiagnostics diagnostics;
};

std::string vndf_part(const VndfSums& m) {
  Words w;
  put_header(w, m.trace.blocks, m.trace.partial);
  w.insert(w.end(), {m.trace.rays, m.trace.hits, m.trace.counts.size()});
  for (const auto& counts : m.trace.counts) {
    w.push_back(counts.size());
    w.insert(w.end(), counts.begin(), counts.end());
  }
  w.push_back(m.trace.unbinned.size());
  w.insert(w.end(), m.trace.unbinned.begin(), m.trace.unbinned.end());
  const HeightfieldVndfDiagnostics& d = m.diagnostics;
  w.insert(w.end(), {d.backfacing, d.edge_grazes, d.leaked, d.unresolved});
  return words_to_bytes(w);
}

// A part cancelled before its first block with nothing measured (a tile's build cancelled on that rank).
std::string cancelled_part(const BlockRange& mine) {
  Words w;
  put_header(w, BlockRange{mine.begin, mine.begin}, true);
  return words_to_bytes(w);
}

// Whether a part is cancelled_part's (read past its header): nothing to add.
bool holds_nothing(const PartReader& in, const BlockRange& blocks, bool partial) {
  return partial && blocks.size() == 0 && in.at_end();
}

// Adds rank r's part to the sums of the ranks before it (whose blocks end where this part begins).
void add_vndf_part(VndfSums& sums, const std::string& bytes, const BlockRange& round, int rank, int ranks) {
  PartReader in(bytes, rank);
  bool partial = false;
  const BlockRange blocks = read_header(in, round, rank, ranks, partial);
  TraceResult& t = sums.trace;
  t.partial = partial;
  if (holds_nothing(in, blocks, partial)) return;
  t.rays += in.next();
  t.hits += in.next();
  in.expect(t.counts.size(), "binnings");
  for (auto& counts : t.counts) {
    in.expect(counts.size(), "bins");
    for (std::uint64_t& c : counts) c += in.next();
  }
  in.expect(t.unbinned.size(), "binnings");
  for (std::uint64_t& u : t.unbinned) u += in.next();
  HeightfieldVndfDiagnostics& d = sums.diagnostics;
  for (std::uint64_t* count : {&d.backfacing, &d.edge_grazes, &d.leaked, &d.unresolved}) *count += in.next();
  in.finish();
  t.blocks.end = blocks.end;
}

std::string joined_counts(const std::vector<std::uint64_t>& v) {
  std::string s;
  for (std::size_t k = 0; k < v.size(); ++k) {
    if (k > 0) s += ',';
    s += std::to_string(v[k]);
  }
  return s;
}

// Checks the measurement the parts are added to: the root's own part (first = 1: rank 0's shard), or nothing
// yet (first = 0, the parts of shard jobs: no block at all, at the round's start).
void check_start(const BlockRange& own, bool partial, const BlockRange& round, int first, int ranks) {
  if (first == 1) return check_shard(own, partial, round, 0, ranks);
  if (own != BlockRange{round.begin, round.begin} || partial)
    throw InternalError(fmt::format("a round's start holds blocks {}", own.to_string()));
}

// The parts (from `first` on; the root's own is rank 0's) added to `own` in rank order: the one-process round's
// sums, timed `seconds`.
VndfSums combine_vndf_sums(VndfSums own, const std::vector<std::string>& parts, const BlockRange& round, int first,
                           double seconds) {
  const int ranks = int(parts.size());  // checked: one part per rank
  check_start(own.trace.blocks, own.trace.partial, round, first, ranks);
  for (int r = first; r < ranks && !own.trace.partial; ++r) add_vndf_part(own, parts[std::size_t(r)], round, r, ranks);
  own.trace.seconds = seconds;
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

EllipsoidVndf combine_vndf_parts(EllipsoidVndf own, const std::vector<std::string>& parts, const BlockRange& round,
                                 int first, double seconds) {
  VndfSums sums = combine_vndf_sums({std::move(own.trace), {}}, parts, round, first, seconds);
  EllipsoidVndf combined = analyse_ellipsoid_vndf(combined_histogram(std::move(own.histogram), sums), sums.trace.unbinned);
  combined.trace = std::move(sums.trace);
  combined.expected_hit_fraction = own.expected_hit_fraction;
  return combined;
}

HeightfieldVndf combine_heightfield_parts(HeightfieldVndf own, const std::vector<std::string>& parts,
                                          const BlockRange& round, int first, double seconds) {
  VndfSums sums = combine_vndf_sums({std::move(own.trace), own.diagnostics}, parts, round, first, seconds);
  HeightfieldVndf combined;
  combined.histogram = combined_histogram(std::move(own.histogram), sums);
  combined.trace = std::move(sums.trace);
  combined.diagnostics = sums.diagnostics;
  return combined;
}

// ---- scattering parts -------------------------------------------------------------------------------------

// Every exact sum of a scattering histogram, in one order (that of run.cpp's add_scatter_round).
std::string scatter_part(const ScatterHistogram& h) {
  Words w;
  put_header(w, h.provenance.blocks, h.partial);
  w.insert(w.end(), {h.paths(), std::uint64_t(h.channels()), h.bins()});
  for (int c = 0; c < h.channels(); ++c) {
    for (int k = 0; k < kScatterOrderBins; ++k) {
      const Histogram& lobe = h.histogram(c, k);
      for (std::size_t b = 0; b < lobe.size(); ++b) {
        put_sum(w, lobe.exact_weight(b));
        put_sum(w, lobe.exact_weight_squared(b));
      }
      put_sum(w, lobe.exact_unbinned_weight());
      put_sum(w, lobe.exact_unbinned_weight_squared());
    }
    for (bool squared : {false, true}) put_sum(w, h.exact_unfinished(c, squared));
    for (bool squared : {false, true}) put_sum(w, h.exact_lost(c, squared));
  }
  return words_to_bytes(w);
}

void add_scatter_part(ScatterHistogram& sum, const std::string& bytes, const BlockRange& round, int rank, int ranks) {
  PartReader in(bytes, rank);
  bool partial = false;
  const BlockRange blocks = read_header(in, round, rank, ranks, partial);
  sum.partial = partial;
  if (holds_nothing(in, blocks, partial)) return;
  const std::uint64_t paths = in.next();
  in.expect(std::uint64_t(sum.channels()), "channels");
  in.expect(sum.bins(), "bins");
  for (int c = 0; c < sum.channels(); ++c) {
    for (int k = 0; k < kScatterOrderBins; ++k) {
      for (std::size_t b = 0; b < sum.bins(); ++b) {
        const ExactSum w = in.next_sum();
        sum.add_sums(c, k, b, w, in.next_sum());
      }
      const ExactSum w = in.next_sum();
      sum.add_unbinned_sums(c, k, w, in.next_sum());
    }
    const ExactSum unfinished = in.next_sum();
    sum.add_unfinished_sums(c, unfinished, in.next_sum());
    const ExactSum lost = in.next_sum();
    sum.add_lost_sums(c, lost, in.next_sum());
  }
  in.finish();
  sum.add_launched(paths);
  sum.provenance.blocks.end = blocks.end;
}

// The parts (from `first` on, as combine_vndf_parts) added to `own` in rank order: the one-process round.
ScatterHistogram combine_scatter_parts(ScatterHistogram own, const std::vector<std::string>& parts, const BlockRange& round,
                                       int first) {
  const int ranks = int(parts.size());
  check_start(own.provenance.blocks, own.partial, round, first, ranks);
  for (int r = first; r < ranks && !own.partial; ++r) add_scatter_part(own, parts[std::size_t(r)], round, r, ranks);
  return own;
}

// ---- walk albedo parts (a shard of a table's cells) -----------------------------------------------------------

// The cells' estimates as their bits (nullopt: cancelled, no cell).
std::string albedo_part(const BlockRange& cells, const std::optional<AlbedoCells>& estimates) {
  Words w;
  put_header(w, cells, !estimates);
  if (estimates)
    for (const std::vector<Estimate>& cell : *estimates) {
      w.push_back(cell.size());
      for (const Estimate& e : cell) w.insert(w.end(), {std::bit_cast<std::uint64_t>(e.value), std::bit_cast<std::uint64_t>(e.standard_error)});
    }
  return words_to_bytes(w);
}

// Rank r's cells appended to `cells` (its header checked: read_header); false when it was cancelled.
bool add_albedo_part(AlbedoCells& cells, const std::string& bytes, const BlockRange& round, int rank, int ranks) {
  PartReader in(bytes, rank);
  bool partial = false;
  const BlockRange got = read_header(in, round, rank, ranks, partial);
  if (partial) return false;
  for (std::uint64_t c = got.begin; c < got.end; ++c) {
    std::vector<Estimate> cell(in.next());
    for (Estimate& e : cell) {
      e.value = std::bit_cast<double>(in.next());
      e.standard_error = std::bit_cast<double>(in.next());
    }
    cells.push_back(std::move(cell));
  }
  in.finish();
  return true;
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
AlbedoTable combine_albedo_parts(const AlbedoTableRequest& request, AlbedoCells cells, const std::vector<std::string>& parts,
                                 const BlockRange& round, int first, double seconds) {
  bool complete = true;
  for (int r = first; r < int(parts.size()) && complete; ++r)
    complete = add_albedo_part(cells, parts[std::size_t(r)], round, r, int(parts.size()));
  return complete ? albedo_table_from_cells(request, cells, seconds) : cancelled_albedo_table(request);
}

// ---- validation parts (a drawn validation's tally) ---------------------------------------------------------

// A part whose content is text (a JSON document): the header of every part (part_is_partial and
// check_whole_part read it), then the text's length and its bytes padded to whole words; a cancelled one
// (nullopt) is cancelled_part's.
std::string text_part(const BlockRange& blocks, const std::optional<std::string>& text) {
  if (!text) return cancelled_part(blocks);
  Words w;
  put_header(w, blocks, false);
  w.push_back(text->size());
  std::string bytes = words_to_bytes(w) + *text;
  bytes.resize((bytes.size() + sizeof(std::uint64_t) - 1) / sizeof(std::uint64_t) * sizeof(std::uint64_t), ' ');
  return bytes;
}

// Rank r's text part: its blocks (checked: read_header) and its JSON, or nullopt when it was cancelled.
std::optional<std::pair<BlockRange, nlohmann::json>> read_text_part(const std::string& bytes, const BlockRange& round,
                                                                    int rank, int ranks) {
  PartReader in(bytes, rank);
  bool partial = false;
  const BlockRange blocks = read_header(in, round, rank, ranks, partial);
  if (partial) return std::nullopt;
  const std::string text = in.next_text(in.next());
  try {
    return std::pair{blocks, nlohmann::json::parse(text)};
  } catch (const nlohmann::json::exception& e) {
    in.fail(e.what());
  }
}

// A rank's tally of its blocks (tally_json), or a cancelled part.
std::string validation_part(const BlockRange& blocks, const std::optional<battery::Tally>& tally) {
  return text_part(blocks, tally ? std::optional<std::string>(tally_json(*tally).dump()) : std::nullopt);
}

// Rank r's tally (its blocks checked), or nullopt when it was cancelled.
std::optional<battery::Tally> read_validation_part(const std::string& bytes, const std::vector<std::size_t>& cells,
                                                   const BlockRange& round, int rank, int ranks) {
  const auto part = read_text_part(bytes, round, rank, ranks);
  if (!part) return std::nullopt;
  try {
    return tally_from_json(part->second, cells, part->first.size(), microsim::PartReader("validation part"),
                           fmt::format("rank {}", rank));
  } catch (const nlohmann::json::exception& e) {
    throw InternalError(fmt::format("the part of rank {} of a split validation is malformed: {}", rank, e.what()));
  } catch (const HistogramMergeError& e) {
    throw InternalError(fmt::format("the part of rank {} of a split validation is malformed: {}", rank, e.what()));
  }
}

// ---- heightfield masking parts (every light's exact sums of a shard of the round's blocks) ---------------------

std::string masking_round_part(const BlockRange& blocks, const std::optional<std::vector<SurfaceMasking>>& round) {
  if (!round) return text_part(blocks, std::nullopt);
  nlohmann::json lights = nlohmann::json::array();
  for (const SurfaceMasking& light : *round) lights.push_back(masking_part_json(light));
  return text_part(blocks, lights.dump());
}

// Rank r's sums added to `sum` (the ranks' before it, per light); false when it was cancelled.
bool add_masking_part(std::vector<SurfaceMasking>& sum, const std::string& bytes, const BlockRange& round, int rank,
                      int ranks) {
  const auto part = read_text_part(bytes, round, rank, ranks);
  if (!part) return false;
  try {
    if (!part->second.is_array() || part->second.size() != sum.size()) throw std::invalid_argument("not one part per light");
    for (std::size_t k = 0; k < sum.size(); ++k) {
      const MaskingPart light = read_masking_part(part->second[k]);
      sum[k].result.sums += light.sums;
      sum[k].result.rays += light.sums.rays;
      sum[k].provenance.blocks.end = part->first.end;
    }
  } catch (const std::exception& e) {  // a malformed part, or sums of other bins
    throw InternalError(fmt::format("the part of rank {} of a split masking round is malformed: {}", rank, e.what()));
  }
  return true;
}

// The parts from `first` on added to `own` (rank 0's, or the stored round's start) in rank order; nullopt when
// any part was cancelled.
std::optional<std::vector<SurfaceMasking>> combine_masking_parts(std::optional<std::vector<SurfaceMasking>> own,
                                                                 const std::vector<std::string>& parts,
                                                                 const BlockRange& round, int first) {
  if (!own) return std::nullopt;
  for (int r = first; r < int(parts.size()); ++r)
    if (!add_masking_part(*own, parts[std::size_t(r)], round, r, int(parts.size()))) return std::nullopt;
  return own;
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
                                       const std::vector<std::string>& parts, const BlockRange& round, int first) {
  std::vector<battery::Tally> tallies;
  if (first == 1) {
    if (!own) throw Cancelled("validation");
    tallies.push_back(*own);
  }
  const int ranks = int(parts.size());
  for (int r = first; r < ranks; ++r) {
    std::optional<battery::Tally> t = read_validation_part(parts[std::size_t(r)], cells, round, r, ranks);
    if (!t) throw Cancelled("validation");
    tallies.push_back(std::move(*t));
  }
  std::vector<const battery::Tally*> in_order;
  for (const battery::Tally& t : tallies) in_order.push_back(&t);
  return merge_tallies(in_order);
}

// ---- messages ---------------------------------------------------------------------------------------------

std::string stop_message(int exit_code) { return nlohmann::json{{"stop", exit_code}}.dump(); }

std::string task_message(const RoundTask& task) { return nlohmann::json{{"round", round_task_json(task)}}.dump(); }

// The stored parts of this round (a merge of shard jobs), or null.
const std::vector<std::string>* stored_parts(const StoredRounds* stored, const RoundTask& task) {
  if (stored == nullptr) return nullptr;
  for (std::size_t t = 0; t < stored->tasks.size(); ++t)
    if (stored->tasks[t] == task) return &stored->parts[t];
  return nullptr;
}

nlohmann::json parse_message(const std::string& text) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw InternalError(fmt::format("a message from the root is not JSON: {}", e.what()));
  }
}

BlockRange round_blocks(const std::optional<BlockRange>& selected, std::uint64_t units, std::uint64_t block_size) {
  return selected ? *selected : BlockRange{0, units / block_size + (units % block_size != 0)};
}

// The gathered parts, one per rank (else a bug: InternalError).
void check_part_count(const std::vector<std::string>& parts, int ranks) {
  if (parts.size() != std::size_t(ranks))
    throw InternalError(fmt::format("a split round gathered {} parts from {} ranks", parts.size(), ranks));
}

// A request with its blocks replaced (a rank's shard, or none of a stored round), or as it is (nullopt).
template <class Request>
Request with_blocks(Request request, const std::optional<BlockRange>& blocks) {
  if (blocks) request.blocks = *blocks;
  return request;
}

// The shape of every split VNDF and scattering round. Stored parts (a merge of shard jobs): `measure` of no
// block (the binnings and attributes) and every part combined from the first; alone: `measure` of the whole
// round; with ranks: the task broadcast, rank 0's shard measured, every rank's part gathered and combined from
// the second (`combine(own, parts, first)`).
template <class Result>
Result split_round(const RoundSplit& split, const RoundTask& task,
                   const std::function<Result(const std::optional<BlockRange>&)>& measure,
                   const std::function<std::string(const Result&)>& encode,
                   const std::function<Result(Result, const std::vector<std::string>&, int)>& combine) {
  if (const std::vector<std::string>* stored = stored_parts(split.stored, task))
    return combine(measure(BlockRange{task.blocks.begin, task.blocks.begin}), *stored, 0);
  if (split.ranks == nullptr || split.ranks->size() == 1) return measure(std::nullopt);
  split.ranks->broadcast(task_message(task));
  Result own = measure(rank_blocks(task.blocks, 0, split.ranks->size()));
  const std::vector<std::string> parts = split.ranks->gather(encode(own));
  check_part_count(parts, split.ranks->size());
  return combine(std::move(own), parts, 1);
}

}  // namespace

bool is_split(const ExperimentSpec& spec, const Decision& decision) {
  const QuantityKind kind = spec.quantities[decision.quantity].kind;
  const Model model = decision.model.model;
  return (kind == QuantityKind::vndf && model == Model::ellipsoid_oracle) ||
         ((kind == QuantityKind::scattering || kind == QuantityKind::albedo) && model == Model::smith_walk) ||
         ((kind == QuantityKind::vndf || kind == QuantityKind::scattering || kind == QuantityKind::masking ||
           kind == QuantityKind::albedo) && model == Model::heightfield);
}

bool is_shared_by_ranks(const ExperimentSpec& spec, const Decision& decision) {
  const SpecQuantity& q = spec.quantities[decision.quantity];
  return is_split(spec, decision) ||
         (q.kind == QuantityKind::validation && (q.dump.empty() || decision.model.model == Model::heightfield));
}

BlockRange rank_blocks(const BlockRange& round, int rank, int ranks) {
  const BlockRange shard = shard_range(round.size(), std::uint64_t(rank) + 1, std::uint64_t(ranks));
  return {round.begin + shard.begin, round.begin + shard.end};
}

EllipsoidVndf split_vndf_round(const RoundSplit& split, std::size_t measurement, const EllipsoidTarget& target,
                               const VndfRequest& request) {
  const auto start = std::chrono::steady_clock::now();
  const BlockRange round = round_blocks(request.blocks, request.rays, kRaysPerBlock);
  return split_round<EllipsoidVndf>(
      split, {measurement, request.rays, request.seed, round},
      [&](const std::optional<BlockRange>& blocks) { return measure_ellipsoid_vndf(target, with_blocks(request, blocks)); },
      [](const EllipsoidVndf& own) { return vndf_part({own.trace, {}}); },
      [&](EllipsoidVndf own, const std::vector<std::string>& parts, int first) {
        return combine_vndf_parts(std::move(own), parts, round, first, seconds_since(start));
      });
}

HeightfieldVndf split_heightfield_vndf_round(const RoundSplit& split, std::size_t measurement, const SceneOf& scene,
                                             const microgeom::Heightfield& field, const std::string& label,
                                             const VndfRequest& request) {
  const auto start = std::chrono::steady_clock::now();
  const BlockRange round = round_blocks(request.blocks, request.rays, kRaysPerBlock);
  return split_round<HeightfieldVndf>(
      split, {measurement, request.rays, request.seed, round},
      [&](const std::optional<BlockRange>& blocks) {
        return trace_heightfield_vndf(scene(), field, label, with_blocks(request, blocks));
      },
      [](const HeightfieldVndf& own) { return vndf_part({own.trace, own.diagnostics}); },
      [&](HeightfieldVndf own, const std::vector<std::string>& parts, int first) {
        return combine_heightfield_parts(std::move(own), parts, round, first, seconds_since(start));
      });
}

ScatterHistogram split_scatter_round(const RoundSplit& split, std::size_t measurement, const ScatterPaths& paths,
                                     const ScatterOptions& options) {
  const BlockRange round = round_blocks(options.blocks, options.paths, kPathsPerBlock);
  return split_round<ScatterHistogram>(
      split, {measurement, options.paths, options.seed, round},
      [&](const std::optional<BlockRange>& blocks) { return paths(with_blocks(options, blocks)); },
      [](const ScatterHistogram& own) { return scatter_part(own); },
      [&](ScatterHistogram own, const std::vector<std::string>& parts, int first) {
        return combine_scatter_parts(std::move(own), parts, round, first);
      });
}

std::optional<std::vector<SurfaceMasking>> split_masking_round(const RoundSplit& split, std::size_t measurement,
                                                               const HeightfieldMasking& h, std::uint64_t surface_seed,
                                                               const BlockRange& blocks, const RunControl& run) {
  const RoundTask task{measurement, kMaskingRunSamples, h.seed(), blocks, surface_seed};
  if (const std::vector<std::string>* stored = stored_parts(split.stored, task))
    return combine_masking_parts(h.measure_round({blocks.begin, blocks.begin}, run), *stored, blocks, 0);
  if (split.ranks == nullptr || split.ranks->size() == 1) return h.measure_round(blocks, run);
  split.ranks->broadcast(task_message(task));
  const BlockRange mine = rank_blocks(blocks, 0, split.ranks->size());
  std::optional<std::vector<SurfaceMasking>> own = h.measure_round(mine, run);
  const std::vector<std::string> parts = split.ranks->gather(masking_round_part(mine, own));
  check_part_count(parts, split.ranks->size());
  return combine_masking_parts(std::move(own), parts, blocks, 1);
}

AlbedoTable split_albedo_round(const RoundSplit& split, std::size_t measurement, const AlbedoTableRequest& request,
                               const AlbedoCellsOf& cells) {
  const auto start = std::chrono::steady_clock::now();
  const BlockRange round{0, request.alphas.size() * std::uint64_t(request.mus)};
  const RoundTask task{measurement, request.paths, request.seed, round};
  if (const std::vector<std::string>* stored = stored_parts(split.stored, task))
    return combine_albedo_parts(request, {}, *stored, round, 0, seconds_since(start));
  if (split.ranks == nullptr || split.ranks->size() == 1) {
    const std::optional<AlbedoCells> all = cells(request, round);
    return all ? albedo_table_from_cells(request, *all, seconds_since(start)) : cancelled_albedo_table(request);
  }
  split.ranks->broadcast(task_message(task));
  const BlockRange mine = rank_blocks(round, 0, split.ranks->size());
  const std::optional<AlbedoCells> own = cells(request, mine);
  const std::vector<std::string> parts = split.ranks->gather(albedo_part(mine, own));
  check_part_count(parts, split.ranks->size());
  if (!own) return cancelled_albedo_table(request);
  return combine_albedo_parts(request, *own, parts, round, 1, seconds_since(start));
}

AlbedoCellsOf albedo_cells_of(const Decision& decision, SurfaceCache& surfaces) {
  if (decision.model.model != Model::heightfield) return walk_albedo_cells;
  return [plan = decision.surface, &surfaces](const AlbedoTableRequest& request, const BlockRange& cells) {
    return surface_albedo_cells_of(request, cells, plan, surfaces);
  };
}

std::uint64_t albedo_round_cells(const ExperimentSpec& spec, const Decision& decision) {
  const SpecQuantity& q = spec.quantities[decision.quantity];
  return spec.material(q.material).alphas.size() * std::uint64_t(q.mus);
}

ValidationReport split_validation(const RoundSplit& split, std::size_t measurement, const SamplerInfo& sampler,
                                  const GGX<double>& ggx, const Vec3<double>& wi, const ValidationOptions& options) {
  const BlockRange round{0, options.samples / kSampleBlock + (options.samples % kSampleBlock != 0)};
  const RoundTask task{measurement, options.samples, options.seed, round};
  const std::vector<std::string>* stored = stored_parts(split.stored, task);
  const bool ranks = split.ranks != nullptr && split.ranks->size() > 1;
  if (stored == nullptr && !ranks) return validate_sampler(sampler, ggx, wi, options);
  const auto start = std::chrono::steady_clock::now();
  require_samples_for_any_test(options.samples);  // before the cubature, as validate_sampler
  const auto reference = claimed_reference(sampler, ggx, wi, options.rows);
  require_samples(options.samples, *reference);
  // The cells of the tallies: those of a tally of no sample.
  const std::optional<battery::Tally> none = own_tally(sampler, *reference, options, BlockRange{0, 0});
  if (!none) throw Cancelled("validation");
  battery::Tally tally;
  if (stored != nullptr) {
    tally = merged_validation_tally(std::nullopt, tally_cells(*none), *stored, round, 0);
  } else {
    split.ranks->broadcast(task_message(task));
    const BlockRange mine = rank_blocks(round, 0, split.ranks->size());
    const std::optional<battery::Tally> own = own_tally(sampler, *reference, options, mine);
    const std::vector<std::string> parts = split.ranks->gather(validation_part(mine, own));
    check_part_count(parts, split.ranks->size());
    tally = merged_validation_tally(own, tally_cells(*none), parts, round, 1);
  }
  ValidationReport r = report_drawn_samples(sampler, *reference, tally, options);
  r.seconds = seconds_since(start);
  return r;
}

void send_plan(Ranks& ranks, const ExperimentSpec& spec, const ExperimentPlan& plan) {
  if (ranks.size() > 1) ranks.broadcast(nlohmann::json{{"plan", plan_json(plan, spec)}, {"spec_digest", spec_digest(spec)}}.dump());
}

void send_stop(Ranks& ranks, int exit_code) {
  if (ranks.size() > 1) ranks.broadcast(stop_message(exit_code));
}

namespace {

// A rank's part of a drawn validation: its blocks' tally against the claimed pdf's binnings (no cubature).
std::string validation_rank_part(const SpecQuantity& q, const Decision& d, const RoundTask& task, const BlockRange& mine,
                                 const RunControl& run) {
  const SamplerInfo* sampler = find_sampler(q.sampler);
  if (sampler == nullptr) throw InternalError(fmt::format("a split validation of an unknown sampler '{}'", q.sampler));
  const ValidationOptions options = validation_request(q, task.units, task.seed, run);
  const GGX<double> ggx(d.alpha.first, d.alpha.second);
  const auto bins = claimed_reference_bins(*sampler, ggx, direction_from_degrees(d.view.theta_deg, d.view.phi_deg), q.rows);
  return validation_part(mine, own_tally(*sampler, *bins, options, mine));
}

// A rank's part of a heightfield masking round: the surface of the run's seed from `surfaces` (a build cancelled:
// a cancelled part), then its shard of the blocks for every light.
std::string masking_rank_part(const ExperimentSpec& spec, const Decision& d, const RoundTask& task, const BlockRange& mine,
                              const RunControl& run, SurfaceCache& surfaces) {
  const SpecQuantity& q = spec.quantities[d.quantity];
  const SpecMaterial& material = spec.material(q.material);
  const microgeom::Heightfield* field = nullptr;
  try {
    field = &acquire_masking_surface(q, material, d.alpha, task.surface_seed, surfaces, run);
  } catch (const Cancelled&) {
    return masking_round_part(mine, std::nullopt);
  }
  const HeightfieldMasking h(q, d, *field, masking_surface_text(q, material, d.alpha, task.surface_seed), task.seed);
  return masking_round_part(mine, h.measure_round(mine, run));
}

// A rank's part of a round on an explicit heightfield: the tile from `surfaces` (its build cancelled: a part
// cancelled before its first block), then its shard of the VNDF's rays (a VNDF's, or the reference rays of a
// validation against the tile) or of the paths.
std::string heightfield_rank_part(const ExperimentSpec& spec, const Decision& d, const RoundTask& task,
                                  const BlockRange& mine, const RunControl& run, SurfaceCache& surfaces) {
  const microgeom::Heightfield* field = nullptr;
  try {
    field = &decision_surface(d, surfaces, run);
  } catch (const Cancelled&) {
    return cancelled_part(mine);
  }
  const SpecQuantity& q = spec.quantities[d.quantity];
  if (q.kind == QuantityKind::vndf || q.kind == QuantityKind::validation) {
    VndfRequest request = vndf_request(spec, d, task.units, task.seed, run);
    request.blocks = mine;
    const HeightfieldVndf m = trace_heightfield_vndf(surfaces.scene_for(*field), *field, surface_label(d.surface), request);
    return vndf_part({m.trace, m.diagnostics});
  }
  ScatterOptions options = scatter_request(spec.material(q.material), d, task.units, task.seed, run);
  options.blocks = mine;
  return scatter_part(scatter_on_surface(surfaces.scene_for(*field), options));
}

}  // namespace

std::string run_part(const ExperimentSpec& spec, const ExperimentPlan& plan, const RoundTask& task, int rank, int ranks,
                     const RunControl& run, SurfaceCache& surfaces) {
  if (task.measurement >= plan.decisions.size())
    throw InternalError(fmt::format("a round of measurement {}: the plan has {}", task.measurement, plan.decisions.size()));
  const Decision& d = plan.decisions[task.measurement];
  const SpecQuantity& q = spec.quantities[d.quantity];
  const BlockRange mine = rank_blocks(task.blocks, rank, ranks);
  if (!is_shared_by_ranks(spec, d))
    throw InternalError(fmt::format("a round of measurement {}, which is not split", task.measurement));
  if (d.model.model == Model::heightfield && q.kind != QuantityKind::masking && q.kind != QuantityKind::albedo)
    return heightfield_rank_part(spec, d, task, mine, run, surfaces);
  if (q.kind == QuantityKind::validation) return validation_rank_part(q, d, task, mine, run);
  if (q.kind == QuantityKind::masking) return masking_rank_part(spec, d, task, mine, run, surfaces);
  if (q.kind == QuantityKind::albedo)
    return albedo_part(mine, albedo_cells_of(d, surfaces)(sampled_albedo_request(spec, d, task.units, task.seed, run), mine));
  if (q.kind == QuantityKind::vndf) {
    VndfRequest request = vndf_request(spec, d, task.units, task.seed, run);
    request.blocks = mine;
    return vndf_part({measure_ellipsoid_vndf(EllipsoidTarget(d.alpha.first, d.alpha.second, -1), request).trace, {}});
  }
  const SpecMaterial& material = spec.material(q.material);
  ScatterOptions options = scatter_request(material, d, task.units, task.seed, run);
  options.blocks = mine;
  return scatter_part(smith_walk_scatter(scatter_surface(material, d), options));
}

bool part_is_partial(const std::string& part) {
  PartReader in(part, 0);
  in.next();
  in.next();
  return in.next() != 0;
}

void check_whole_part(const std::string& part, const BlockRange& round, int rank, int ranks) {
  PartReader in(part, rank);
  bool partial = false;
  read_header(in, round, rank, ranks, partial);
  if (partial) in.fail("cancelled part way");
}

nlohmann::json round_task_json(const RoundTask& task) {
  nlohmann::json j{{"measurement", task.measurement}, {"units", task.units}, {"seed", task.seed},
                   {"blocks", {task.blocks.begin, task.blocks.end}}};
  if (task.surface_seed != 0) j["surface_seed"] = task.surface_seed;
  return j;
}

RoundTask round_task_from_json(const nlohmann::json& task) {
  return {task.at("measurement").get<std::size_t>(), task.at("units").get<std::uint64_t>(),
          task.at("seed").get<std::uint64_t>(),
          BlockRange{task.at("blocks").at(0).get<std::uint64_t>(), task.at("blocks").at(1).get<std::uint64_t>()},
          task.value("surface_seed", std::uint64_t(0))};
}

namespace {

// The plan the root sent, for this rank's spec (which must be the root's).
ExperimentPlan received_plan(const nlohmann::json& message, const ExperimentSpec& spec, int rank) {
  const auto root_digest = message.at("spec_digest").get<std::string>();
  if (spec_digest(spec) != root_digest)
    throw std::invalid_argument(fmt::format("rank {}: the spec {} is not rank 0's (digest {} here, {} there): every rank "
                                            "must read the same spec",
                                            rank, spec.source, spec_digest(spec), root_digest));
  return plan_from_json(message.at("plan"), spec);
}

}  // namespace

int serve_rounds(Ranks& ranks, const std::function<ExperimentSpec()>& load_spec, const RunControl& run,
                 SurfaceCache& surfaces) {
  nlohmann::json message = parse_message(ranks.broadcast(""));
  if (message.contains("stop")) return message.at("stop").get<int>();
  const ExperimentSpec spec = load_spec();
  ExperimentPlan plan;
  try {
    plan = received_plan(message, spec, ranks.rank());
  } catch (const nlohmann::json::exception& e) {
    throw InternalError(fmt::format("rank {}: the plan from the root is malformed: {}", ranks.rank(), e.what()));
  }
  for (;;) {
    message = parse_message(ranks.broadcast(""));
    if (message.contains("stop")) return message.at("stop").get<int>();
    std::string part;
    try {
      part = run_part(spec, plan, round_task_from_json(message.at("round")), ranks.rank(), ranks.size(), run, surfaces);
    } catch (const nlohmann::json::exception& e) {
      throw InternalError(fmt::format("rank {}: a round from the root is malformed: {}", ranks.rank(), e.what()));
    }
    ranks.gather(part);
  }
}

}  // namespace microsim::experiment
