#include "microgeom/heightfield.h"

#include "microgeom/exr_io.h"
#include "core/strict_parse.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace microgeom {

Heightfield::Heightfield(int n, double tile_size, std::vector<float> heights)
    : n_(n), tile_size_(tile_size), heights_(std::move(heights)) {
  if (n < 2) throw std::invalid_argument(fmt::format("heightfield resolution {} is below 2", n));
  if (!(std::isfinite(tile_size) && tile_size > 0))
    throw std::invalid_argument(fmt::format("heightfield tile size {} is not a finite positive number", tile_size));
  if (heights_.size() != texel_count())
    throw std::invalid_argument(
        fmt::format("heightfield has {} heights, expected {} x {} = {}", heights_.size(), n, n, texel_count()));
  double sum = 0;
  min_height_ = heights_[0];
  max_height_ = heights_[0];
  for (std::size_t k = 0; k < heights_.size(); ++k) {
    const float z = heights_[k];
    if (!std::isfinite(z))
      throw std::invalid_argument(fmt::format("height {} at texel (x={}, y={}) is not finite", z,
                                              k % std::size_t(n), k / std::size_t(n)));
    min_height_ = std::min(min_height_, z);
    max_height_ = std::max(max_height_, z);
    sum += z;
  }
  mean_height_ = sum / double(heights_.size());
}

std::array<Eigen::Vector3d, 3> Heightfield::triangle_vertices(int i, int j, int t) const {
  const double h = cell_size();
  auto v = [&](int di, int dj) {
    return Eigen::Vector3d((i + di) * h, (j + dj) * h, double(height(long(i) + di, long(j) + dj)));
  };
  if (t == 0) return {v(0, 0), v(1, 0), v(1, 1)};
  return {v(0, 0), v(1, 1), v(0, 1)};
}

Eigen::Vector2d Heightfield::triangle_slope(int i, int j, int t) const {
  const double inv_h = 1.0 / cell_size();
  const int i1 = i + 1 == n_ ? 0 : i + 1, j1 = j + 1 == n_ ? 0 : j + 1;
  const double h00 = height_unchecked(i, j), h10 = height_unchecked(i1, j), h01 = height_unchecked(i, j1),
               h11 = height_unchecked(i1, j1);
  if (t == 0) return {(h10 - h00) * inv_h, (h11 - h10) * inv_h};
  return {(h11 - h01) * inv_h, (h01 - h00) * inv_h};
}

Eigen::Vector3d Heightfield::triangle_normal(int i, int j, int t) const {
  const Eigen::Vector2d s = triangle_slope(i, j, t);
  return Eigen::Vector3d(-s.x(), -s.y(), 1.0).normalized();
}

double Heightfield::triangle_centroid_height(int i, int j, int t) const {
  const int i1 = i + 1 == n_ ? 0 : i + 1, j1 = j + 1 == n_ ? 0 : j + 1;
  const double h00 = height_unchecked(i, j), h11 = height_unchecked(i1, j1);
  const double third = t == 0 ? height_unchecked(i1, j) : height_unchecked(i, j1);
  return (h00 + h11 + third) / 3.0;
}

namespace {
// Splits a coordinate into a wrapped cell index and the local coordinate in [0, 1].
void locate(double x, double inv_h, int n, int& cell, double& local) {
  const double g = x * inv_h;
  const double fl = std::floor(g);
  local = g - fl;
  long c = long(std::fmod(fl, double(n)));
  if (c < 0) c += n;
  if (c >= n) c -= n;  // fmod rounding at the boundary
  cell = int(c);
  local = std::clamp(local, 0.0, 1.0);  // g - floor(g) may round to 1 for tiny negative g
}
}  // namespace

double Heightfield::height_at(double x, double y) const {
  if (!(std::isfinite(x) && std::isfinite(y))) return 0.0;
  const double inv_h = 1.0 / cell_size();
  int i, j;
  double u, v;
  locate(x, inv_h, n_, i, u);
  locate(y, inv_h, n_, j, v);
  const double h00 = height(i, j), h10 = height(long(i) + 1, j), h01 = height(i, long(j) + 1),
               h11 = height(long(i) + 1, long(j) + 1);
  if (u >= v) return h00 + u * (h10 - h00) + v * (h11 - h10);
  return h00 + u * (h11 - h01) + v * (h01 - h00);
}

std::uint32_t Heightfield::triangle_at(double x, double y) const {
  const double inv_h = 1.0 / cell_size();
  int i = 0, j = 0;
  double u = 0, v = 0;
  if (std::isfinite(x) && std::isfinite(y)) {
    locate(x, inv_h, n_, i, u);
    locate(y, inv_h, n_, j, v);
  }
  return triangle_id(i, j, u >= v ? 0 : 1);
}

// ---- EXR files ------------------------------------------------------------------------------------------

namespace {
std::map<std::string, std::string> exr_attributes(const Heightfield& field) {
  std::map<std::string, std::string> a;
  for (const auto& [k, v] : field.metadata) a["microsim." + k] = v;
  a["microsim.tile_size"] = fmt::format("{:.17g}", field.tile_size());
  a["microsim.resolution"] = std::to_string(field.resolution());
  return a;
}
}  // namespace

