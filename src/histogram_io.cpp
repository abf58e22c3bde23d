#include "microsim/histogram_io.h"

#include "microgeom/atomic_file.h"
#include "microgeom/exr_io.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <sstream>

namespace microsim {

namespace {
constexpr const char* kFormat = "microsim-histogram-1";
constexpr double kTwo24 = 16777216.0;

std::vector<std::string> split_commas(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(item);
  return out;
}
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

TracedHistogram read_histogram_exr(const std::filesystem::path& path) {
  microgeom::ExrImage image;
  try {
    image = microgeom::read_exr(path);
  } catch (const std::exception& e) {
    throw HistogramIoError(e.what());
  }
  const auto attr = [&](const std::string& key) -> const std::string& {
    const auto it = image.attributes.find(key);
    if (it == image.attributes.end()) {
      throw HistogramIoError(fmt::format("'{}' is not a microsim histogram: attribute '{}' is missing", path.string(), key));
    }
    return it->second;
  };
  if (attr("format") != kFormat) {
    throw HistogramIoError(fmt::format("'{}': unsupported histogram format '{}' (expected {})", path.string(),
                                       attr("format"), kFormat));
  }
  TracedHistogram h;
  try {
    h.rays = std::stoull(attr("rays"));
    h.hits = std::stoull(attr("hits"));
  } catch (const std::logic_error&) {
    throw HistogramIoError(fmt::format("'{}': malformed rays/hits attributes", path.string()));
  }
  h.partial = attr("partial") == "true";
  for (const std::string& name : split_commas(attr("binnings"))) {
    DirectionBinning b = DirectionBinning::sphere(1);
    try {
      b = DirectionBinning::from_description(nlohmann::json::parse(attr("binning." + name)));
    } catch (const nlohmann::json::exception& e) {
      throw HistogramIoError(fmt::format("'{}': malformed binning.{}: {}", path.string(), name, e.what()));
    } catch (const std::invalid_argument& e) {
      throw HistogramIoError(fmt::format("'{}': malformed binning.{}: {}", path.string(), name, e.what()));
    }
    if (b.name() != name || b.cols() != image.width || b.rows() != image.height) {
      throw HistogramIoError(fmt::format("'{}': binning '{}' ({} x {}) does not match the image ({} x {})",
                                         path.string(), name, b.rows(), b.cols(), image.height, image.width));
    }
    const auto* high = image.find(name + ".count_high");
    const auto* low = image.find(name + ".count_low");
    if (!high || !low) throw HistogramIoError(fmt::format("'{}': channels {}.count_high/low are missing", path.string(), name));
    std::vector<std::uint64_t> counts(std::size_t(b.size()));
    std::uint64_t total = 0;
    for (int i = 0; i < b.size(); ++i) {
      const double hi = high->data[std::size_t(i)], lo = low->data[std::size_t(i)];
      if (!(hi >= 0 && lo >= 0 && lo < kTwo24 && hi < kTwo24 && hi == std::floor(hi) && lo == std::floor(lo))) {
        throw HistogramIoError(fmt::format("'{}': bin {} of {} has a count that is not a non-negative integer",
                                           path.string(), i, name));
      }
      counts[std::size_t(i)] = (std::uint64_t(hi) << 24) + std::uint64_t(lo);
      total += counts[std::size_t(i)];
    }
    if (total > h.hits) {
      throw HistogramIoError(fmt::format("'{}': the {} counts add up to {}, more than the {} hits", path.string(), name,
                                         total, h.hits));
    }
    std::vector<double> probability;
    if (const auto* expected = image.find(name + ".expected"); expected && h.hits > 0) {
      for (float e : expected->data) probability.push_back(double(e) / double(h.hits));
    }
    h.binnings.push_back(std::move(b));
    h.counts.push_back(std::move(counts));
    h.probability.push_back(std::move(probability));
  }
  if (h.binnings.empty()) throw HistogramIoError(fmt::format("'{}': the histogram has no binning", path.string()));
  for (const auto& [key, value] : image.attributes) {
    if (key.rfind("binning.", 0) == 0 || key == "format" || key == "binnings" || key == "rays" || key == "hits" ||
        key == "partial" || key == "channel_layout")
      continue;
    h.attributes[key] = value;
  }
  return h;
}

void check_writable(const std::filesystem::path& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (path.empty()) throw HistogramIoError("output path is empty");
  if (fs::is_directory(path, ec)) throw HistogramIoError(fmt::format("output '{}' is a directory", path.string()));
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  if (!fs::is_directory(dir, ec)) {
    throw HistogramIoError(fmt::format("cannot write '{}': directory '{}' does not exist", path.string(), dir.string()));
  }
  try {
    const microgeom::TemporaryFile probe(path);  // a new file beside `path`, removed again
  } catch (const microgeom::FileWriteError&) {
    throw HistogramIoError(fmt::format("cannot write '{}': directory '{}' is not writable", path.string(), dir.string()));
  }
  // An existing file at `path` is replaced by rename(), which needs only the directory to be writable.
}

}  // namespace microsim

namespace microsim {
void write_text_atomically(const std::filesystem::path& path, const std::string& text) {
  try {
    microgeom::write_file_atomically(path, text);
  } catch (const microgeom::FileWriteError& e) {
    throw HistogramIoError(e.what());
  }
}
}  // namespace microsim
