// microgeom: a periodic heightfield microsurface: float heights on an N x N vertex grid over a square
// tile of physical side L, repeated periodically in x and y.
//
// Geometry (fixed; tracers and statistics rely on it):
// - Cell size h = L / N. Vertex (i, j), 0 <= i, j < N, sits at (x, y, z) = (i h, j h, height(i, j));
//   i is the x (column) index, j the y (row) index; heights are stored row-major: heights()[j N + i].
//   Indices wrap around: height(i, j) = height(i mod N, j mod N), so vertex (N, j) is vertex (0, j)
//   shifted by L in x.
// - Cell (i, j) covers [i h, (i+1) h] x [j h, (j+1) h] and is split along its diagonal from vertex (i, j)
//   to vertex (i+1, j+1) into two triangles, both counter-clockwise seen from +z (normals point up):
//     triangle t = 0 ("below the diagonal", local u >= v):  (i, j), (i+1, j), (i+1, j+1)
//     triangle t = 1 ("above the diagonal", local v >  u):  (i, j), (i+1, j+1), (i, j+1)
//   with local coordinates u = x/h - i, v = y/h - j in [0, 1]. Every triangle has projected area h^2/2,
//   so the histogram of triangle slopes (equal weights) is the surface's slope distribution P22, i.e.
//   its NDF D(m) weighted by projected area.
// - Triangle id = 2 (j N + i) + t (0 <= id < 2 N^2), the natural primitive id for a tracer.
// - Slopes are height gradients, (sx, sy) = (dz/dx, dz/dy) = (-mx/mz, -my/mz) for the unit normal m:
//     t = 0: sx = (h(i+1,j) - h(i,j)) / h,     sy = (h(i+1,j+1) - h(i+1,j)) / h
//     t = 1: sx = (h(i+1,j+1) - h(i,j+1)) / h, sy = (h(i,j+1) - h(i,j)) / h
//   i.e. each horizontal edge difference Dx(i,j) = h(i+1,j) - h(i,j) is shared by triangle 0 of cell (i,j)
//   and triangle 1 of cell (i,j-1); each vertical difference Dy(i,j) = h(i,j+1) - h(i,j) by triangle 1 of
//   cell (i,j) and triangle 0 of cell (i-1,j).
// - A ray leaving the tile re-enters from the opposite side (shifted by L); a ray above max_height()
//   going up can never hit again.
#pragma once

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace microgeom {

class Heightfield {
public:
  Heightfield() = default;  // empty (resolution 0): only assignment and resolution() are meaningful
  // Throws std::invalid_argument if n < 2, heights.size() != n*n, tile_size is not finite and > 0, or a
  // height is NaN/inf (the message names the first bad value and its texel).
  Heightfield(int n, double tile_size, std::vector<float> heights);

  int resolution() const { return n_; }            // N (vertices and cells per side)
  double tile_size() const { return tile_size_; }  // L
  double cell_size() const { return tile_size_ / n_; }
  std::size_t texel_count() const { return std::size_t(n_) * std::size_t(n_); }
  std::size_t triangle_count() const { return 2 * texel_count(); }

  const std::vector<float>& heights() const { return heights_; }
  // Height of vertex (i, j) for 0 <= i, j < N (no wrap; fastest).
  float height_unchecked(int i, int j) const { return heights_[std::size_t(j) * n_ + i]; }
  // Height of vertex (i, j), any integers (periodic wrap-around).
  float height(long i, long j) const { return height_unchecked(wrap(i), wrap(j)); }
  int wrap(long i) const {
    const long r = i % n_;
    return int(r < 0 ? r + n_ : r);
  }

  float min_height() const { return min_height_; }
  float max_height() const { return max_height_; }
  double mean_height() const { return mean_height_; }

  // Triangle ids: 2 (j N + i) + t, see the header comment.
  std::uint32_t triangle_id(int i, int j, int t) const {
    return std::uint32_t(2 * (std::size_t(j) * n_ + i) + t);
  }
  struct TriangleIndex {
    int i, j, t;
  };
  TriangleIndex triangle_index(std::uint32_t id) const {
    const std::uint32_t cell = id >> 1;
    return {int(cell % std::uint32_t(n_)), int(cell / std::uint32_t(n_)), int(id & 1u)};
  }
  // The three vertices of triangle t of cell (i, j) (0 <= i, j < N) in tile coordinates, counter-clockwise
  // from +z; x, y in [0, L] (vertices on the far edges are the wrapped ones shifted by L).
  std::array<Eigen::Vector3d, 3> triangle_vertices(int i, int j, int t) const;
  // Height gradient (dz/dx, dz/dy) of triangle t of cell (i, j), computed in double from float heights.
  Eigen::Vector2d triangle_slope(int i, int j, int t) const;
  Eigen::Vector2d triangle_slope(std::uint32_t id) const {
    const auto c = triangle_index(id);
    return triangle_slope(c.i, c.j, c.t);
  }
  // Unit upward normal (-sx, -sy, 1) / |.| of triangle t of cell (i, j).
  Eigen::Vector3d triangle_normal(int i, int j, int t) const;
  Eigen::Vector3d triangle_normal(std::uint32_t id) const {
    const auto c = triangle_index(id);
    return triangle_normal(c.i, c.j, c.t);
  }
  // Brings the heights that triangle_normal(id) reads toward the cache: a hint, no effect on any value
  // (a tracer issues it when a ray hits the triangle and computes the normal after the next ray).
  void prefetch_triangle(std::uint32_t id) const {
    const auto c = triangle_index(id);
    const int j1 = c.j + 1 == n_ ? 0 : c.j + 1;
    __builtin_prefetch(&heights_[std::size_t(c.j) * n_ + c.i]);
    __builtin_prefetch(&heights_[std::size_t(j1) * n_ + c.i]);
  }
  // Mean of the three vertex heights of the triangle.
  double triangle_centroid_height(int i, int j, int t) const;

  // The surface height over any (x, y) (periodic), linear on each triangle of the split above.
  double height_at(double x, double y) const;
  // The triangle id over (x, y) (periodic); points on the diagonal belong to triangle 0.
  std::uint32_t triangle_at(double x, double y) const;

  // Free-form provenance (assembly, alpha, seed, ...), written as EXR string attributes.
  std::map<std::string, std::string> metadata;

private:
  int n_ = 0;
  double tile_size_ = 0;
  std::vector<float> heights_;
  float min_height_ = 0, max_height_ = 0;
  double mean_height_ = 0;
};

struct ExrImage;  // microgeom/exr_io.h

// ---- EXR files ------------------------------------------------------------------------------------------
// Heightmap: one FLOAT channel "height" (N x N, row-major, pixel (x, y) = vertex (i, j)) in the same
// physical unit as the tile size; string attributes "microsim.tile_size" (%.17g) and
// "microsim.resolution", plus every metadata entry under "microsim.<key>".
void save_heightmap_exr(const std::filesystem::path& path, const Heightfield& field);

// Reads a heightmap. The height channel is "height", else "Y", else the only channel of the file; any
// other layout is an error naming the channels found. The tile size is `tile_size` if given, else the
// file's "microsim.tile_size" attribute; neither -> error. Non-square images, NaN/inf heights (naming the
// texel), tile size <= 0, files that are not EXR: std::runtime_error naming the path.
// The attribute microsim.tile_size is a whole finite decimal number > 0 ("1x", "nan", "-1" are errors
// quoting a short excerpt of it); heights so steep that a slope overflows a double are an error too.
// The EXR reader's size limits apply (kMaxExrDecodedBytes).
Heightfield load_heightmap_exr(const std::filesystem::path& path, std::optional<double> tile_size = {});
// The same checks on an image already read (the fuzz target's entry point); `name` names it in messages.
Heightfield heightfield_from_exr(ExrImage image, const std::string& name, std::optional<double> tile_size = {});

// Normal map: channels "R", "G", "B" = the unit normal of each cell, the normalised sum of its two
// triangles' normals (signed components, not remapped to [0, 1]); same attributes as the heightmap.
// For display and for tools expecting per-texel normals; exact triangle normals follow from the heights.
void save_normal_map_exr(const std::filesystem::path& path, const Heightfield& field);

}  // namespace microgeom
