// stats: a histogram as a value type. Per bin the sum of weights and the sum of squared weights (a count
// is weight 1, so counts are exact integers), plus the same for entries outside the binning; the
// binning's identity (its description, so that only histograms of one binning merge); and provenance:
// what produced it, with which seed, over which blocks of the measurement (core/block_runner.h).
//
// Sums are ExactSum: merging is exactly associative, so the merge of the shards of a run is the single
// run bit for bit, whatever the grouping. merge() refuses different binnings, different measurements and
// overlapping block ranges, with a message naming them; merge_partials() also names gaps.
#pragma once

#include "core/block_runner.h"
#include "core/exact_sum.h"

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace microsim {

struct HistogramMergeError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

// What a partial result is part of. Two partial results merge only when everything but `blocks` agrees.
struct Provenance {
  std::string producer;          // "trace vndf", "trace masking", ...
  std::string measurement;       // the parameters that define the run, canonically written (not the seed)
  std::uint64_t seed = 0;
  std::uint64_t total_blocks = 0;  // blocks of the whole run
  BlockRange blocks;               // the blocks this result holds

  bool complete() const { return blocks == BlockRange{0, total_blocks}; }
  bool operator==(const Provenance&) const = default;
  // Throws HistogramMergeError naming the first difference unless `other` is part of the same run.
  void check_same_run(const Provenance& other) const;
};

class Histogram {
public:
  Histogram() = default;
  Histogram(std::string binning_id, std::size_t bins) : binning_id_(std::move(binning_id)), w_(bins), w2_(bins) {}

  void add(std::size_t bin, double weight) {
    w_[bin].add(weight);
    w2_[bin].add(weight * weight);
  }
  void add_count(std::size_t bin, std::uint64_t n) {
    w_[bin].add_count(n);
    w2_[bin].add_count(n);
  }
  void add_unbinned(double weight) {
    unbinned_w_.add(weight);
    unbinned_w2_.add(weight * weight);
  }
  void add_unbinned_count(std::uint64_t n) {
    unbinned_w_.add_count(n);
    unbinned_w2_.add_count(n);
  }

  const std::string& binning_id() const { return binning_id_; }
  std::size_t size() const { return w_.size(); }
  double weight(std::size_t bin) const { return w_[bin].value(); }
  double weight_squared(std::size_t bin) const { return w2_[bin].value(); }
  double unbinned_weight() const { return unbinned_w_.value(); }
  const ExactSum& exact_weight(std::size_t bin) const { return w_[bin]; }
  const ExactSum& exact_weight_squared(std::size_t bin) const { return w2_[bin]; }
  const ExactSum& exact_unbinned_weight() const { return unbinned_w_; }
  const ExactSum& exact_unbinned_weight_squared() const { return unbinned_w2_; }
  // Adds exact sums to a bin, or to the entries outside the binning (a reader rebuilding a histogram
  // from the sums its file stores, stats/scatter_io.h).
  void add_sums(std::size_t bin, const ExactSum& w, const ExactSum& w2) {
    w_[bin] += w;
    w2_[bin] += w2;
  }
  void add_unbinned_sums(const ExactSum& w, const ExactSum& w2) {
    unbinned_w_ += w;
    unbinned_w2_ += w2;
  }
  // Every bin's weight as an integer count; throws std::domain_error unless the weights are counts.
  std::vector<std::uint64_t> counts() const;

  // Adds `other`'s sums; throws HistogramMergeError when the binnings differ.
  void merge(const Histogram& other);
  bool operator==(const Histogram&) const = default;

private:
  std::string binning_id_;
  std::vector<ExactSum> w_, w2_;
  ExactSum unbinned_w_, unbinned_w2_;
};

// The union of `parts` (block ranges of one run of `total_blocks` blocks, in any order). Throws
// HistogramMergeError naming every repeated (overlapping) range, and, when `require_complete`, every
// missing range; otherwise the parts must at least be contiguous.
BlockRange merge_block_ranges(std::vector<BlockRange> parts, std::uint64_t total_blocks, bool require_complete);

}  // namespace microsim
