// Scatter histograms and expectations in EXR files, and their JSON summaries (scatter_io.h).
#include "stats/scatter_io.h"
#include "stats/json_values.h"

#include "core/parse.h"
#include "core/strict_parse.h"
#include "microfacet/material.h"
#include "microgeom/exr_io.h"
#include "stats/exr_reading.h"
#include "stats/binning.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <optional>
#include <set>

namespace microsim {

namespace {

constexpr std::array<const char*, kScatterOrderBins> kOrderParts{"order1", "order2", "order3", "order4", "order5plus"};
constexpr std::array<const char*, 6> kSumLimbs{"hi0", "hi1", "hi2", "lo0", "lo1", "lo2"};
constexpr std::array<const char*, 3> kBitLimbs{"bits0", "bits1", "bits2"};
constexpr std::uint64_t kLimbMask = 0xffffff;  // 24 bits: an integer a float holds exactly
constexpr const char* kHistogramLayout =
    "cC.PART.w and .w2 (float: sums of weights and squared weights per bin; PART order1..order4, order5plus, "
    "total); cC.PART.w.hi0..2, .lo0..2 and cC.PART.w2.* (the exact 128-bit fixed-point sums, two 64-bit halves "
    "in 24-bit limbs, least significant first); pixel (x, y) = bin y * cols + x; channel names in attribute "
    "channel_names";
constexpr const char* kExpectationLayout =
    "cC.order1.expected (float: expected weight per launched path per bin) and cC.order1.expected.bits0..2 (the "
    "double's 64 bits in 24-bit limbs, least significant first); pixel (x, y) = bin y * cols + x";

std::string channel_prefix(int c, const char* part) { return fmt::format("c{}.{}", c, part); }

// The three 24-bit limbs of a 64-bit integer, least significant first, and back.
std::array<float, 3> limbs_of(std::uint64_t x) {
  return {float(x & kLimbMask), float((x >> 24) & kLimbMask), float(x >> 48)};
}

// ---- writing ---------------------------------------------------------------------------------------------

// A float channel and the limb channels of an exact quantity, added to an image.
struct ExactChannels {
  microgeom::ExrChannel* value = nullptr;
  std::vector<microgeom::ExrChannel*> limbs;
};

template <std::size_t N>
ExactChannels add_exact_channels(microgeom::ExrImage& image, const std::string& name, const std::array<const char*, N>& limbs) {
  ExactChannels e;
  e.value = &image.add_channel(name);
  for (const char* limb : limbs) e.limbs.push_back(&image.add_channel(name + "." + limb));
  return e;
}

void store_sum(ExactChannels& e, std::size_t i, const ExactSum& s) {
  e.value->data[i] = float(s.value());
  const std::array<float, 3> hi = limbs_of(s.high_bits()), lo = limbs_of(s.low_bits());
  for (std::size_t k = 0; k < 3; ++k) {
    e.limbs[k]->data[i] = hi[k];
    e.limbs[3 + k]->data[i] = lo[k];
  }
}

std::string sum_text(const ExactSum& s) { return fmt::format("{},{}", s.high_bits(), s.low_bits()); }

// The binning a result claims: a hemispheres binning whose upper half is the reflection side.
DirectionBinning checked_binning(const std::filesystem::path& path, const std::string& binning_id,
                                 const std::vector<bool>& reflection_bins) {
  const nlohmann::json d = nlohmann::json::parse(binning_id, nullptr, false);
  std::optional<DirectionBinning> b;
  try {
    if (d.is_object() && d.value("kind", "") == "hemispheres") b = DirectionBinning::from_description(d);
  } catch (const std::invalid_argument&) {
  }
  if (!b || b->describe().dump() != binning_id)
    throw ScatterIoError(fmt::format("scatter file '{}': the result's binning is not a hemispheres binning ({})",
                                     path.string(), quote_excerpt(binning_id)));
  for (std::size_t i = 0; i < reflection_bins.size(); ++i)
    if (reflection_bins.size() != std::size_t(b->size()) || reflection_bins[i] != (int(i) < b->size() / 2))
      throw ScatterIoError(fmt::format("scatter file '{}': reflection bins are not the upper hemisphere", path.string()));
  return *b;
}

microgeom::ExrImage scatter_image(const std::filesystem::path& path, const std::string& binning_id,
                                  const std::vector<bool>& reflection_bins, const std::vector<std::string>& channels,
                                  const std::map<std::string, std::string>& notes) {
  const DirectionBinning b = checked_binning(path, binning_id, reflection_bins);
  microgeom::ExrImage image;
  image.width = b.cols();
  image.height = b.rows();
  for (const auto& [key, value] : notes) {
    if (key.empty()) throw ScatterIoError(fmt::format("scatter file '{}': a note with an empty key", path.string()));
    image.attributes["note." + key] = value;
  }
  image.attributes["format"] = kScatterFormat;
  image.attributes["binning"] = binning_id;
  image.attributes["channel_names"] = nlohmann::json(channels).dump();
  return image;
}

void write_image(const std::filesystem::path& path, const microgeom::ExrImage& image) {
  try {
    microgeom::write_exr(path, image);
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    throw ScatterIoError(e.what());
  }
}

// The float of the total over orders, summed in order: the reader recomputes it the same way.
std::vector<double> total_over_orders(const ScatterHistogram& h, int c, bool squared) {
  std::vector<double> total(h.bins(), 0.0);
  for (int k = 0; k < kScatterOrderBins; ++k)
    for (std::size_t i = 0; i < h.bins(); ++i)
      total[i] += squared ? h.histogram(c, k).weight_squared(i) : h.histogram(c, k).weight(i);
  return total;
}

// One order of one channel: the exact per-bin sums and their floats, and the sums outside the bins.
void put_order(microgeom::ExrImage& image, const ScatterHistogram& h, int c, int k) {
  const std::string prefix = channel_prefix(c, kOrderParts[std::size_t(k)]);
  ExactChannels w = add_exact_channels(image, prefix + ".w", kSumLimbs);
  ExactChannels w2 = add_exact_channels(image, prefix + ".w2", kSumLimbs);
  const Histogram& o = h.histogram(c, k);
  for (std::size_t i = 0; i < h.bins(); ++i) {
    store_sum(w, i, o.exact_weight(i));
    store_sum(w2, i, o.exact_weight_squared(i));
  }
  image.attributes[prefix + ".unbinned.w"] = sum_text(o.exact_unbinned_weight());
  image.attributes[prefix + ".unbinned.w2"] = sum_text(o.exact_unbinned_weight_squared());
}

}  // namespace

void write_scatter_exr(const std::filesystem::path& path, const ScatterHistogram& h,
                       const std::map<std::string, std::string>& notes) {
  std::vector<bool> reflection(h.bins());
  for (std::size_t i = 0; i < h.bins(); ++i) reflection[i] = h.is_reflection_bin(i);
  std::vector<std::string> names;
  for (int c = 0; c < h.channels(); ++c) names.push_back(h.channel_name(c));
  microgeom::ExrImage image = scatter_image(path, h.binning_id(), reflection, names, notes);
  for (int c = 0; c < h.channels(); ++c) {
    for (int k = 0; k < kScatterOrderBins; ++k) put_order(image, h, c, k);
    const std::vector<double> total_w = total_over_orders(h, c, false), total_w2 = total_over_orders(h, c, true);
    auto& tw = image.add_channel(channel_prefix(c, "total") + ".w");
    auto& tw2 = image.add_channel(channel_prefix(c, "total") + ".w2");
    for (std::size_t i = 0; i < h.bins(); ++i) {
      tw.data[i] = float(total_w[i]);
      tw2.data[i] = float(total_w2[i]);
    }
    image.attributes[fmt::format("c{}.unfinished.w", c)] = sum_text(h.exact_unfinished(c, false));
    image.attributes[fmt::format("c{}.unfinished.w2", c)] = sum_text(h.exact_unfinished(c, true));
    image.attributes[fmt::format("c{}.lost.w", c)] = sum_text(h.exact_lost(c, false));
    image.attributes[fmt::format("c{}.lost.w2", c)] = sum_text(h.exact_lost(c, true));
  }
  const Provenance& p = h.provenance;
  image.attributes["kind"] = "histogram";
  image.attributes["paths"] = std::to_string(h.paths());
  image.attributes["producer"] = p.producer;
  image.attributes["measurement"] = p.measurement;
  image.attributes["seed"] = std::to_string(p.seed);
  image.attributes["total_blocks"] = std::to_string(p.total_blocks);
  image.attributes["blocks"] = fmt::format("{},{}", p.blocks.begin, p.blocks.end);
  image.attributes["partial"] = h.partial ? "true" : "false";
  image.attributes["channel_layout"] = kHistogramLayout;
  write_image(path, image);
}

void write_scatter_exr(const std::filesystem::path& path, const ScatterExpectation& e,
                       const std::map<std::string, std::string>& notes) {
  if (e.order1.size() != e.channel_names.size() || e.error_estimate.size() != e.channel_names.size())
    throw ScatterIoError(fmt::format("scatter file '{}': an expectation needs one order-1 lobe and one error estimate "
                                     "per channel", path.string()));
  microgeom::ExrImage image = scatter_image(path, e.binning_id, e.reflection_bins, e.channel_names, notes);
  for (int c = 0; c < e.channels(); ++c) {
    const std::vector<double>& lobe = e.order1[std::size_t(c)];
    if (lobe.size() != e.bins()) throw ScatterIoError(fmt::format("scatter file '{}': channel {} has {} bins, not {}",
                                                                  path.string(), c, lobe.size(), e.bins()));
    ExactChannels x = add_exact_channels(image, channel_prefix(c, "order1") + ".expected", kBitLimbs);
    for (std::size_t i = 0; i < lobe.size(); ++i) {
      x.value->data[i] = float(lobe[i]);
      const std::array<float, 3> limbs = limbs_of(std::bit_cast<std::uint64_t>(lobe[i]));
      for (std::size_t k = 0; k < 3; ++k) x.limbs[k]->data[i] = limbs[k];
    }
    image.attributes[fmt::format("c{}.error_estimate", c)] = fmt::format("{}", e.error_estimate[std::size_t(c)]);
  }
  image.attributes["kind"] = "expectation";
  image.attributes["producer"] = e.producer;
  image.attributes["measurement"] = e.measurement;
  image.attributes["channel_layout"] = kExpectationLayout;
  write_image(path, image);
}

// ---- reading -----------------------------------------------------------------------------------------------

namespace {

// The checks of one file, each naming the file, the attribute or channel, and the bad value.
class ScatterReader {
public:
  ScatterReader(const microgeom::ExrImage& image, const std::string& name) : image_(image), name_(name) {}

