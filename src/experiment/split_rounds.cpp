// experiment: the rounds of run_experiment split over ranks (split_rounds.h).
#include "experiment/split_rounds.h"
#include "core/wall_clock.h"

#include "core/errors.h"
#include "experiment/measures.h"
#include "experiment/run.h"
#include "core/run_control.h"
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
  w.insert(w.end(), {blocks.begin, blocks.end, std::uint64_t(partial)});
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

std::string vndf_part(const EllipsoidVndf& m) {
  Words w;
  put_header(w, m.trace.blocks, m.trace.partial);
  w.insert(w.end(), {m.trace.rays, m.trace.hits, m.trace.counts.size()});
  for (const auto& counts : m.trace.counts) {
    w.push_back(counts.size());
    w.insert(w.end(), counts.begin(), counts.end());
  }
  w.push_back(m.trace.unbinned.size());
  w.insert(w.end(), m.trace.unbinned.begin(), m.trace.unbinned.end());
  return words_to_bytes(w);
}

// Adds rank r's part to the trace of the ranks before it (whose blocks end where this part begins).
void add_vndf_part(TraceResult& t, const std::string& bytes, const BlockRange& round, int rank, int ranks) {
  PartReader in(bytes, rank);
  bool partial = false;
  const BlockRange blocks = read_header(in, round, rank, ranks, partial);
  t.rays += in.next();
  t.hits += in.next();
  in.expect(t.counts.size(), "binnings");
  for (auto& counts : t.counts) {
    in.expect(counts.size(), "bins");
    for (std::uint64_t& c : counts) c += in.next();
  }
  in.expect(t.unbinned.size(), "binnings");
  for (std::uint64_t& u : t.unbinned) u += in.next();
  in.finish();
  t.blocks.end = blocks.end;
  t.partial = partial;
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

// The parts (from `first` on; the root's own is rank 0's) in rank order, as the one-process round: the counts
// summed, the histogram's per-part attributes (blocks, unbinned, rate) those of the whole, analysed.
EllipsoidVndf combine_vndf_parts(EllipsoidVndf own, const std::vector<std::string>& parts, const BlockRange& round,
                                 int first, double seconds) {
  const int ranks = int(parts.size());  // checked: one part per rank
  TraceResult t = std::move(own.trace);
  check_start(t.blocks, t.partial, round, first, ranks);
  for (int r = first; r < ranks && !t.partial; ++r) add_vndf_part(t, parts[std::size_t(r)], round, r, ranks);
  t.seconds = seconds;
  TracedHistogram h = std::move(own.histogram);
  h.counts = t.counts;
  h.rays = t.rays;
  h.hits = t.hits;
  h.partial = t.partial;
  h.attributes["blocks"] = fmt::format("{},{}", t.blocks.begin, t.blocks.end);
  h.attributes["unbinned"] = joined_counts(t.unbinned);
  h.attributes["rays_per_second"] = fmt::format("{:.17g}", t.rays_per_second());
  EllipsoidVndf combined = analyse_ellipsoid_vndf(std::move(h), t.unbinned);
  combined.trace = std::move(t);
  combined.expected_hit_fraction = own.expected_hit_fraction;
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
  sum.partial = partial;
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

// A rank's tally of its blocks (tally_json), or a cancelled part (no tally).
std::string validation_part(const BlockRange& blocks, const std::optional<battery::Tally>& tally) {
  nlohmann::json part{{"blocks", {blocks.begin, blocks.end}}, {"cancelled", !tally.has_value()}};
  if (tally) part["tally"] = tally_json(*tally);
  return part.dump();
}

// Rank r's tally (its blocks checked as check_shard checks them), or nullopt when it was cancelled.
std::optional<battery::Tally> read_validation_part(const std::string& text, const std::vector<std::size_t>& cells,
                                                   const BlockRange& round, int rank, int ranks) {
  try {
    const nlohmann::json part = nlohmann::json::parse(text);
    if (part.at("cancelled").get<bool>()) return std::nullopt;
    const BlockRange blocks{part.at("blocks").at(0).get<std::uint64_t>(), part.at("blocks").at(1).get<std::uint64_t>()};
    check_shard(blocks, false, round, rank, ranks);
    return tally_from_json(part.at("tally"), cells, blocks.size(), microsim::PartReader("validation part"),
                           fmt::format("rank {}", rank));
  } catch (const nlohmann::json::exception& e) {
    throw InternalError(fmt::format("the part of rank {} of a split validation is malformed: {}", rank, e.what()));
  } catch (const HistogramMergeError& e) {
    throw InternalError(fmt::format("the part of rank {} of a split validation is malformed: {}", rank, e.what()));
  }
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

// The ranks' tallies in rank order as one (merge_tallies); Cancelled when any part was cancelled.
battery::Tally merged_validation_tally(const std::optional<battery::Tally>& own, const std::vector<std::string>& parts,
                                       const BlockRange& round) {
  if (!own) throw Cancelled("validation");
  const int ranks = int(parts.size());
  std::vector<battery::Tally> tallies{*own};
  for (int r = 1; r < ranks; ++r) {
    std::optional<battery::Tally> t = read_validation_part(parts[std::size_t(r)], tally_cells(*own), round, r, ranks);
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

}  // namespace

bool is_split(const ExperimentSpec& spec, const Decision& decision) {
  const QuantityKind kind = spec.quantities[decision.quantity].kind;
  return (kind == QuantityKind::vndf && decision.model.model == Model::ellipsoid_oracle) ||
         ((kind == QuantityKind::scattering || kind == QuantityKind::albedo) && decision.model.model == Model::smith_walk);
}

bool is_shared_by_ranks(const ExperimentSpec& spec, const Decision& decision) {
  const SpecQuantity& q = spec.quantities[decision.quantity];
  return is_split(spec, decision) || (q.kind == QuantityKind::validation && q.dump.empty());
}

BlockRange rank_blocks(const BlockRange& round, int rank, int ranks) {
  const BlockRange shard = shard_range(round.size(), std::uint64_t(rank) + 1, std::uint64_t(ranks));
  return {round.begin + shard.begin, round.begin + shard.end};
}

EllipsoidVndf split_vndf_round(const RoundSplit& split, std::size_t measurement, const EllipsoidTarget& target,
                               const VndfRequest& request) {
  const auto start = std::chrono::steady_clock::now();
  const BlockRange round = round_blocks(request.blocks, request.rays, kRaysPerBlock);
  const RoundTask task{measurement, request.rays, request.seed, round};
  VndfRequest own = request;
  if (const std::vector<std::string>* stored = stored_parts(split.stored, task)) {
    own.blocks = BlockRange{round.begin, round.begin};  // nothing traced: the binnings and attributes
    return combine_vndf_parts(measure_ellipsoid_vndf(target, own), *stored, round, 0, seconds_since(start));
  }
  if (split.ranks == nullptr || split.ranks->size() == 1) return measure_ellipsoid_vndf(target, request);
  split.ranks->broadcast(task_message(task));
  own.blocks = rank_blocks(round, 0, split.ranks->size());
  EllipsoidVndf part = measure_ellipsoid_vndf(target, own);
  const std::vector<std::string> parts = split.ranks->gather(vndf_part(part));
  check_part_count(parts, split.ranks->size());
  return combine_vndf_parts(std::move(part), parts, round, 1, seconds_since(start));
}

ScatterHistogram split_scatter_round(const RoundSplit& split, std::size_t measurement, const SmithMicrosurface& surface,
                                     const ScatterOptions& options) {
  const BlockRange round = round_blocks(options.blocks, options.paths, kPathsPerBlock);
  const RoundTask task{measurement, options.paths, options.seed, round};
  ScatterOptions own = options;
  if (const std::vector<std::string>* stored = stored_parts(split.stored, task)) {
    own.blocks = BlockRange{round.begin, round.begin};  // nothing walked: the binning and provenance
    return combine_scatter_parts(smith_walk_scatter(surface, own), *stored, round, 0);
  }
  if (split.ranks == nullptr || split.ranks->size() == 1) return smith_walk_scatter(surface, options);
  split.ranks->broadcast(task_message(task));
  own.blocks = rank_blocks(round, 0, split.ranks->size());
  ScatterHistogram part = smith_walk_scatter(surface, own);
  const std::vector<std::string> parts = split.ranks->gather(scatter_part(part));
  check_part_count(parts, split.ranks->size());
  return combine_scatter_parts(std::move(part), parts, round, 1);
}

AlbedoTable split_albedo_round(const RoundSplit& split, std::size_t measurement, const AlbedoTableRequest& request) {
  const auto start = std::chrono::steady_clock::now();
  const BlockRange round{0, request.alphas.size() * std::uint64_t(request.mus)};
  const RoundTask task{measurement, request.paths, request.seed, round};
  if (const std::vector<std::string>* stored = stored_parts(split.stored, task))
    return combine_albedo_parts(request, {}, *stored, round, 0, seconds_since(start));
  if (split.ranks == nullptr || split.ranks->size() == 1) return albedo_table(request);
  split.ranks->broadcast(task_message(task));
  const BlockRange mine = rank_blocks(round, 0, split.ranks->size());
  const std::optional<AlbedoCells> own = walk_albedo_cells(request, mine);
  const std::vector<std::string> parts = split.ranks->gather(albedo_part(mine, own));
  check_part_count(parts, split.ranks->size());
  if (!own) return cancelled_albedo_table(request);
  return combine_albedo_parts(request, *own, parts, round, 1, seconds_since(start));
}

std::uint64_t albedo_round_cells(const ExperimentSpec& spec, const Decision& decision) {
  const SpecQuantity& q = spec.quantities[decision.quantity];
  return spec.material(q.material).alphas.size() * std::uint64_t(q.mus);
}

ValidationReport split_validation(const RoundSplit& split, std::size_t measurement, const SamplerInfo& sampler,
                                  const GGX<double>& ggx, const Vec3<double>& wi, const ValidationOptions& options) {
  if (split.ranks == nullptr || split.ranks->size() == 1) return validate_sampler(sampler, ggx, wi, options);
  const auto start = std::chrono::steady_clock::now();
  require_samples_for_any_test(options.samples);  // before the cubature, as validate_sampler
  const auto reference = claimed_reference(sampler, ggx, wi, options.rows);
  require_samples(options.samples, *reference);
  const BlockRange round{0, options.samples / kSampleBlock + (options.samples % kSampleBlock != 0)};
  split.ranks->broadcast(task_message({measurement, options.samples, options.seed, round}));
  const std::optional<battery::Tally> own = own_tally(sampler, *reference, options, rank_blocks(round, 0, split.ranks->size()));
  const std::vector<std::string> parts = split.ranks->gather(validation_part(rank_blocks(round, 0, split.ranks->size()), own));
  check_part_count(parts, split.ranks->size());
  ValidationReport r = report_drawn_samples(sampler, *reference, merged_validation_tally(own, parts, round), options);
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

}  // namespace

std::string run_part(const ExperimentSpec& spec, const ExperimentPlan& plan, const RoundTask& task, int rank, int ranks,
                     const RunControl& run) {
  if (task.measurement >= plan.decisions.size())
    throw InternalError(fmt::format("a round of measurement {}: the plan has {}", task.measurement, plan.decisions.size()));
  const Decision& d = plan.decisions[task.measurement];
  const SpecQuantity& q = spec.quantities[d.quantity];
  const BlockRange mine = rank_blocks(task.blocks, rank, ranks);
  if (!is_shared_by_ranks(spec, d))
    throw InternalError(fmt::format("a round of measurement {}, which is not split", task.measurement));
  if (q.kind == QuantityKind::validation) return validation_rank_part(q, d, task, mine, run);
  if (q.kind == QuantityKind::albedo)
    return albedo_part(mine, walk_albedo_cells(albedo_request(spec, q, Model::smith_walk, task.units, d.order_cap, 0, task.seed, run), mine));
  if (q.kind == QuantityKind::vndf) {
    VndfRequest request = vndf_request(spec, d, task.units, task.seed, run);
    request.blocks = mine;
    return vndf_part(measure_ellipsoid_vndf(EllipsoidTarget(d.alpha.first, d.alpha.second, -1), request));
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
  return {{"measurement", task.measurement}, {"units", task.units}, {"seed", task.seed},
          {"blocks", {task.blocks.begin, task.blocks.end}}};
}

RoundTask round_task_from_json(const nlohmann::json& task) {
  return {task.at("measurement").get<std::size_t>(), task.at("units").get<std::uint64_t>(),
          task.at("seed").get<std::uint64_t>(),
          BlockRange{task.at("blocks").at(0).get<std::uint64_t>(), task.at("blocks").at(1).get<std::uint64_t>()}};
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

int serve_rounds(Ranks& ranks, const std::function<ExperimentSpec()>& load_spec, const RunControl& run) {
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
      part = run_part(spec, plan, round_task_from_json(message.at("round")), ranks.rank(), ranks.size(), run);
    } catch (const nlohmann::json::exception& e) {
      throw InternalError(fmt::format("rank {}: a round from the root is malformed: {}", ranks.rank(), e.what()));
    }
    ranks.gather(part);
  }
}

}  // namespace microsim::experiment
