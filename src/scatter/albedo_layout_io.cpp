#include "scatter/albedo_layout_io.h"
#include "scatter/albedo_table_io.h"

#include "core/parse.h"
#include "core/strict_parse.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>

namespace microsim {

namespace {

std::string layout_number(double x) { return fmt::format("{:.17g}", x); }

std::string layout_joined(const std::vector<double>& values) {
  std::string s;
  for (const double v : values) {
    if (!s.empty()) s += ',';
    s += layout_number(v);
  }
  return s;
}

const char* column_axis(const AlbedoLayout& l) { return l.mu_rows ? "roughness" : "mu"; }
const char* row_axis(const AlbedoLayout& l) { return l.mu_rows ? "mu" : "roughness"; }
const char* roughness_name(const AlbedoLayout& l) { return l.roughness_is_alpha ? "alpha" : "sqrt(alpha)"; }

// Calls f(ri, mj, storage index) for every node in storage order.
template <class F> void for_storage(const LayoutTable& t, const F& f) {
  const std::size_t nr = t.alphas.size(), nm = t.mus.size();
  for (std::size_t k = 0; k < nr * nm; ++k) {
    const std::size_t row = k / std::size_t(layout_columns(t.layout)), col = k % std::size_t(layout_columns(t.layout));
    const std::size_t ri = t.layout.mu_rows ? col : row, mj = t.layout.mu_rows ? row : col;
    f(ri, mj, k);
  }
}

// The grazing channel (AlbedoLayout::grazing_quantity) as "<quantity>.value", ".error" and ".encoded".
void add_grazing_channels(microgeom::ExrImage& image, const LayoutTable& t) {
  const std::string& q = t.layout.grazing_quantity;
  auto& value = image.add_channel(q + ".value");
  auto& error = image.add_channel(q + ".error");
  auto& encoded = image.add_channel(q + ".encoded");
  for_storage(t, [&](std::size_t ri, std::size_t mj, std::size_t k) {
    const Estimate& e = t.grazing[ri * t.mus.size() + mj];
    value.data[k] = float(e.value);
    error.data[k] = float(e.standard_error);
    encoded.data[k] = float(encode_layout_value(t.layout.encoding, e.value));
  });
}

// One value in the layout's binary encoding (float32: 4 bytes, half and unorm16: 2; little-endian).
void append_encoded(std::string& s, LayoutEncoding enc, double v) {
  unsigned char bytes[4];
  std::size_t n = 2;
  if (enc == LayoutEncoding::float32) {
    const auto bits = std::bit_cast<std::uint32_t>(float(v));
    for (int b = 0; b < 4; ++b) bytes[b] = static_cast<unsigned char>(bits >> (8 * b));
    n = 4;
  } else {
    const std::uint16_t bits =
        enc == LayoutEncoding::half ? half_bits(v) : std::uint16_t(std::nearbyint(std::clamp(v, 0.0, 1.0) * 65535));
    bytes[0] = static_cast<unsigned char>(bits & 0xff);
    bytes[1] = static_cast<unsigned char>(bits >> 8);
  }
  s.append(reinterpret_cast<const char*>(bytes), n);
}

}  // namespace

microgeom::ExrImage layout_table_exr(const LayoutTable& t) {
  microgeom::ExrImage image;
  image.width = layout_columns(t.layout);
  image.height = layout_rows(t.layout);
  auto& value = image.add_channel("E.value");
  auto& error = image.add_channel("E.error");
  auto& encoded = image.add_channel("E.encoded");
  for_storage(t, [&](std::size_t ri, std::size_t mj, std::size_t k) {
    const Estimate& e = t.cells[ri * t.mus.size() + mj];
    value.data[k] = float(e.value);
    error.data[k] = float(e.standard_error);
    encoded.data[k] = float(encode_layout_value(t.layout.encoding, e.value));
  });
  if (t.layout.has_grazing()) add_grazing_channels(image, t);
  image.attributes = {{"kind", kAlbedoLayoutKind}, {"layout", t.layout.name}, {"ndf", to_string(t.ndf)},
                      {"source", t.layout.source},
                      {"quantity", t.layout.quantity}, {"encoding", to_string(t.layout.encoding)},
                      {"columns", column_axis(t.layout)}, {"rows", row_axis(t.layout)},
                      {"roughness_axis", roughness_name(t.layout)}, {"roughness", layout_joined(t.roughness)},
                      {"alphas", layout_joined(t.alphas)}, {"mus", layout_joined(t.mus)}, {"tolerance", layout_number(t.tolerance)},
                      {"interpolation_max_abs", layout_number(t.interpolation.max_abs)},
                      {"interpolation_rms", layout_number(t.interpolation.rms)}};
  std::string in_range;
  for (const bool in : t.in_range) in_range += (in_range.empty() ? "" : ",") + std::string(in ? "1" : "0");
  image.attributes["roughness_in_reference_range"] = in_range;
  if (t.layout.has_grazing()) {
    image.attributes["grazing_quantity"] = t.layout.grazing_quantity;
    image.attributes["grazing_interpolation_max_abs"] = layout_number(t.grazing_interpolation.max_abs);
    image.attributes["grazing_interpolation_rms"] = layout_number(t.grazing_interpolation.rms);
  }
  if (!t.average.empty()) {
    image.attributes["E_avg"] = layout_joined(estimate_values(t.average, false));
    image.attributes["E_avg_error"] = layout_joined(estimate_values(t.average, true));
  }
  return image;
}

std::string layout_table_csv(const LayoutTable& t) {
  const bool avg = !t.average.empty(), grazing = t.layout.has_grazing();
  std::string s = std::string("x,y,roughness,alpha,mu,E,E_error,E_encoded") +
                  (grazing ? ",E_grazing,E_grazing_error,E_grazing_encoded" : "") + (avg ? ",E_avg,E_avg_error" : "") + "\n";
  s += fmt::format("# microsim albedo layout {}: {}\n# source: {}\n", t.layout.name, t.layout.summary, t.layout.source);
  s += fmt::format("# x: {} index, y: {} index; roughness = {}; encoding {}\n", column_axis(t.layout),
                   row_axis(t.layout), roughness_name(t.layout), to_string(t.layout.encoding));
  s += fmt::format("# E: analytic single scattering of a {} mirror (F = 1), E_error its quadrature error estimate "
                   "(tolerance {})\n", t.ndf == NdfKind::ggx ? "GGX" : "Beckmann", layout_number(t.tolerance));
  if (grazing)
    s += fmt::format("# E_grazing: the same weighted by Schlick's grazing term (1 - VoH)^5 ({}; E is {})\n",
                     t.layout.grazing_quantity, t.layout.quantity);
  std::size_t outside = 0;
  for (const bool in : t.in_range) outside += !in;
  if (outside > 0)
    s += fmt::format("# the first {} roughness node(s) have alpha below 1e-4: E there is the reference at alpha 1e-4 "
                     "(microsim's {} clamps alpha)\n", outside, t.ndf == NdfKind::ggx ? "GGX" : "Beckmann");
  for_storage(t, [&](std::size_t ri, std::size_t mj, std::size_t k) {
    const Estimate& e = t.cells[ri * t.mus.size() + mj];
    const std::size_t x = k % std::size_t(layout_columns(t.layout)), y = k / std::size_t(layout_columns(t.layout));
    s += fmt::format("{},{},{},{},{},{},{},{}", x, y, layout_number(t.roughness[ri]), layout_number(t.alphas[ri]), layout_number(t.mus[mj]),
                     layout_number(e.value), layout_number(e.standard_error), layout_number(encode_layout_value(t.layout.encoding, e.value)));
    if (grazing) {
      const Estimate& g = t.grazing[ri * t.mus.size() + mj];
      s += fmt::format(",{},{},{}", layout_number(g.value), layout_number(g.standard_error),
                       layout_number(encode_layout_value(t.layout.encoding, g.value)));
    }
    if (avg) s += fmt::format(",{},{}", layout_number(t.average[ri].value), layout_number(t.average[ri].standard_error));
    s += "\n";
  });
  return s;
}

std::string layout_table_encoded(const LayoutTable& t) {
  std::string s;
  const LayoutEncoding enc = t.layout.encoding;
  for_storage(t, [&](std::size_t ri, std::size_t mj, std::size_t k) {
    const double v = t.cells[ri * t.mus.size() + mj].value;
    if (enc == LayoutEncoding::six_decimals) {
      s += fmt::format("{:.6f}", v);
      s += (k + 1) % std::size_t(layout_columns(t.layout)) == 0 ? "\n" : ",";
      return;
    }
    if (t.layout.has_grazing()) append_encoded(s, enc, t.grazing[ri * t.mus.size() + mj].value);  // R, then G
    append_encoded(s, enc, v);
  });
  return s;
}

std::string layout_centres_csv(const LayoutTable& t) {
  std::string s = "roughness_index,mu_index,alpha,mu,reference,reference_error,bilinear,error\n";
  s += fmt::format("# microsim albedo layout {}: bilinear interpolation of the nodes at each cell centre\n", t.layout.name);
  const std::size_t cm = t.mus.size() - 1;
  for (std::size_t k = 0; k < t.centres.size(); ++k) {
    const std::size_t i = k / cm, j = k % cm;
    const double alpha = layout_alpha(t.layout, layout_coordinate(t.layout.roughness, double(i) + 0.5));
    const double mu = layout_coordinate(t.layout.mu, double(j) + 0.5);
    const double e = t.interpolation.errors[k];
    s += fmt::format("{},{},{},{},{},{},{},{}\n", i, j, layout_number(alpha), layout_number(mu), layout_number(t.centres[k].value),
                     layout_number(t.centres[k].standard_error), layout_number(t.centres[k].value + e), layout_number(e));
  }
  return s;
}

nlohmann::json layout_table_json(const LayoutTable& t) {
  nlohmann::json j{{"kind", kAlbedoLayoutKind}, {"layout", t.layout.name}, {"ndf", to_string(t.ndf)},
                   {"summary", t.layout.summary},
                   {"source", t.layout.source}, {"quantity", t.layout.quantity},
                   {"encoding", to_string(t.layout.encoding)}, {"columns", column_axis(t.layout)},
                   {"rows", row_axis(t.layout)}, {"roughness_axis", roughness_name(t.layout)},
                   {"roughness", t.roughness}, {"alphas", t.alphas}, {"mus", t.mus}, {"tolerance", t.tolerance},
                   {"seconds", t.seconds}};
  j["E"] = estimate_rows_json(t.cells, t.mus.size());  // [roughness][mu]
  if (t.layout.has_grazing()) {
    j["E_grazing"] = estimate_rows_json(t.grazing, t.mus.size());
    j["E_grazing"]["quantity"] = t.layout.grazing_quantity;
  }
  if (!t.average.empty()) j["E_avg"] = {{"value", estimate_values(t.average, false)}, {"error", estimate_values(t.average, true)}};
  const InterpolationError& e = t.interpolation;
  j["interpolation"] = {{"max_abs", e.max_abs}, {"rms", e.rms}, {"worst_alpha", e.worst_alpha}, {"worst_mu", e.worst_mu}};
  return j;
}

std::vector<double> layout_values_from_exr(const microgeom::ExrImage& image, const AlbedoLayout& l) {
  if (image.width != layout_columns(l) || image.height != layout_rows(l))
    throw std::invalid_argument(fmt::format("a {} x {} image; the {} layout is {} x {}", image.width, image.height,
                                            l.name, layout_columns(l), layout_rows(l)));
  const microgeom::ExrChannel* c = image.find("E.value");
  if (c == nullptr && image.channels.size() == 1) c = &image.channels.front();
  if (c == nullptr) c = image.find("G");
  if (c == nullptr) {
    std::string names;
    for (const auto& ch : image.channels) names += (names.empty() ? "" : ", ") + ch.name;
    throw std::invalid_argument(fmt::format("no E.value channel, no single channel and no G channel (channels: {})", names));
  }
  return std::vector<double>(c->data.begin(), c->data.end());
}

namespace {

std::size_t csv_column(const std::vector<std::string_view>& header, std::string_view name) {
  for (std::size_t i = 0; i < header.size(); ++i)
    if (header[i] == name) return i;
  throw std::invalid_argument(fmt::format("the CSV has no column '{}' (a table microsim wrote for a layout has "
                                          "x, y and E)", name));
}

}  // namespace

std::vector<double> layout_values_from_csv(std::string_view text, const AlbedoLayout& l, std::string_view column) {
  std::istringstream in{std::string(text)};
  std::string header_line, line;
  if (!std::getline(in, header_line)) throw std::invalid_argument("an empty CSV");
  if (!header_line.empty() && header_line.back() == '\r') header_line.pop_back();
  const std::vector<std::string_view> header = reader::split_commas(header_line);
  const std::size_t cx = csv_column(header, "x"), cy = csv_column(header, "y"), ce = csv_column(header, column);
  const std::size_t w = std::size_t(layout_columns(l)), h = std::size_t(layout_rows(l));
  std::vector<double> values(w * h, std::nan(""));
  std::size_t seen = 0, number_of_line = 1;
  while (std::getline(in, line)) {
    ++number_of_line;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line.front() == '#') continue;
    const std::vector<std::string_view> f = reader::split_commas(line);
    if (f.size() != header.size())
      throw std::invalid_argument(fmt::format("line {}: {} fields, the header has {}", number_of_line, f.size(), header.size()));
    const std::string what = fmt::format("line {}", number_of_line);
    const auto x = std::size_t(parse_uint(what + " x", f[cx], 0, w - 1));
    const auto y = std::size_t(parse_uint(what + " y", f[cy], 0, h - 1));
    if (!std::isnan(values[y * w + x])) throw std::invalid_argument(fmt::format("{}: cell ({}, {}) given twice", what, x, y));
    values[y * w + x] = parse_double(fmt::format("{} {}", what, column), f[ce]);
    ++seen;
  }
  if (seen != w * h)
    throw std::invalid_argument(fmt::format("{} cells in the CSV; the {} layout has {}", seen, l.name, w * h));
  return values;
}