  ScatterFile read() {
    if (attr("format") != kScatterFormat)
      fail(fmt::format("attribute format = {} (expected {}): not a microsim scatter file", quote_excerpt(attr("format")),
                       kScatterFormat));
    ScatterFile f;
    const std::string& kind = attr("kind");
    if (kind != "histogram" && kind != "expectation")
      fail(fmt::format("attribute kind = {} is neither 'histogram' nor 'expectation'", quote_excerpt(kind)));
    f.kind = kind == "histogram" ? ScatterFileKind::histogram : ScatterFileKind::expectation;
    binning_ = read_binning();
    channel_names_ = read_channel_names();
    check_names(f.kind);
    if (f.kind == ScatterFileKind::histogram) f.histogram = read_histogram();
    else f.expectation = read_expectation();
    for (const auto& [key, value] : image_.attributes)
      if (key.rfind("note.", 0) == 0) f.notes[key.substr(5)] = value;
    return f;
  }

private:
  [[noreturn]] void fail(const std::string& why) const { throw ScatterIoError(fmt::format("'{}': {}", name_, why)); }

  const std::string& attr(const std::string& key) const {
    const auto it = image_.attributes.find(key);
    if (it == image_.attributes.end())
      fail(key == "format" ? "not a microsim scatter file: attribute 'format' is missing"
                           : fmt::format("attribute '{}' is missing", key));
    return it->second;
  }

