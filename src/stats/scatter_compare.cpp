// Order-by-order comparison of two scattering results (scatter_compare.h).
#include "stats/scatter_compare.h"

#include "stats/binning.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <stdexcept>

namespace microsim {

std::string scatter_order_name(int order_bin) {
  if (order_bin == kTotalOrder) return "total";
  if (order_bin == kScatterOrderBins - 1) return fmt::format("order{}plus", kScatterOrderBins);
  return fmt::format("order{}", order_bin + 1);
}

namespace {

ScatterLobe histogram_lobe(const ScatterHistogram& h, int channel, int order_bin) {
  ScatterLobe lobe;
  lobe.mean.assign(h.bins(), 0.0);
  lobe.variance.assign(h.bins(), 0.0);
  const double n = double(h.paths());
  for (std::size_t i = 0; i < h.bins() && n > 0; ++i) {
    ExactSum w, w2;
    for (int k = 0; k < kScatterOrderBins; ++k) {
      if (order_bin != kTotalOrder && k != order_bin) continue;
      w += h.histogram(channel, k).exact_weight(i);
      w2 += h.histogram(channel, k).exact_weight_squared(i);
    }
    lobe.mean[i] = w.value() / n;
    lobe.variance[i] = w2.value() / (n * n);
  }
  lobe.albedo = h.albedo(channel, order_bin);
  return lobe;
}

double sum(const std::vector<double>& x) {
  double s = 0;
  for (double v : x) s += v;
  return s;
}

// Shape TV and its noise floor (NaN when a lobe is empty).
void shape_distance(const ScatterLobe& a, const ScatterLobe& b, LobeComparison& c) {
  const double sa = sum(a.mean), sb = sum(b.mean);
  if (!(sa > 0) || !(sb > 0)) {
    c.tv = c.tv_noise_floor = std::numeric_limits<double>::quiet_NaN();
    return;
  }
  double tv = 0, floor = 0;
  for (std::size_t i = 0; i < a.mean.size(); ++i) {
    tv += std::abs(a.mean[i] / sa - b.mean[i] / sb);
    floor += std::sqrt(a.variance[i] / (sa * sa) + b.variance[i] / (sb * sb));
  }
  c.tv = tv / 2;
  c.tv_noise_floor = floor / 2 * std::sqrt(2 / std::numbers::pi);
}

}  // namespace

std::optional<ScatterLobe> scatter_lobe(const ScatterFile& file, int channel, int order_bin) {
  if (file.kind == ScatterFileKind::histogram) return histogram_lobe(file.histogram, channel, order_bin);
  if (order_bin != 0) return std::nullopt;
  const ScatterExpectation& e = file.expectation;
  ScatterLobe lobe;
  lobe.mean = e.order1[std::size_t(channel)];
  lobe.variance.assign(lobe.mean.size(), 0.0);
  lobe.albedo = {sum(lobe.mean), 0.0};
  lobe.exact = true;
  return lobe;
}

double difference_p(const Estimate& a, const Estimate& b) {
  const double se = std::hypot(a.standard_error, b.standard_error), d = a.value - b.value;
  return se > 0 ? std::erfc(std::abs(d) / se / std::numbers::sqrt2) : (d == 0 ? 1.0 : 0.0);
}

ComparisonFamily comparison_family(const std::vector<const LobeComparison*>& lobes, double level) {
  ComparisonFamily f;
  f.tests = 2 * int(lobes.size());
  f.per_test = sidak_significance(level, f.tests);
  for (const LobeComparison* l : lobes) f.rejected = f.rejected || l->chi2->p_value < f.per_test || l->difference_p < f.per_test;
  return f;
}

LobeComparison compare_lobes(const ScatterLobe& a, const ScatterLobe& b, const ChiSquareOptions& options) {
  if (a.mean.size() != b.mean.size())
    throw std::invalid_argument(fmt::format("compare_lobes: lobes of {} and {} bins", a.mean.size(), b.mean.size()));
  LobeComparison c;
  shape_distance(a, b, c);
  c.albedo_a = a.albedo;
  c.albedo_b = b.albedo;
  c.difference = {a.albedo.value - b.albedo.value, std::hypot(a.albedo.standard_error, b.albedo.standard_error)};
  c.difference_p = difference_p(a.albedo, b.albedo);
  if (a.exact && b.exact) {
    c.insufficient = "both are exact expectations: there is nothing random to test";
  } else if (!(a.albedo.value > 0) || !(b.albedo.value > 0)) {
    c.insufficient = fmt::format("no weight in this order in {}", !(a.albedo.value > 0) ? "the first" : "the second");
  } else {
    try {
      c.chi2 = weighted_homogeneity(a.mean, a.variance, b.mean, b.variance, options);
    } catch (const InsufficientData& e) {
      c.insufficient = e.what();
    }
  }
  return c;
}

std::vector<double> shape_residuals(const ScatterLobe& a, const ScatterLobe& b, double min_effective) {
  const double sa = sum(a.mean), sb = sum(b.mean);
  std::vector<double> r(a.mean.size(), std::numeric_limits<double>::quiet_NaN());
  if (!(sa > 0) || !(sb > 0) || a.mean.size() != b.mean.size()) return r;
  const auto too_few = [&](const ScatterLobe& l, std::size_t i) {
    return !l.exact && (l.mean[i] == 0 || l.mean[i] * l.mean[i] < min_effective * l.variance[i]);
  };
  for (std::size_t i = 0; i < r.size(); ++i) {
    if (a.mean[i] == 0 && b.mean[i] == 0) r[i] = 0;
    else if (!too_few(a, i) && !too_few(b, i))
      r[i] = (a.mean[i] / sa - b.mean[i] / sb) / std::sqrt(a.variance[i] / (sa * sa) + b.variance[i] / (sb * sb));
  }
  return r;
}

namespace {

std::vector<std::string> channel_names(const ScatterFile& f) {
  if (f.kind == ScatterFileKind::expectation) return f.expectation.channel_names;
  std::vector<std::string> names;
  for (int c = 0; c < f.histogram.channels(); ++c) names.push_back(f.histogram.channel_name(c));
  return names;
}

// The options with cells named by the binning ("theta 12.3..15.6 phi ..."), unless they name them already.
ChiSquareOptions with_bin_names(ChiSquareOptions options, const std::string& binning_id) {
  const nlohmann::json d = nlohmann::json::parse(binning_id, nullptr, false);
  if (options.describe_cell || !d.is_object()) return options;
  try {
    const auto b = std::make_shared<const DirectionBinning>(DirectionBinning::from_description(d));
    options.describe_cell = [b](int bin) { return b->describe_bin(bin); };
  } catch (const std::invalid_argument&) {
  }
  return options;
}

const std::string& binning_of(const ScatterFile& f) {
  return f.kind == ScatterFileKind::expectation ? f.expectation.binning_id : f.histogram.binning_id();
}

}  // namespace

std::vector<LobeComparison> compare_scatter_files(const ScatterFile& a, const std::string& a_name, const ScatterFile& b,
                                                  const std::string& b_name, const ScatterComparisonOptions& options) {
  if (binning_of(a) != binning_of(b))
    throw std::invalid_argument(fmt::format("'{}' and '{}' have different binnings ({} vs {})", a_name, b_name,
                                            binning_of(a), binning_of(b)));
  const std::vector<std::string> ca = channel_names(a), cb = channel_names(b);
  if (ca.size() != cb.size())
    throw std::invalid_argument(fmt::format("'{}' has {} channels but '{}' has {}", a_name, ca.size(), b_name, cb.size()));
  const ChiSquareOptions chi2 = with_bin_names(options.chi2, binning_of(a));
  std::vector<LobeComparison> out;
  for (int c = 0; c < int(ca.size()); ++c)
    for (int k : options.order_bins) {
      const auto la = scatter_lobe(a, c, k), lb = scatter_lobe(b, c, k);
      if (!la || !lb) continue;
      LobeComparison r = compare_lobes(*la, *lb, chi2);
      r.channel = c;
      r.order_bin = k;
      out.push_back(std::move(r));
    }
  if (out.empty())
    throw std::invalid_argument(fmt::format("'{}' and '{}' share none of the orders to compare (an expectation models "
                                            "order 1 only)", a_name, b_name));
  return out;
}

}  // namespace microsim