std::vector<double> layout_grazing_values_from_exr(const microgeom::ExrImage& image, const AlbedoLayout& l) {
  if (!l.has_grazing()) return {};
  if (image.width != layout_columns(l) || image.height != layout_rows(l))
    throw std::invalid_argument(fmt::format("a {} x {} image; the {} layout is {} x {}", image.width, image.height,
                                            l.name, layout_columns(l), layout_rows(l)));
  const microgeom::ExrChannel* c = image.find(l.grazing_quantity + ".value");
  if (c == nullptr && image.find("G") != nullptr) c = image.find("R");
  if (c == nullptr) return {};
  return std::vector<double>(c->data.begin(), c->data.end());
}

std::vector<double> layout_grazing_values_from_csv(std::string_view text, const AlbedoLayout& l) {
  if (!l.has_grazing()) return {};
  const std::string_view header = text.substr(0, text.find('\n'));
  for (const std::string_view name : reader::split_commas(header))
    if (name == "E_grazing" || name == "E_grazing\r") return layout_values_from_csv(text, l, "E_grazing");
  return {};
}

std::vector<double> printed_values(std::string_view text, std::size_t count, const std::string& layout_name) {
  std::vector<double> values;
  std::size_t number_of_line = 1;
  for (std::size_t i = 0; i < text.size();) {
    const char c = text[i];
    if (c == '\n') ++number_of_line;
    if (c == ',' || c == ' ' || c == '\t' || c == '\r' || c == '\n') {
      ++i;
      continue;
    }
    const std::size_t end = std::min(text.find_first_of(", \t\r\n", i), text.size());
    std::string_view number = text.substr(i, end - i);
    if (number.size() > 1 && (number.back() == 'f' || number.back() == 'F')) number.remove_suffix(1);
    values.push_back(parse_double(fmt::format("line {}", number_of_line), number));
    i = end;
  }
  if (values.size() != count)
    throw std::invalid_argument(fmt::format("{} values in the text; the {} layout has {}", values.size(), layout_name, count));
  return values;
}

LayoutValues read_layout_channels(const std::string& path, const AlbedoLayout& layout) {
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext != ".exr" && ext != ".csv" && ext != ".txt")
    throw std::invalid_argument("an .exr, a .csv or a .txt (the values as the renderer prints them) table");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::invalid_argument("cannot be read");
  if (ext != ".exr") {
    std::ostringstream text;
    text << in.rdbuf();
    if (ext == ".txt") {
      const std::size_t count = std::size_t(layout_columns(layout)) * std::size_t(layout_rows(layout));
      return {printed_values(text.str(), count, layout.name), {}};
    }
    return {layout_values_from_csv(text.str(), layout), layout_grazing_values_from_csv(text.str(), layout)};
  }
  microgeom::ExrImage image;
  try {
    image = microgeom::read_exr(path);
  } catch (const std::runtime_error& e) {  // not an EXR, or a damaged one
    throw std::invalid_argument(e.what());
  }
  return {layout_values_from_exr(image, layout), layout_grazing_values_from_exr(image, layout)};
}

std::vector<double> read_layout_values(const std::string& path, const AlbedoLayout& layout) {
  return read_layout_channels(path, layout).values;
}

}  // namespace microsim
