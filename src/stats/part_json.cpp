#include "stats/part_json.h"

#include "core/strict_parse.h"

#include <fmt/core.h>

#include <algorithm>
#include <bit>
#include <numeric>
#include <utility>

namespace microsim {

nlohmann::json provenance_json(const Provenance& p, const nlohmann::json& parameters) {
  return {{"producer", p.producer},
          {"parameters", parameters},
          {"seed", p.seed},
          {"blocks", {p.blocks.begin, p.blocks.end}},
          {"total_blocks", p.total_blocks}};
}

std::string producer_of(const nlohmann::json& report) {
  if (!report.is_object() || !report.contains("provenance")) return "";
  const nlohmann::json& p = report["provenance"];
  if (!p.is_object() || !p.contains("producer") || !p["producer"].is_string()) return "";
  return p["producer"].get<std::string>();
}

std::string exact_real_json(double x) { return fmt::format("{:016x}", std::bit_cast<std::uint64_t>(x)); }

nlohmann::json exact_sum_json(const ExactSum& s) { return {s.high_bits(), s.low_bits()}; }

namespace {
// The path of member `key` of the member at `where` ("" for the report itself).
std::string path_of(const std::string& where, const char* key) { return where.empty() ? key : where + "/" + key; }
}  // namespace

void PartReader::malformed(const std::string& where, const std::string& what) const {
  throw HistogramMergeError(fmt::format("not a {} part: {} {}", producer_, where, what));
}

const nlohmann::json& PartReader::member(const nlohmann::json& j, const char* key, const std::string& where) const {
  if (!j.is_object() || !j.contains(key)) malformed(path_of(where, key), "is missing");
  return j[key];
}

// Member `key` of `j` as a T, when `is_t` says it is one; else "WHERE/KEY is not WHAT".
template <class T>
T PartReader::typed(const nlohmann::json& j, const char* key, const std::string& where, bool (nlohmann::json::*is_t)() const noexcept,
                    const char* what) const {
  const nlohmann::json& v = member(j, key, where);
  if (!(v.*is_t)()) malformed(path_of(where, key), what);
  return v.get<T>();
}

std::uint64_t PartReader::count(const nlohmann::json& j, const char* key, const std::string& where) const {
  return typed<std::uint64_t>(j, key, where, &nlohmann::json::is_number_unsigned, "is not a count");
}

double PartReader::real(const nlohmann::json& j, const char* key, const std::string& where) const {
  return typed<double>(j, key, where, &nlohmann::json::is_number, "is not a number");
}

std::string PartReader::text(const nlohmann::json& j, const char* key, const std::string& where) const {
  return typed<std::string>(j, key, where, &nlohmann::json::is_string, "is not a string");
}

bool PartReader::flag(const nlohmann::json& j, const char* key, const std::string& where) const {
  return typed<bool>(j, key, where, &nlohmann::json::is_boolean, "is not true or false");
}

double PartReader::exact_real(const nlohmann::json& v, const std::string& where) const {
  const std::string s = v.is_string() ? v.get<std::string>() : std::string();
  const auto hex = [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); };
  if (s.size() != 16 || !std::all_of(s.begin(), s.end(), hex))
    malformed(where, fmt::format("= {} is not an exact real (16 hex digits)", reader::quote_excerpt(v.dump())));
  return std::bit_cast<double>(std::uint64_t(std::stoull(s, nullptr, 16)));
}

double PartReader::exact_real(const nlohmann::json& j, const char* key, const std::string& where) const {
  return exact_real(member(j, key, where), path_of(where, key));
}

const nlohmann::json& PartReader::array(const nlohmann::json& j, const char* key, std::size_t size,
                                        const std::string& where) const {
  const nlohmann::json& a = member(j, key, where);
  if (!a.is_array() || a.size() != size) malformed(path_of(where, key), fmt::format("is not an array of {}", size));
  return a;
}

ExactSum PartReader::exact_sum(const nlohmann::json& v, const std::string& where) const {
  const bool ok = v.is_array() && v.size() == 2 && v[0].is_number_unsigned() && v[1].is_number_unsigned() &&
                  (v[0].get<std::uint64_t>() >> 63) == 0;
  if (!ok)
    malformed(where, fmt::format("= {} is not an exact sum ([HIGH, LOW]: two counts, HIGH below 2^63)",
                                 reader::quote_excerpt(v.dump())));
  return ExactSum::from_bits(v[0].get<std::uint64_t>(), v[1].get<std::uint64_t>());
}

Provenance PartReader::provenance(const nlohmann::json& report, nlohmann::json& parameters) const {
  if (producer_of(report) != producer_) malformed("provenance/producer", fmt::format("is not \"{}\"", producer_));
  const nlohmann::json& prov = report["provenance"];
  parameters = member(prov, "parameters", "provenance");
  if (!parameters.is_object()) malformed("provenance/parameters", "is not an object");
  Provenance p;
  p.producer = producer_;
  p.measurement = parameters.dump();
  p.seed = count(prov, "seed", "provenance");
  p.total_blocks = count(prov, "total_blocks", "provenance");
  const nlohmann::json& blocks = member(prov, "blocks", "provenance");
  if (!blocks.is_array() || blocks.size() != 2 || !blocks[0].is_number_unsigned() || !blocks[1].is_number_unsigned() ||
      blocks[0].get<std::uint64_t>() > blocks[1].get<std::uint64_t>() ||
      blocks[1].get<std::uint64_t>() > p.total_blocks)
    malformed("provenance/blocks", fmt::format("= {} is not a range [B, E] within the run's {} blocks",
                                               reader::quote_excerpt(blocks.dump()), p.total_blocks));
  p.blocks = {blocks[0].get<std::uint64_t>(), blocks[1].get<std::uint64_t>()};
  return p;
}

