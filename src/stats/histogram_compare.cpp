// Two traced direction histograms compared binning by binning (histogram_compare.h).
#include "stats/histogram_compare.h"

#include "stats/scatter_histogram.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <stdexcept>

namespace microsim {

ScatterLobe traced_lobe(const TracedHistogram& h, int index) {
  const std::vector<std::uint64_t>& counts = h.counts[std::size_t(index)];
  const double n = double(h.rays);
  ScatterLobe lobe;
  lobe.mean.assign(counts.size(), 0.0);
  lobe.variance.assign(counts.size(), 0.0);
  for (std::size_t i = 0; i < counts.size() && n > 0; ++i) {
    lobe.mean[i] = double(counts[i]) / n;
    lobe.variance[i] = double(counts[i]) / (n * n);
  }
  lobe.albedo = mean_per_path(double(h.hits), double(h.hits), h.rays);
  return lobe;
}

std::vector<TracedComparison> compare_traced_histograms(const TracedHistogram& a, const std::string& a_name,
                                                        const TracedHistogram& b, const std::string& b_name,
                                                        const ChiSquareOptions& options) {
  std::vector<TracedComparison> out;
  for (std::size_t i = 0; i < a.binnings.size(); ++i) {
    const int j = b.find(a.binnings[i].kind());
    if (j < 0 || a.binnings[i].describe() != b.binnings[std::size_t(j)].describe()) continue;
    out.push_back({a.binnings[i].name(), compare_lobes(traced_lobe(a, int(i)), traced_lobe(b, j), options)});
  }
  if (out.empty())
    throw std::invalid_argument(fmt::format("'{}' and '{}' share no binning (the same kind, rows and, for the lobe "
                                            "binning, the same alpha and view): trace both with the same --rows",
                                            a_name, b_name));
  return out;
}

}  // namespace microsim