  std::uint64_t count_attribute(const std::string& key) const {
    const std::optional<std::uint64_t> v = reader::parse_uint64(attr(key));
    if (!v) fail(fmt::format("attribute {} = {} is not a count (decimal digits only, at most 18446744073709551615)", key,
                             quote_excerpt(attr(key))));
    return *v;
  }

  // "HIGH,LOW": the two halves of an exact sum of non-negative terms (HIGH below 2^63).
  ExactSum sum_attribute(const std::string& key) const {
    const std::vector<std::string_view> f = reader::split_commas(attr(key));
    const auto hi = f.size() == 2 ? reader::parse_uint64(f[0]) : std::nullopt;
    const auto lo = f.size() == 2 ? reader::parse_uint64(f[1]) : std::nullopt;
    if (!hi || !lo || *hi >> 63)
      fail(fmt::format("attribute {} = {} is not an exact sum (HIGH,LOW: two decimal 64-bit halves, HIGH below 2^63)",
                       key, quote_excerpt(attr(key))));
    return ExactSum::from_bits(*hi, *lo);
  }

  DirectionBinning read_binning() const {
    const std::string& text = attr("binning");
    const nlohmann::json d = nlohmann::json::parse(text, nullptr, false);
    if (d.is_discarded() || !d.is_object() || d.value("kind", "") != "hemispheres")
      fail(fmt::format("attribute binning = {} is not the JSON description of a hemispheres binning", quote_excerpt(text)));
    std::optional<DirectionBinning> b;
    try {
      b = DirectionBinning::from_description(d);
    } catch (const std::invalid_argument& e) {
      fail(fmt::format("attribute binning: {}", std::string(e.what()).substr(0, 200)));
    }
    if (b->describe().dump() != text)
      fail(fmt::format("attribute binning = {} is not in its canonical form", quote_excerpt(text)));
    if (b->rows() != image_.height || b->cols() != image_.width)
      fail(fmt::format("attribute binning describes {} x {} bins but the image is {} x {}", b->rows(), b->cols(),
                       image_.height, image_.width));
    return *b;
  }

