#include "stats/histogram_io.h"

#include "core/atomic_file.h"
#include "microgeom/exr_io.h"
#include "stats/exr_reading.h"
#include "core/parse.h"
#include "core/strict_parse.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>

namespace microsim {

namespace {
constexpr const char* kFormat = "microsim-histogram-1";
constexpr double kTwo24 = 16777216.0;

}  // namespace

int TracedHistogram::find(BinningKind kind) const {
  for (std::size_t k = 0; k < binnings.size(); ++k) {
    if (binnings[k].kind() == kind) return int(k);
  }
  return -1;
}

void write_histogram_exr(const std::filesystem::path& path, const TracedHistogram& h) {
  if (h.binnings.empty()) throw HistogramIoError(fmt::format("histogram '{}': no binning to write", path.string()));
  if (h.counts.size() != h.binnings.size()) throw HistogramIoError("write_histogram_exr: counts/binnings mismatch");
  const int rows = h.binnings.front().rows(), cols = h.binnings.front().cols();
  microgeom::ExrImage image;
  image.width = cols;
  image.height = rows;
  std::string names;
  for (std::size_t k = 0; k < h.binnings.size(); ++k) {
    const DirectionBinning& b = h.binnings[k];
    if (b.rows() != rows) {
      throw HistogramIoError(fmt::format("histogram '{}': binnings must share the number of rows ({} vs {})",
                                         path.string(), b.rows(), rows));
    }
    if (h.counts[k].size() != std::size_t(b.size())) throw HistogramIoError("write_histogram_exr: count size mismatch");
    const std::string name = b.name();
    if (image.find(name + ".count")) throw HistogramIoError(fmt::format("histogram: two '{}' binnings", name));
    names += (k ? "," : "") + name;
    auto& count = image.add_channel(name + ".count");
    auto& high = image.add_channel(name + ".count_high");
    auto& low = image.add_channel(name + ".count_low");
    auto& err = image.add_channel(name + ".stderr");
    const double hits = double(h.hits);
    for (int i = 0; i < b.size(); ++i) {
      const std::uint64_t c = h.counts[k][std::size_t(i)];
      count.data[i] = float(c);
      high.data[i] = float(c >> 24);
      low.data[i] = float(c & 0xffffffu);
      const double p = hits > 0 ? double(c) / hits : 0.0;
      err.data[i] = float(std::sqrt(double(c) * std::max(0.0, 1.0 - p)));
    }
    if (k < h.probability.size() && h.probability[k].size() == std::size_t(b.size())) {
      auto& expected = image.add_channel(name + ".expected");
      for (int i = 0; i < b.size(); ++i) expected.data[i] = float(hits * h.probability[k][std::size_t(i)]);
    }
    image.attributes["binning." + name] = b.describe().dump();
  }
  for (const auto& [key, value] : h.attributes) image.attributes[key] = value;
  image.attributes["format"] = kFormat;
  image.attributes["binnings"] = names;
  image.attributes["rays"] = std::to_string(h.rays);
  image.attributes["hits"] = std::to_string(h.hits);
  image.attributes["partial"] = h.partial ? "true" : "false";
  image.attributes["channel_layout"] =
      "NAME.count (float), NAME.count_high * 16777216 + NAME.count_low (exact count), NAME.stderr (standard "
      "error of the count given hits), NAME.expected (hits x analytic D_v bin probability); pixel (x, y) = bin "
      "y * cols + x";
  try {
    microgeom::write_exr(path, image);
  } catch (const std::exception& e) {
    throw HistogramIoError(e.what());
  }
}

namespace {

// The checks of one file, each naming the file, the attribute or channel, and the bad value.
class HistogramReader {
public:
  HistogramReader(const microgeom::ExrImage& image, const std::string& name) : image_(image), name_(name) {}

