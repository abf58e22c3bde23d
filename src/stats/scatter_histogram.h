// stats: the result of a scattering measurement (explicit surfaces and the Smith random walk alike):
// the outgoing directions of the paths that left the surface, weighted per channel, histogrammed per
// bounce order (1, 2, 3, 4 and "5 and more") over one binning of the whole sphere (upper hemisphere =
// reflection, lower = transmission), plus the weight of the paths that did not leave (stopped at the
// order cap, or lost by the tracer), so that no energy is ever silently dropped.
//
// Every path leaves at most once, with one weight per channel: the per-path variance of any sum over
// orders and bins is the sum of the per-bin squared weights (Histogram's w2), which gives the standard
// error of every albedo (mean weight per launched path). Sums are ExactSum, so merge() of the shards of a
// run is the single run bit for bit; merge refuses other binnings, channels or runs (HistogramMergeError).
#pragma once

#include "core/estimate.h"
#include "stats/histogram.h"

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace microsim {

inline constexpr int kScatterOrderBins = 5;  // orders 1, 2, 3, 4 and 5+
// The order bin (0-based) of a bounce order >= 1.
inline int scatter_order_bin(int order) { return (order < kScatterOrderBins ? order : kScatterOrderBins) - 1; }

// The mean of per-path values whose sum is `w` and sum of squares `w2`, over `paths` paths (the ones
// that contributed nothing count as zeros); standard error sqrt((w2/n - mean^2) / (n - 1)), 0 for n < 2.
Estimate mean_per_path(double w, double w2, std::uint64_t paths);

enum class ScatterSide { reflected, transmitted, both };

class ScatterHistogram {
public:
  ScatterHistogram() = default;
  // `binning_id`: the binning's description (a binning of the whole sphere, bins in [0, bins));
  // reflection_bins[b]: bin b lies in the upper hemisphere; `channels`: the channel names.
  ScatterHistogram(std::string binning_id, std::size_t bins, std::vector<bool> reflection_bins,
                   std::vector<std::string> channels);

  // Paths launched (the denominator of every albedo).
  void add_launched(std::uint64_t n) { paths_ += n; }
  // A path that left the surface after `order` >= 1 facet events, into `bin`, with these per-channel weights.
  void add_escaped(int order, std::size_t bin, std::span<const double> weights);
  // A path that left into no bin (a direction the binning cannot place: counted, never dropped).
  void add_escaped_unbinned(int order, std::span<const double> weights);
  // A path stopped at the order cap with this weight still carried.
  void add_unfinished(std::span<const double> weights);
  // A path the tracer lost (a leak through the surface, an unresolved ray): its weight.
  void add_lost(std::span<const double> weights);

  int channels() const { return int(channel_names_.size()); }
  const std::string& channel_name(int c) const { return channel_names_[std::size_t(c)]; }
  const std::string& binning_id() const { return binning_id_; }
  std::size_t bins() const { return reflection_bins_.size(); }
  bool is_reflection_bin(std::size_t bin) const { return reflection_bins_[bin]; }
  std::uint64_t paths() const { return paths_; }
  const Histogram& histogram(int channel, int order_bin) const { return orders_[index(channel, order_bin)]; }

  // Albedo of one order bin (or of every order: order_bin = -1) on one side, per launched path.
  Estimate albedo(int channel, int order_bin, ScatterSide side = ScatterSide::both) const;
  Estimate unfinished(int channel) const;
  Estimate lost(int channel) const;

  // Adds `other`'s sums and paths; throws HistogramMergeError unless binning and channels agree.
  void merge(const ScatterHistogram& other);
  bool operator==(const ScatterHistogram&) const = default;

  Provenance provenance;  // what produced it, which blocks
  bool partial = false;   // cancelled before every block ran

private:
  std::size_t index(int channel, int order_bin) const { return std::size_t(channel) * kScatterOrderBins + std::size_t(order_bin); }
  std::string binning_id_;
  std::vector<bool> reflection_bins_;
  std::vector<std::string> channel_names_;
  std::vector<Histogram> orders_;            // [channel][order bin]
  std::vector<ExactSum> unfinished_w_, unfinished_w2_, lost_w_, lost_w2_;  // per channel
  std::uint64_t paths_ = 0;
};

}  // namespace microsim