  std::vector<std::string> read_channel_names() const {
    const std::string& text = attr("channel_names");
    const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
    const bool ok = j.is_array() && !j.empty() && j.size() <= std::size_t(Material::kMaxChannels) &&
                    std::all_of(j.begin(), j.end(), [](const nlohmann::json& v) { return v.is_string(); });
    if (!ok)
      fail(fmt::format("attribute channel_names = {} is not a JSON array of 1 to {} names", quote_excerpt(text),
                       Material::kMaxChannels));
    return j.get<std::vector<std::string>>();
  }

  // The attribute keys and channel names of this kind of file, and a check that the file has exactly those
  // (plus notes).
  void check_names(ScatterFileKind kind) const {
    std::set<std::string> attributes{"format", "kind", "binning", "channel_names", "producer", "measurement", "channel_layout"};
    std::set<std::string> channels;
    for (int c = 0; c < int(channel_names_.size()); ++c) add_names(kind, c, attributes, channels);
    if (kind == ScatterFileKind::histogram)
      attributes.insert({"paths", "seed", "total_blocks", "blocks", "partial"});
    for (const auto& [key, value] : image_.attributes)
      if (!attributes.count(key) && key.rfind("note.", 0) != 0)
        fail(fmt::format("unknown attribute {} (not part of a {} scatter file with {} channels)", quote_excerpt(key),
                         kind == ScatterFileKind::histogram ? "histogram" : "expectation", channel_names_.size()));
    for (const auto& ch : image_.channels)
      if (!channels.erase(ch.name))
        fail(fmt::format("channel {} is not part of this scatter file (channel_names {})", quote_excerpt(ch.name),
                         quote_excerpt(attr("channel_names"))));
    if (!channels.empty()) fail(fmt::format("channel {} is missing", *channels.begin()));
  }