void save_heightmap_exr(const std::filesystem::path& path, const Heightfield& field) {
  ExrImage img;
  img.width = img.height = field.resolution();
  img.channels.push_back({"height", field.heights()});
  img.attributes = exr_attributes(field);
  write_exr(path, img);
}

void save_normal_map_exr(const std::filesystem::path& path, const Heightfield& field) {
  ExrImage img;
  const int n = field.resolution();
  img.width = img.height = n;
  auto& r = img.add_channel("R");
  auto& g = img.add_channel("G");
  auto& b = img.add_channel("B");
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d m = (field.triangle_normal(i, j, 0) + field.triangle_normal(i, j, 1)).normalized();
      const std::size_t k = std::size_t(j) * n + i;
      r.data[k] = float(m.x());
      g.data[k] = float(m.y());
      b.data[k] = float(m.z());
    }
  img.attributes = exr_attributes(field);
  img.attributes["microsim.content"] = "normal map: unit cell normals (sum of the two triangle normals)";
  write_exr(path, img);
}

namespace {

constexpr int kMaxHeightmapResolution = 46340;  // 2 N^2 < 2^32

// The channel holding the heights: 'height', else 'Y', else the only channel.
ExrChannel& height_channel(ExrImage& img, const std::string& name) {
  ExrChannel* channel = img.find("height");
  if (!channel) channel = img.find("Y");
  if (!channel && img.channels.size() == 1) channel = &img.channels[0];
  if (channel) return *channel;
  std::string names;
  for (const auto& c : img.channels) names += (names.empty() ? "" : ", ") + microsim::reader::quote_excerpt(c.name);
  throw std::runtime_error(fmt::format(
      "heightmap '{}': no height channel: expected a channel 'height' or 'Y' or a single channel, found {}", name,
      names.size() > 200 ? names.substr(0, 200) + "..." : names));
}

// The physical tile size: --tile-size, else the attribute microsim.tile_size (a finite number > 0).
double tile_size_of(const ExrImage& img, const std::string& name, std::optional<double> tile_size) {
  if (tile_size) return *tile_size;
  const auto it = img.attributes.find("microsim.tile_size");
  if (it == img.attributes.end())
    throw std::runtime_error(fmt::format(
        "heightmap '{}': has no microsim.tile_size attribute: give the physical tile size (--tile-size)", name));
  const std::optional<double> size = microsim::reader::parse_finite_double(it->second);
  if (!size || !(*size > 0))
    throw std::runtime_error(fmt::format("heightmap '{}': attribute microsim.tile_size = {} is not a finite number > 0",
                                         name, microsim::reader::quote_excerpt(it->second)));
  return *size;
}

}  // namespace

Heightfield heightfield_from_exr(ExrImage img, const std::string& name, std::optional<double> tile_size) {
  auto fail = [&](const std::string& why) {
    return std::runtime_error(fmt::format("heightmap '{}': {}", name, why));
  };
  if (img.width != img.height)
    throw fail(fmt::format("is {} x {}, but a heightmap must be square", img.width, img.height));
  if (img.width < 2) throw fail(fmt::format("resolution {} is too small", img.width));
  if (img.width > kMaxHeightmapResolution)
    throw fail(fmt::format("resolution {} is above the largest supported, {} (2 N^2 triangle ids in 32 bits)",
                           img.width, kMaxHeightmapResolution));
  ExrChannel& channel = height_channel(img, name);
  for (std::size_t k = 0; k < channel.data.size(); ++k)
    if (!std::isfinite(channel.data[k]))
      throw fail(fmt::format("channel {} has a non-finite height {} at texel (x={}, y={})",
                             microsim::reader::quote_excerpt(channel.name), channel.data[k],
                             k % std::size_t(img.width), k / std::size_t(img.width)));
  const double size = tile_size_of(img, name, tile_size);
  if (!(std::isfinite(size) && size > 0)) throw fail(fmt::format("tile size {} must be a finite number > 0", size));
  const auto [lo, hi] = std::minmax_element(channel.data.begin(), channel.data.end());
  // Every slope is at most (max - min) / cell size: finite, or the surface's normals are not.
  if (!std::isfinite((double(*hi) - double(*lo)) * img.width / size))
    throw fail(fmt::format("tile size {} is too small for heights from {} to {}: the slopes overflow", size, *lo, *hi));

  Heightfield field(img.width, size, std::move(channel.data));
  for (const auto& [k, v] : img.attributes)
    if (k.rfind("microsim.", 0) == 0 && k != "microsim.tile_size" && k != "microsim.resolution")
      field.metadata[k.substr(9)] = v;
  return field;
}

Heightfield load_heightmap_exr(const std::filesystem::path& path, std::optional<double> tile_size) {
  return heightfield_from_exr(read_exr(path), path.string(), tile_size);  // read_exr throws naming the path
}

}  // namespace microgeom