  TracedHistogram read() {
    if (attr("format") != kFormat)
      fail(fmt::format("unsupported histogram format {} (expected {})", quote_excerpt(attr("format")), kFormat));
    TracedHistogram h;
    h.rays = count_attribute("rays");
    h.hits = count_attribute("hits");
    if (h.hits > h.rays) fail(fmt::format("attribute hits = {} is more than rays = {}", h.hits, h.rays));
    if (attr("partial") != "true" && attr("partial") != "false")
      fail(fmt::format("attribute partial = {} is neither 'true' nor 'false'", quote_excerpt(attr("partial"))));
    h.partial = attr("partial") == "true";
    const std::vector<std::string> names = binning_names();
    check_channels(names);
    for (const std::string& name : names) {
      DirectionBinning b = binning(name);
      std::vector<std::uint64_t> counts = exact_counts(b, h.hits);
      h.probability.push_back(probabilities(name, h.hits));
      h.binnings.push_back(std::move(b));
      h.counts.push_back(std::move(counts));
    }
    for (const auto& [key, value] : image_.attributes) {
      if (key.rfind("binning.", 0) == 0 || key == "format" || key == "binnings" || key == "rays" || key == "hits" ||
          key == "partial" || key == "channel_layout")
        continue;
      h.attributes[key] = value;
    }
    return h;
  }

private:
  [[noreturn]] void fail(const std::string& why) const {
    throw HistogramIoError(fmt::format("'{}': {}", name_, why));
  }

  const std::string& attr(const std::string& key) const {
    const auto it = image_.attributes.find(key);
    if (it == image_.attributes.end())
      throw HistogramIoError(fmt::format("'{}' is not a microsim histogram: attribute '{}' is missing", name_, key));
    return it->second;
  }

  std::uint64_t count_attribute(const std::string& key) const {
    const std::optional<std::uint64_t> v = reader::parse_uint64(attr(key));
    if (!v)
      fail(fmt::format("attribute {} = {} is not a count (decimal digits only, at most 18446744073709551615)", key,
                       quote_excerpt(attr(key))));
    return *v;
  }

  // The names listed in `binnings`: each known, none twice, at least one.
  std::vector<std::string> binning_names() const {
    const std::string& list = attr("binnings");
    std::vector<std::string> names;
    if (list.empty()) fail("attribute binnings is empty: the histogram has no binning");
    for (const std::string_view field : reader::split_commas(list)) {
      const std::string name(field);
      if (name != "sphere" && name != "lobe")
        fail(fmt::format("attribute binnings = {}: unknown binning {} (known: sphere, lobe)", quote_excerpt(list),
                         quote_excerpt(name)));
      if (std::find(names.begin(), names.end(), name) != names.end())
        fail(fmt::format("attribute binnings = {} names binning '{}' twice", quote_excerpt(list), name));
      names.push_back(name);
    }
    return names;
  }

  // Every channel is one of NAME.count, .count_high, .count_low, .stderr, .expected of a listed binning.
  void check_channels(const std::vector<std::string>& names) const {
    static const char* const kSuffixes[] = {".count", ".count_high", ".count_low", ".stderr", ".expected"};
    for (const auto& c : image_.channels) {
      bool known = false;
      for (const std::string& name : names)
        for (const char* suffix : kSuffixes) known = known || c.name == name + suffix;
      if (!known)
        fail(fmt::format("channel {} belongs to no binning of attribute binnings = {}", quote_excerpt(c.name),
                         quote_excerpt(attr("binnings"))));
    }
  }

  // binning.NAME, rebuilt; its rows and columns must be the image's.
  DirectionBinning binning(const std::string& name) const {
    const std::string key = "binning." + name;
    const nlohmann::json d = nlohmann::json::parse(attr(key), nullptr, false);
    if (d.is_discarded() || !d.is_object())
      fail(fmt::format("attribute {} = {} is not a JSON object", key, quote_excerpt(attr(key))));
    check_description(key, name, d);
    try {
      return DirectionBinning::from_description(d);
    } catch (const std::invalid_argument& e) {
      fail(fmt::format("attribute {}: {}", key, std::string(e.what()).substr(0, 200)));
    }
  }