  static void add_names(ScatterFileKind kind, int c, std::set<std::string>& attributes, std::set<std::string>& channels) {
    auto add_exact = [&](const std::string& name, auto limbs) {
      channels.insert(name);
      for (const char* limb : limbs) channels.insert(name + "." + limb);
    };
    if (kind == ScatterFileKind::expectation) {
      add_exact(channel_prefix(c, "order1") + ".expected", kBitLimbs);
      attributes.insert(fmt::format("c{}.error_estimate", c));
      return;
    }
    for (const char* part : kOrderParts) {
      const std::string prefix = channel_prefix(c, part);
      add_exact(prefix + ".w", kSumLimbs);
      add_exact(prefix + ".w2", kSumLimbs);
      attributes.insert({prefix + ".unbinned.w", prefix + ".unbinned.w2"});
    }
    channels.insert({channel_prefix(c, "total") + ".w", channel_prefix(c, "total") + ".w2"});
    for (const char* what : {"unfinished", "lost"})
      attributes.insert({fmt::format("c{}.{}.w", c, what), fmt::format("c{}.{}.w2", c, what)});
  }

  const std::vector<float>& data(const std::string& channel) const { return image_.find(channel)->data; }

  // The 64-bit integer of three 24-bit limb channels at bin i (each an integer below 2^24, the last below 2^16).
  std::uint64_t limbs_at(const std::array<const std::vector<float>*, 3>& limbs, std::size_t i, const std::string& name) const {
    std::uint64_t x = 0;
    for (std::size_t k = 0; k < 3; ++k) {
      const float v = (*limbs[k])[i];
      const float top = k < 2 ? 16777216.0f : 65536.0f;
      if (!(v >= 0 && v < top && v == std::floor(v)))
        fail(fmt::format("channel {} has {} at bin {}: a limb must be an integer in [0, {})", name, v, i, top));
      x |= std::uint64_t(v) << (24 * k);
    }
    return x;
  }

  std::array<const std::vector<float>*, 3> limb_data(const std::string& name, std::size_t first,
                                                     const auto& limbs) const {
    return {&data(name + "." + limbs[first]), &data(name + "." + limbs[first + 1]), &data(name + "." + limbs[first + 2])};
  }

  // The exact per-bin sums of channel `name` (and its limbs); its float channel must be their value.
  std::vector<ExactSum> exact_sums(const std::string& name) const {
    const auto hi = limb_data(name, 0, kSumLimbs), lo = limb_data(name, 3, kSumLimbs);
    const std::vector<float>& value = data(name);
    std::vector<ExactSum> sums(value.size());
    for (std::size_t i = 0; i < sums.size(); ++i) {
      const std::uint64_t h = limbs_at(hi, i, name + ".hi*");
      if (h >> 63) fail(fmt::format("channel {}.hi2 at bin {}: the sum is negative (limb {})", name, i, (*hi[2])[i]));
      sums[i] = ExactSum::from_bits(h, limbs_at(lo, i, name + ".lo*"));
      if (value[i] != float(sums[i].value()))
        fail(fmt::format("channel {} = {} at bin {} disagrees with its exact sum {}", name, value[i], i, sums[i].value()));
    }
    return sums;
  }

  // The float channel `name` must be `expected` (a total over orders, recomputed).
  void check_floats(const std::string& name, const std::vector<double>& expected) const {
    const std::vector<float>& value = data(name);
    for (std::size_t i = 0; i < value.size(); ++i)
      if (value[i] != float(expected[i]))
        fail(fmt::format("channel {} = {} at bin {} is not the sum over orders {}", name, value[i], i, expected[i]));
  }

  ScatterHistogram empty_histogram() const {
    std::vector<bool> reflection(std::size_t(binning_.size()));
    for (int i = 0; i < binning_.size(); ++i) reflection[std::size_t(i)] = i < binning_.size() / 2;
    return ScatterHistogram(binning_.describe().dump(), std::size_t(binning_.size()), std::move(reflection), channel_names_);
  }

  Provenance read_provenance() const {
    Provenance p{attr("producer"), attr("measurement"), count_attribute("seed"), count_attribute("total_blocks"), {}};
    const std::vector<std::string_view> f = reader::split_commas(attr("blocks"));
    const auto begin = f.size() == 2 ? reader::parse_uint64(f[0]) : std::nullopt;
    const auto end = f.size() == 2 ? reader::parse_uint64(f[1]) : std::nullopt;
    if (!begin || !end || *begin > *end || *end > p.total_blocks)
      fail(fmt::format("attribute blocks = {} is not a block range BEGIN,END with BEGIN <= END <= total_blocks = {}",
                       quote_excerpt(attr("blocks")), p.total_blocks));
    p.blocks = {*begin, *end};
    return p;
  }

