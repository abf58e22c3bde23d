#include "stats/scatter_merge.h"

#include "microfacet/material.h"
#include "stats/binning.h"
#include "stats/part_json.h"

#include <fmt/core.h>

#include <algorithm>
#include <optional>
#include <stdexcept>

namespace microsim {

ScatterHistogram merge_scatter_parts(const std::vector<ScatterHistogram>& parts) {
  if (parts.empty()) throw HistogramMergeError("nothing to merge");
  std::vector<BlockRange> ranges;
  ScatterHistogram merged = parts.front();
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const ScatterHistogram& p = parts[i];
    try {
      if (i > 0) add_scatter_part(merged, p);
    } catch (const HistogramMergeError& e) {
      throw HistogramMergeError(fmt::format("part {}: {}", i + 1, e.what()));
    }
    ranges.push_back(p.provenance.blocks);
  }
  merged.provenance.blocks = merge_block_ranges(ranges, merged.provenance.total_blocks, /*require_complete=*/true);
  merged.partial = false;
  return merged;
}

void add_scatter_part(ScatterHistogram& sum, const ScatterHistogram& part) {
  sum.provenance.check_same_run(part.provenance);
  sum.merge(part);
}

namespace {

// The binning a histogram's id describes, when it is a hemispheres binning in canonical form whose upper half
// is the reflection side; nullopt otherwise.
std::optional<DirectionBinning> scatter_binning(const std::string& binning_id, const std::vector<bool>& reflection) {
  const nlohmann::json d = nlohmann::json::parse(binning_id, nullptr, /*allow_exceptions=*/false);
  if (d.is_discarded() || !d.is_object() || d.value("kind", "") != "hemispheres") return std::nullopt;
  std::optional<DirectionBinning> b;
  try {
    b = DirectionBinning::from_description(d);
  } catch (const std::invalid_argument&) {
    return std::nullopt;
  }
  if (b->describe().dump() != binning_id || reflection.size() != std::size_t(b->size())) return std::nullopt;
  for (std::size_t i = 0; i < reflection.size(); ++i)
    if (reflection[i] != (int(i) < b->size() / 2)) return std::nullopt;
  return b;
}

std::vector<bool> reflection_bins(const ScatterHistogram& h) {
  std::vector<bool> r(h.bins());
  for (std::size_t i = 0; i < h.bins(); ++i) r[i] = h.is_reflection_bin(i);
  return r;
}

}  // namespace

nlohmann::json scatter_part_json(const ScatterHistogram& h, const std::map<std::string, std::string>& notes) {
  if (!scatter_binning(h.binning_id(), reflection_bins(h)))
    throw std::invalid_argument("scatter part: the result's binning is not a hemispheres binning with reflection in "
                                "its upper half");
  std::vector<std::string> channels;
  for (int c = 0; c < h.channels(); ++c) channels.push_back(h.channel_name(c));
  const nlohmann::json parameters = {{"producer", h.provenance.producer},
                                     {"measurement", h.provenance.measurement},
                                     {"binning", nlohmann::json::parse(h.binning_id())},
                                     {"channels", channels}};
  Provenance p = h.provenance;
  p.producer = kScatterPartProducer;
  return {{"provenance", provenance_json(p, parameters)},
          {"partial", h.partial},
          {"notes", notes},
          {"sums", scatter_sums_json(h)}};
}

namespace {

// The empty histogram of a part's binning and channels.
ScatterHistogram empty_histogram(const PartReader& r, const nlohmann::json& parameters) {
  const nlohmann::json& d = r.member(parameters, "binning", "provenance/parameters");
  const std::string id = d.dump();
  std::optional<DirectionBinning> b;
  if (d.is_object() && d.value("kind", "") == "hemispheres") {
    try {
      b = DirectionBinning::from_description(d);
    } catch (const std::invalid_argument&) {
    }
  }
  if (!b || b->describe().dump() != id)
    r.malformed("provenance/parameters/binning", "is not the canonical description of a hemispheres binning");
  const nlohmann::json& names = r.member(parameters, "channels", "provenance/parameters");
  const bool ok = names.is_array() && !names.empty() && names.size() <= std::size_t(Material::kMaxChannels) &&
                  std::all_of(names.begin(), names.end(), [](const nlohmann::json& v) { return v.is_string(); });
  if (!ok)
    r.malformed("provenance/parameters/channels", fmt::format("is not an array of 1 to {} names", Material::kMaxChannels));
  std::vector<bool> reflection(std::size_t(b->size()));
  for (int i = 0; i < b->size(); ++i) reflection[std::size_t(i)] = i < b->size() / 2;
  return ScatterHistogram(id, std::size_t(b->size()), std::move(reflection), names.get<std::vector<std::string>>());
}

std::map<std::string, std::string> read_notes(const PartReader& r, const nlohmann::json& report) {
  const nlohmann::json& notes = r.member(report, "notes", "");
  if (!notes.is_object()) r.malformed("notes", "is not an object");
  std::map<std::string, std::string> out;
  for (auto it = notes.begin(); it != notes.end(); ++it) {
    if (it.key().empty() || !it.value().is_string()) r.malformed("notes", "holds a note that is not KEY: text");
    out[it.key()] = it.value().get<std::string>();
  }
  return out;
}

}  // namespace

ScatterPart read_scatter_part(const nlohmann::json& report) {
  const PartReader r(kScatterPartProducer);
  nlohmann::json parameters;
  Provenance p = r.provenance(report, parameters);
  ScatterPart part{empty_histogram(r, parameters), read_notes(r, report)};
  p.producer = r.text(parameters, "producer", "provenance/parameters");
  p.measurement = r.text(parameters, "measurement", "provenance/parameters");
  part.histogram.provenance = p;
  part.histogram.partial = r.flag(report, "partial", "");
  add_scatter_sums(part.histogram, r.member(report, "sums", ""), r, "sums");
  return part;
}

}  // namespace microsim
