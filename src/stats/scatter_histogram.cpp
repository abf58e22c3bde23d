#include "stats/scatter_histogram.h"

#include <fmt/core.h>

#include <cmath>

namespace microsim {

Estimate mean_per_path(double w, double w2, std::uint64_t paths) {
  if (paths == 0) return {};
  const double n = double(paths), mean = w / n;
  if (paths < 2) return {mean, 0.0};
  return {mean, std::sqrt(std::max(w2 / n - mean * mean, 0.0) / (n - 1.0))};
}

ScatterHistogram::ScatterHistogram(std::string binning_id, std::size_t bins, std::vector<bool> reflection_bins,
                                   std::vector<std::string> channels)
    : binning_id_(std::move(binning_id)), reflection_bins_(std::move(reflection_bins)),
      channel_names_(std::move(channels)) {
  if (reflection_bins_.size() != bins) {
    throw std::invalid_argument(fmt::format("ScatterHistogram: {} bin sides for {} bins", reflection_bins_.size(), bins));
  }
  if (channel_names_.empty()) throw std::invalid_argument("ScatterHistogram: no channels");
  orders_.assign(channel_names_.size() * kScatterOrderBins, Histogram(binning_id_, bins));
  unfinished_w_.assign(channel_names_.size(), {});
  unfinished_w2_ = lost_w_ = lost_w2_ = unfinished_w_;
}

void ScatterHistogram::add_escaped(int order, std::size_t bin, std::span<const double> weights) {
  const int k = scatter_order_bin(order);
  for (int c = 0; c < channels(); ++c) orders_[index(c, k)].add(bin, weights[std::size_t(c)]);
}

void ScatterHistogram::add_escaped_unbinned(int order, std::span<const double> weights) {
  const int k = scatter_order_bin(order);
  for (int c = 0; c < channels(); ++c) orders_[index(c, k)].add_unbinned(weights[std::size_t(c)]);
}

void ScatterHistogram::add_unfinished(std::span<const double> weights) {
  for (std::size_t c = 0; c < channel_names_.size(); ++c) {
    unfinished_w_[c].add(weights[c]);
    unfinished_w2_[c].add(weights[c] * weights[c]);
  }
}

void ScatterHistogram::add_lost(std::span<const double> weights) {
  for (std::size_t c = 0; c < channel_names_.size(); ++c) {
    lost_w_[c].add(weights[c]);
    lost_w2_[c].add(weights[c] * weights[c]);
  }
}

Estimate ScatterHistogram::albedo(int channel, int order_bin, ScatterSide side) const {
  ExactSum w, w2;
  for (int k = 0; k < kScatterOrderBins; ++k) {
    if (order_bin >= 0 && k != order_bin) continue;
    const Histogram& h = histogram(channel, k);
    for (std::size_t b = 0; b < h.size(); ++b) {
      if (side != ScatterSide::both && reflection_bins_[b] != (side == ScatterSide::reflected)) continue;
      w += h.exact_weight(b);
      w2 += h.exact_weight_squared(b);
    }
  }
  return mean_per_path(w.value(), w2.value(), paths_);
}

Estimate ScatterHistogram::unfinished(int channel) const {
  return mean_per_path(unfinished_w_[std::size_t(channel)].value(), unfinished_w2_[std::size_t(channel)].value(), paths_);
}

Estimate ScatterHistogram::lost(int channel) const {
  return mean_per_path(lost_w_[std::size_t(channel)].value(), lost_w2_[std::size_t(channel)].value(), paths_);
}

void ScatterHistogram::merge(const ScatterHistogram& other) {
  if (other.binning_id_ != binning_id_ || other.reflection_bins_ != reflection_bins_) {
    throw HistogramMergeError(fmt::format("different binnings: {} vs {}", binning_id_, other.binning_id_));
  }
  if (other.channel_names_ != channel_names_) {
    throw HistogramMergeError(fmt::format("different channels: {} vs {}", channel_names_.size(), other.channel_names_.size()));
  }
  for (std::size_t i = 0; i < orders_.size(); ++i) orders_[i].merge(other.orders_[i]);
  for (std::size_t c = 0; c < channel_names_.size(); ++c) {
    unfinished_w_[c] += other.unfinished_w_[c];
    unfinished_w2_[c] += other.unfinished_w2_[c];
    lost_w_[c] += other.lost_w_[c];
    lost_w2_[c] += other.lost_w2_[c];
  }
  paths_ += other.paths_;
}

}  // namespace microsim