// ---- scattering sums ------------------------------------------------------------------------------------------

namespace {
nlohmann::json sum_pair(const ExactSum& w, const ExactSum& w2) { return {exact_sum_json(w), exact_sum_json(w2)}; }
}  // namespace

nlohmann::json scatter_sums_json(const ScatterHistogram& h) {
  nlohmann::json channels = nlohmann::json::array();
  for (int c = 0; c < h.channels(); ++c) {
    nlohmann::json orders = nlohmann::json::array();
    for (int k = 0; k < kScatterOrderBins; ++k) {
      const Histogram& lobe = h.histogram(c, k);
      nlohmann::json w = nlohmann::json::array(), w2 = nlohmann::json::array();
      for (std::size_t b = 0; b < lobe.size(); ++b) {
        w.push_back(exact_sum_json(lobe.exact_weight(b)));
        w2.push_back(exact_sum_json(lobe.exact_weight_squared(b)));
      }
      orders.push_back({{"w", std::move(w)}, {"w2", std::move(w2)},
                        {"unbinned", sum_pair(lobe.exact_unbinned_weight(), lobe.exact_unbinned_weight_squared())}});
    }
    channels.push_back({{"orders", std::move(orders)},
                        {"unfinished", sum_pair(h.exact_unfinished(c, false), h.exact_unfinished(c, true))},
                        {"lost", sum_pair(h.exact_lost(c, false), h.exact_lost(c, true))}});
  }
  return {{"paths", h.paths()}, {"channels", std::move(channels)}};
}

namespace {
// Member `key` of `j`: [w, w2], two exact sums.
std::pair<ExactSum, ExactSum> read_sum_pair(const PartReader& r, const nlohmann::json& j, const char* key,
                                            const std::string& where) {
  const nlohmann::json& pair = r.array(j, key, 2, where);
  const std::string at = where + "/" + key;
  return {r.exact_sum(pair[0], at + "/0"), r.exact_sum(pair[1], at + "/1")};
}

void add_order_sums(ScatterHistogram& sum, int c, int k, const nlohmann::json& lobe, const PartReader& r,
                    const std::string& where) {
  const nlohmann::json& w = r.array(lobe, "w", sum.bins(), where);
  const nlohmann::json& w2 = r.array(lobe, "w2", sum.bins(), where);
  for (std::size_t b = 0; b < sum.bins(); ++b)
    sum.add_sums(c, k, b, r.exact_sum(w[b], fmt::format("{}/w/{}", where, b)),
                 r.exact_sum(w2[b], fmt::format("{}/w2/{}", where, b)));
  const auto [uw, uw2] = read_sum_pair(r, lobe, "unbinned", where);
  sum.add_unbinned_sums(c, k, uw, uw2);
}
}  // namespace

void add_scatter_sums(ScatterHistogram& sum, const nlohmann::json& sums, const PartReader& r, const std::string& where) {
  const nlohmann::json& channels = r.array(sums, "channels", std::size_t(sum.channels()), where);
  for (int c = 0; c < sum.channels(); ++c) {
    const std::string at = fmt::format("{}/channels/{}", where, c);
    const nlohmann::json& channel = channels[std::size_t(c)];
    const nlohmann::json& orders = r.array(channel, "orders", kScatterOrderBins, at);
    for (int k = 0; k < kScatterOrderBins; ++k)
      add_order_sums(sum, c, k, orders[std::size_t(k)], r, fmt::format("{}/orders/{}", at, k));
    const auto [fw, fw2] = read_sum_pair(r, channel, "unfinished", at);
    sum.add_unfinished_sums(c, fw, fw2);
    const auto [lw, lw2] = read_sum_pair(r, channel, "lost", at);
    sum.add_lost_sums(c, lw, lw2);
  }
  sum.add_launched(r.count(sums, "paths", where));
}

namespace {
// A parameter as a message quotes it (strings without their JSON quotes).
std::string parameter_text(const nlohmann::json& v) {
  return reader::quote_excerpt(v.is_string() ? v.get<std::string>() : v.dump());
}
}  // namespace

void check_same_parameters(const nlohmann::json& first, const nlohmann::json& other, const std::string& name) {
  for (auto it = first.begin(); it != first.end(); ++it) {
    const bool missing = !other.contains(it.key());
    if (missing || other[it.key()] != it.value())
      throw HistogramMergeError(fmt::format("{} is not part of the same run: {} is {} there, {} in the first part", name,
                                            it.key(), missing ? "missing" : parameter_text(other[it.key()]),
                                            parameter_text(it.value())));
  }
  for (auto it = other.begin(); it != other.end(); ++it)
    if (!first.contains(it.key()))
      throw HistogramMergeError(fmt::format("{} is not part of the same run: it has parameter {}, the first part not", name,
                                            it.key()));
}

std::vector<std::size_t> check_parts_of_one_run(const std::vector<Provenance>& provenances,
                                                const std::vector<nlohmann::json>& parameters) {
  if (provenances.empty()) throw HistogramMergeError("nothing to merge");
  std::vector<BlockRange> ranges;
  for (std::size_t i = 0; i < provenances.size(); ++i) {
    check_same_parameters(parameters.front(), parameters[i], fmt::format("part {}", i + 1));
    provenances.front().check_same_run(provenances[i]);
    ranges.push_back(provenances[i].blocks);
  }
  merge_block_ranges(ranges, provenances.front().total_blocks, /*require_complete=*/true);
  std::vector<std::size_t> order(provenances.size());
  std::iota(order.begin(), order.end(), std::size_t(0));
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return provenances[a].blocks.begin < provenances[b].blocks.begin; });
  return order;
}

}  // namespace microsim