  void read_channel(ScatterHistogram& h, int c) const {
    for (int k = 0; k < kScatterOrderBins; ++k) {
      const std::string prefix = channel_prefix(c, kOrderParts[std::size_t(k)]);
      const std::vector<ExactSum> w = exact_sums(prefix + ".w"), w2 = exact_sums(prefix + ".w2");
      for (std::size_t i = 0; i < w.size(); ++i) h.add_sums(c, k, i, w[i], w2[i]);
      h.add_unbinned_sums(c, k, sum_attribute(prefix + ".unbinned.w"), sum_attribute(prefix + ".unbinned.w2"));
    }
    check_floats(channel_prefix(c, "total") + ".w", total_over_orders(h, c, false));
    check_floats(channel_prefix(c, "total") + ".w2", total_over_orders(h, c, true));
    h.add_unfinished_sums(c, sum_attribute(fmt::format("c{}.unfinished.w", c)),
                          sum_attribute(fmt::format("c{}.unfinished.w2", c)));
    h.add_lost_sums(c, sum_attribute(fmt::format("c{}.lost.w", c)), sum_attribute(fmt::format("c{}.lost.w2", c)));
  }

  ScatterHistogram read_histogram() const {
    ScatterHistogram h = empty_histogram();
    h.add_launched(count_attribute("paths"));
    h.provenance = read_provenance();
    const std::string& partial = attr("partial");
    if (partial != "true" && partial != "false")
      fail(fmt::format("attribute partial = {} is neither 'true' nor 'false'", quote_excerpt(partial)));
    h.partial = partial == "true";
    for (int c = 0; c < h.channels(); ++c) read_channel(h, c);
    return h;
  }

  // Channel c's expected weights per path: doubles read bit for bit, each finite and >= 0.
  std::vector<double> expected_lobe(int c) const {
    const std::string name = channel_prefix(c, "order1") + ".expected";
    const auto limbs = limb_data(name, 0, kBitLimbs);
    const std::vector<float>& value = data(name);
    std::vector<double> lobe(value.size());
    for (std::size_t i = 0; i < lobe.size(); ++i) {
      lobe[i] = std::bit_cast<double>(limbs_at(limbs, i, name + ".bits*"));
      if (!(std::isfinite(lobe[i]) && lobe[i] >= 0))
        fail(fmt::format("channel {} at bin {}: the expected weight {} is not finite and >= 0", name, i, lobe[i]));
      if (value[i] != float(lobe[i]))
        fail(fmt::format("channel {} = {} at bin {} disagrees with its exact value {}", name, value[i], i, lobe[i]));
    }
    return lobe;
  }

  ScatterExpectation read_expectation() const {
    ScatterExpectation e;
    e.binning_id = binning_.describe().dump();
    e.reflection_bins.resize(std::size_t(binning_.size()));
    for (int i = 0; i < binning_.size(); ++i) e.reflection_bins[std::size_t(i)] = i < binning_.size() / 2;
    e.channel_names = channel_names_;
    e.producer = attr("producer");
    e.measurement = attr("measurement");
    for (int c = 0; c < e.channels(); ++c) {
      e.order1.push_back(expected_lobe(c));
      const std::string key = fmt::format("c{}.error_estimate", c);
      const auto v = reader::parse_finite_double(attr(key));
      if (!v || *v < 0) fail(fmt::format("attribute {} = {} is not a finite number >= 0", key, quote_excerpt(attr(key))));
      e.error_estimate.push_back(*v);
    }
    return e;
  }

