// experiment: the parts of a split round (parts.h): exact integers as words, added in block order.
#include "experiment/parts.h"

#include "core/errors.h"
#include "validate/validation_part.h"

#include <fmt/core.h>

#include <bit>
#include <cstring>
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
class WordReader {
public:
  WordReader(const std::string& bytes, int rank) : rank_(rank) {
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
BlockRange read_header(WordReader& in, const BlockRange& round, int rank, int ranks, bool& partial) {
  const BlockRange got{in.next(), in.next()};
  partial = in.next() != 0;
  check_shard(got, partial, round, rank, ranks);
  return got;
}
}  // namespace

namespace {
// ---- VNDF parts -------------------------------------------------------------------------------------------

// The traced sums of a VNDF round: counts and the heightfield tracer's diagnostics (0 on the ellipsoid).
struct VndfSums {
  TraceResult trace;
  HeightfieldVndfDiagnostics diagnostics;
};
}  // namespace

std::string vndf_part(const TraceResult& trace, const HeightfieldVndfDiagnostics& d) {
  Words w;
  put_header(w, trace.blocks, trace.partial);
  w.insert(w.end(), {trace.rays, trace.hits, trace.counts.size()});
  for (const auto& counts : trace.counts) {
    w.push_back(counts.size());
    w.insert(w.end(), counts.begin(), counts.end());
  }
  w.push_back(trace.unbinned.size());
  w.insert(w.end(), trace.unbinned.begin(), trace.unbinned.end());
  w.insert(w.end(), {d.backfacing, d.edge_grazes, d.leaked, d.unresolved});
  return words_to_bytes(w);
}

// A part cancelled before its first block with nothing measured (a tile's build cancelled on that rank).
std::string cancelled_part(const BlockRange& mine) {
  Words w;
  put_header(w, BlockRange{mine.begin, mine.begin}, true);
  return words_to_bytes(w);
}

namespace {
// Whether a part is cancelled_part's (read past its header): nothing to add.
bool holds_nothing(const WordReader& in, const BlockRange& blocks, bool partial) {
  return partial && blocks.size() == 0 && in.at_end();
}

// Adds rank r's part to the sums of the ranks before it (whose blocks end where this part begins).
void add_vndf_part(VndfSums& sums, const std::string& bytes, const BlockRange& round, int rank, int ranks) {
  WordReader in(bytes, rank);
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
}  // namespace

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

// Every exact sum of a scattering histogram, in one order (ScatterHistogram::add_sums's arguments).
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

namespace {
void add_scatter_part(ScatterHistogram& sum, const std::string& bytes, const BlockRange& round, int rank, int ranks) {
  WordReader in(bytes, rank);
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
}  // namespace

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


namespace {
// Rank r's cells appended to `cells` (its header checked: read_header); false when it was cancelled.
bool add_albedo_part(AlbedoCells& cells, const std::string& bytes, const BlockRange& round, int rank, int ranks) {
  WordReader in(bytes, rank);
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
}  // namespace

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

namespace {
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
  WordReader in(bytes, rank);
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

}  // namespace

// A rank's tally of its blocks (tally_json), or a cancelled part.
std::string validation_part(const BlockRange& blocks, const std::optional<battery::Tally>& tally) {
  return text_part(blocks, tally ? std::optional<std::string>(tally_json(*tally).dump()) : std::nullopt);
}


namespace {
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
}  // namespace

// ---- heightfield masking parts (every light's exact sums of a shard of the round's blocks) ---------------------

std::string masking_round_part(const BlockRange& blocks, const std::optional<std::vector<SurfaceMasking>>& round) {
  if (!round) return text_part(blocks, std::nullopt);
  nlohmann::json lights = nlohmann::json::array();
  for (const SurfaceMasking& light : *round) lights.push_back(masking_part_json(light));
  return text_part(blocks, lights.dump());
}

namespace {
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

}  // namespace

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

BlockRange rank_blocks(const BlockRange& round, int rank, int ranks) {
  const BlockRange shard = shard_range(round.size(), std::uint64_t(rank) + 1, std::uint64_t(ranks));
  return {round.begin + shard.begin, round.begin + shard.end};
}

bool part_is_partial(const std::string& part) {
  WordReader in(part, 0);
  in.next();
  in.next();
  return in.next() != 0;
}

void check_whole_part(const std::string& part, const BlockRange& round, int rank, int ranks) {
  WordReader in(part, rank);
  bool partial = false;
  read_header(in, round, rank, ranks, partial);
  if (partial) in.fail("cancelled part way");
}

}  // namespace microsim::experiment