  // What the histogram relies on in a binning description, checked before it is rebuilt.
  void check_description(const std::string& key, const std::string& name, const nlohmann::json& d) const {
    const auto integer_is = [&](const char* field, long long expected) {
      return d.contains(field) && d[field].is_number_integer() && d[field].get<long long>() == expected;
    };
    if (!(d.contains("kind") && d["kind"] == name))
      fail(fmt::format("attribute {} = {} does not describe a '{}' binning", key, quote_excerpt(attr(key)), name));
    if (!integer_is("rows", image_.height) || (d.contains("cols") && !integer_is("cols", image_.width)))
      fail(fmt::format("attribute {} = {}: rows and cols must be the image's {} and {}", key,
                       quote_excerpt(attr(key)), image_.height, image_.width));
    if (name != "lobe") return;
    const auto finite_numbers = [&](const char* field, std::size_t n) {
      if (!d.contains(field) || !d[field].is_array() || d[field].size() != n) return false;
      for (const auto& v : d[field])
        if (!v.is_number() || !std::isfinite(v.get<double>())) return false;
      return true;
    };
    if (!finite_numbers("alpha", 2) || !(d["alpha"][0].get<double>() > 0 && d["alpha"][1].get<double>() > 0) ||
        !finite_numbers("wi", 3) || !d.contains("domain") || !d["domain"].is_string())
      fail(fmt::format("attribute {}: needs alpha (2 positive numbers), wi (3 finite numbers) and domain", key));
  }

  const microgeom::ExrChannel& channel(const std::string& name) const {
    const auto* c = image_.find(name);
    if (!c) fail(fmt::format("channel {} is missing", name));
    return *c;
  }

  // count_high * 2^24 + count_low per bin; the sum of a binning's counts is at most hits.
  std::vector<std::uint64_t> exact_counts(const DirectionBinning& b, std::uint64_t hits) const {
    const std::string name = b.name();
    const auto& high = channel(name + ".count_high").data;
    const auto& low = channel(name + ".count_low").data;
    const auto* rounded = image_.find(name + ".count");
    std::vector<std::uint64_t> counts(std::size_t(b.size()));
    std::uint64_t total = 0;
    for (std::size_t i = 0; i < counts.size(); ++i) {
      const double hi = high[i], lo = low[i];
      if (!(hi >= 0 && lo >= 0 && lo < kTwo24 && hi < kTwo24 && hi == std::floor(hi) && lo == std::floor(lo)))
        fail(fmt::format("bin {} of {} has a count that is not a non-negative integer (count_high {}, count_low {})",
                         i, name, hi, lo));
      counts[i] = (std::uint64_t(hi) << 24) + std::uint64_t(lo);
      if (rounded && rounded->data[i] != float(counts[i]))
        fail(fmt::format("bin {} of {}: channel {}.count = {} disagrees with the exact count {}", i, name, name,
                         rounded->data[i], counts[i]));
      if (counts[i] > hits - total)  // total <= hits throughout: no overflow
        fail(fmt::format("the {} counts add up to more than the {} hits (attribute hits)", name, hits));
      total += counts[i];
    }
    return counts;
  }

  // NAME.expected / hits (empty when the channel is absent or there are no hits).
  std::vector<double> probabilities(const std::string& name, std::uint64_t hits) const {
    std::vector<double> probability;
    const auto* expected = image_.find(name + ".expected");
    if (!expected || hits == 0) return probability;
    for (std::size_t i = 0; i < expected->data.size(); ++i) {
      const float e = expected->data[i];
      if (!(std::isfinite(e) && e >= 0))
        fail(fmt::format("channel {}.expected has {} at bin {}: not a finite number >= 0", name, e, i));
      probability.push_back(double(e) / double(hits));
    }
    return probability;
  }

  const microgeom::ExrImage& image_;
  const std::string& name_;
};

}  // namespace

TracedHistogram histogram_from_exr(const microgeom::ExrImage& image, const std::string& name) {
  return HistogramReader(image, name).read();
}

TracedHistogram read_histogram_exr(const std::filesystem::path& path) {
  return histogram_from_exr(read_exr_or<HistogramIoError>(path), path.string());
}

bool is_traced_histogram_image(const microgeom::ExrImage& image) {
  const auto it = image.attributes.find("format");
  return it != image.attributes.end() && it->second == kFormat;
}

}  // namespace microsim
