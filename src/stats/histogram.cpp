#include "stats/histogram.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>

namespace microsim {

void Provenance::check_same_run(const Provenance& other) const {
  auto differ = [](const char* what, const std::string& a, const std::string& b) {
    throw HistogramMergeError(fmt::format("not parts of one run: {} '{}' vs '{}'", what, a, b));
  };
  if (producer != other.producer) differ("producer", producer, other.producer);
  if (measurement != other.measurement) differ("measurement", measurement, other.measurement);
  if (seed != other.seed) differ("seed", std::to_string(seed), std::to_string(other.seed));
  if (total_blocks != other.total_blocks)
    differ("total blocks", std::to_string(total_blocks), std::to_string(other.total_blocks));
}

std::vector<std::uint64_t> Histogram::counts() const {
  std::vector<std::uint64_t> c(w_.size());
  for (std::size_t b = 0; b < w_.size(); ++b) {
    const double v = w_[b].value();
    if (v != std::floor(v) || w2_[b] != w_[b]) throw std::domain_error("Histogram::counts: weights are not counts");
    c[b] = static_cast<std::uint64_t>(v);
  }
  return c;
}

void Histogram::merge(const Histogram& other) {
  if (other.binning_id_ != binning_id_ || other.w_.size() != w_.size())
    throw HistogramMergeError(fmt::format("different binnings: {} vs {}", binning_id_, other.binning_id_));
  for (std::size_t b = 0; b < w_.size(); ++b) {
    w_[b] += other.w_[b];
    w2_[b] += other.w2_[b];
  }
  unbinned_w_ += other.unbinned_w_;
  unbinned_w2_ += other.unbinned_w2_;
}

namespace {
std::string join_ranges(const std::vector<BlockRange>& ranges) {
  std::string s;
  for (const BlockRange& r : ranges) s += (s.empty() ? "" : ", ") + r.to_string();
  return s;
}
}  // namespace

BlockRange merge_block_ranges(std::vector<BlockRange> parts, std::uint64_t total_blocks, bool require_complete) {
  if (parts.empty()) throw HistogramMergeError("nothing to merge");
  std::sort(parts.begin(), parts.end(), [](const BlockRange& a, const BlockRange& b) {
    return a.begin != b.begin ? a.begin < b.begin : a.end < b.end;
  });
  std::vector<BlockRange> repeated, missing;
  if (parts.front().begin > 0) missing.push_back({0, parts.front().begin});
  std::uint64_t covered = parts.front().end;
  for (std::size_t i = 1; i < parts.size(); ++i) {
    const BlockRange& p = parts[i];
    if (p.begin < covered) repeated.push_back({p.begin, std::min(covered, p.end)});
    else if (p.begin > covered) missing.push_back({covered, p.begin});
    covered = std::max(covered, p.end);
  }
  if (covered < total_blocks) missing.push_back({covered, total_blocks});
  if (!repeated.empty())
    throw HistogramMergeError(fmt::format("blocks {} are in more than one part", join_ranges(repeated)));
  const bool gap_inside = std::any_of(missing.begin(), missing.end(), [&](const BlockRange& m) {
    return m.begin > parts.front().begin && m.end < covered;
  });
  if (!missing.empty() && (require_complete || gap_inside))
    throw HistogramMergeError(fmt::format("blocks {} of [0, {}) are missing", join_ranges(missing), total_blocks));
  return {parts.front().begin, covered};
}

}  // namespace microsim