  const microgeom::ExrImage& image_;
  const std::string& name_;
  DirectionBinning binning_ = DirectionBinning::hemispheres(1);
  std::vector<std::string> channel_names_;
};

}  // namespace

ScatterFile scatter_from_exr(const microgeom::ExrImage& image, const std::string& name) {
  return ScatterReader(image, name).read();
}

bool is_scatter_image(const microgeom::ExrImage& image) {
  const auto it = image.attributes.find("format");
  return it != image.attributes.end() && it->second == kScatterFormat;
}

ScatterFile read_scatter_exr(const std::filesystem::path& path) {
  return scatter_from_exr(read_exr_or<ScatterIoError>(path), path.string());
}

// ---- JSON summaries -----------------------------------------------------------------------------------------

namespace {

// The binning's description as JSON (as text if it is none).
nlohmann::json binning_json(const std::string& id) {
  nlohmann::json j = nlohmann::json::parse(id, nullptr, false);
  return j.is_discarded() ? nlohmann::json(id) : j;
}

nlohmann::json sides_json(const ScatterHistogram& h, int c, int order_bin) {
  return {{"upper", estimate_json(h.albedo(c, order_bin, ScatterSide::reflected))},
          {"lower", estimate_json(h.albedo(c, order_bin, ScatterSide::transmitted))},
          {"both", estimate_json(h.albedo(c, order_bin, ScatterSide::both))}};
}

// Every path ends in exactly one place (a bin of one order, outside the bins, unfinished or lost): the sums of
// all of them are one per-path quantity, with its standard error.
nlohmann::json channel_summary(const ScatterHistogram& h, int c) {
  nlohmann::json albedo;
  ExactSum unbinned_w, unbinned_w2, all_w = h.exact_unfinished(c, false), all_w2 = h.exact_unfinished(c, true);
  all_w += h.exact_lost(c, false);
  all_w2 += h.exact_lost(c, true);
  for (int k = 0; k < kScatterOrderBins; ++k) {
    albedo[kOrderParts[std::size_t(k)]] = sides_json(h, c, k);
    const Histogram& o = h.histogram(c, k);
    unbinned_w += o.exact_unbinned_weight();
    unbinned_w2 += o.exact_unbinned_weight_squared();
    for (std::size_t i = 0; i < h.bins(); ++i) {
      all_w += o.exact_weight(i);
      all_w2 += o.exact_weight_squared(i);
    }
  }
  albedo["total"] = sides_json(h, c, -1);
  all_w += unbinned_w;
  all_w2 += unbinned_w2;
  return {{"name", h.channel_name(c)},
          {"albedo", albedo},
          {"unbinned", estimate_json(mean_per_path(unbinned_w.value(), unbinned_w2.value(), h.paths()))},
          {"unfinished", estimate_json(h.unfinished(c))},
          {"lost", estimate_json(h.lost(c))},
          {"energy", estimate_json(mean_per_path(all_w.value(), all_w2.value(), h.paths()))}};
}

}  // namespace

nlohmann::json scatter_summary_json(const ScatterHistogram& h) {
  const Provenance& p = h.provenance;
  nlohmann::json j{{"kind", "histogram"},
                   {"binning", binning_json(h.binning_id())},
                   {"paths", h.paths()},
                   {"partial", h.partial},
                   {"provenance",
                    {{"producer", p.producer},
                     {"measurement", p.measurement},
                     {"seed", p.seed},
                     {"total_blocks", p.total_blocks},
                     {"blocks", {p.blocks.begin, p.blocks.end}}}}};
  nlohmann::json channels = nlohmann::json::array();
  for (int c = 0; c < h.channels(); ++c) channels.push_back(channel_summary(h, c));
  j["channels"] = channels;
  return j;
}

nlohmann::json scatter_summary_json(const ScatterExpectation& e) {
  nlohmann::json j{{"kind", "expectation"},
                   {"binning", binning_json(e.binning_id)},
                   {"provenance", {{"producer", e.producer}, {"measurement", e.measurement}}}};
  nlohmann::json channels = nlohmann::json::array();
  for (int c = 0; c < e.channels(); ++c) {
    double r = 0, t = 0;
    for (std::size_t i = 0; i < e.bins(); ++i) (e.reflection_bins[i] ? r : t) += e.order1[std::size_t(c)][i];
    auto exact = [](double v) { return estimate_json({v, 0.0}); };
    channels.push_back({{"name", e.channel_names[std::size_t(c)]},
                        {"albedo", {{"order1", {{"upper", exact(r)}, {"lower", exact(t)}, {"both", exact(r + t)}}}}},
                        {"error_estimate", e.error_estimate[std::size_t(c)]}});
  }
  j["channels"] = channels;
  return j;
}

}  // namespace microsim
