// microsim: an exact tracer of the periodic heightfield without a BVH: a hierarchical grid traversal over
// a min-max height pyramid (maximum mipmaps, Tevs, Ihrke and Seidel 2008, "Maximum Mipmaps for Fast,
// Accurate, and Scalable Dynamic Height Field Rendering", section 3, extended to minima so that rays below
// the surface skip empty space too).
//
// The surface is the heightfield's own: two triangles per cell split along (i, j)-(i+1, j+1)
// (microgeom/heightfield.h), periodic. Memory: the heights (read in place) and the pyramid, 8 bytes per
// node of levels 1 .. K (a third of the cell count): 2.7 bytes per texel, against ~300 for Embree's
// triangle BVH.
//
// Traversal. Level k >= 1 holds, per node of 2^k x 2^k cells of the tile (the last node of a row or
// column cut at the tile edge), the least and greatest height of the vertices of its cells; level K is one
// node, the whole tile. The walk keeps the current cell (in the tile; the ray's origin is shifted by a
// whole tile when it leaves through an edge, so cell indices never need a modulo) and a level: the ray's
// part inside the current node lies entirely above its maximum or below its minimum (by a relative 1e-9
// margin, far beyond the rounding of the heights interpolated below) -> the node is passed and the walk
// goes up a level if it left the node's parent (else it tries the parent's next child); otherwise down a
// level, and at level 0 the cell's two triangles are tested.
//
// Exact and watertight. Along the ray's path over the plane, g(t) = z(t) - surface height is continuous
// and piecewise linear, linear over each triangle's part of a cell. The walk evaluates g at the path's
// breakpoints only: where it enters and leaves a cell (on a cell edge: the height interpolated along that
// edge from its two vertices, at a corner the vertex itself) and where it crosses a cell's diagonal
// (interpolated along the diagonal). A breakpoint shared by two cells (or two triangles) gets one value,
// computed by the same expression from the same numbers on both sides, so a ray cannot pass through a
// crack: it hits the first triangle over whose part g changes sign (> 0 to <= 0 or back), and the hit's t
// is that triangle's plane intersection (in double, as reference_trace), clamped to the part. A ray that
// starts above the surface therefore always enters the solid first (no convex-edge grazes to pass over,
// heightfield_trace.h); a ray that exactly touches an edge or vertex (g = 0 there) hits the triangle
// before it.
//
// Self-hits: the caller lifts a ray leaving the surface (HeightfieldScene::lifted / surface_origin) and
// names its start triangle, which is skipped in the start cell and its eight neighbours (in unwrapped
// coordinates; as reference_trace). Outcomes as HeightfieldScene::trace: escaped above escape_height going
// up, leaked below floor_height going down, unresolved after kMaxSegments tiles. `segments` counts the
// tiles the ray crossed (one per tile, the first included).
//
// Many rays at once (trace_batch): the same walks in SIMD lanes (heightfield_pyramid_lanes.h), every
// ray's result trace()'s to the bit (tests/trace/test_pyramid_trace.cpp).
//
// Determinism: a ray's result depends on the ray only. Thread-safe (const after construction; the
// set_batch_* knobs, for benchmarks and tests, excepted).
#pragma once

#include "microgeom/heightfield.h"
#include "core/math.h"

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace microsim {

struct HeightfieldHit;  // trace/heightfield_trace.h

// The min-max pyramid of a heightfield's vertex heights (levels 1 .. K, see above).
class HeightPyramid {
public:
  explicit HeightPyramid(const microgeom::Heightfield& field);
  int top_level() const { return int(levels_.size()); }
  // Nodes per side of level k (1 <= k <= top_level()): ceil(N / 2^k).
  int nodes_per_side(int k) const { return levels_[std::size_t(k - 1)].n; }
  // {min, max} of node (a, b) of level k: the vertices of cells [a 2^k, (a+1) 2^k] x [b 2^k, (b+1) 2^k]
  // (clipped to the tile, wrapped).
  const std::array<float, 2>& node(int k, int a, int b) const {
    const Level& l = levels_[std::size_t(k - 1)];
    return nodes_[l.offset + std::size_t(b) * std::size_t(l.n) + std::size_t(a)];
  }
  // Every level's nodes in one array, level 1 first, each row by row (for gathers by lanes).
  std::span<const std::array<float, 2>> nodes() const { return nodes_; }
  // Index in nodes() of node (0, 0) of level k.
  std::size_t level_offset(int k) const { return levels_[std::size_t(k - 1)].offset; }
  std::size_t bytes() const { return nodes_.size() * sizeof(nodes_[0]); }

private:
  struct Level {
    int n = 0;
    std::size_t offset = 0;
  };
  std::vector<Level> levels_;
  std::vector<std::array<float, 2>> nodes_;
};

class PyramidTracer {
public:
  // escape_height / floor_height: as HeightfieldScene's (above / below them nothing can be hit).
  PyramidTracer(const microgeom::Heightfield& field, double escape_height, double floor_height);

  // Closest hit of origin + t dir, t >= 0 (dir: unit; origin: any x, y), skipping skip_triangle near the
  // origin (see above). The origin is used as given (lifting it is the caller's).
  HeightfieldHit trace(const Vec3<double>& origin, const Vec3<double>& dir,
                       std::optional<std::uint32_t> skip_triangle) const;

  // A ray of a batch: trace()'s arguments.
  struct Ray {
    Vec3<double> origin, dir;
    std::optional<std::uint32_t> skip_triangle;
  };
  // trace() of many rays at once, out[i] bit for bit trace()'s result for ray i: the walks run in SIMD
  // lanes (heightfield_pyramid_lanes.h), each lane its own ray, so that the reads of many rays' nodes
  // are in flight together (a walk's next node depends on its last read). Node steps and cells without
  // a hit run in the lanes with the same double expressions as trace()'s (no contraction into FMA); a
  // cell that may hold the hit runs through trace()'s own step. The first form: rays origins[i] along
  // dir, no skip. Lanes: kMaxBatchLanes (measured fastest; 8 to 32 slower).
  void trace_batch(std::span<const Vec3<double>> origins, const Vec3<double>& dir, std::span<HeightfieldHit> out) const;
  void trace_batch(std::span<const Ray> rays, std::span<HeightfieldHit> out) const;
  // Lanes per batch walk (rounded to a multiple of the SIMD width, at most kMaxBatchLanes); for benchmarks.
  static constexpr int kMaxBatchLanes = 64;
  void set_batch_lanes(int lanes) { batch_lanes_ = lanes; }
  // Software prefetch of every lane's next read before each step of the lanes (default: on for tiles of
  // kPrefetchResolution^2 and more, whose heights and pyramid leave the caches).
  static constexpr int kPrefetchResolution = 2048;
  void set_batch_prefetch(bool prefetch) { batch_prefetch_ = prefetch; }

  const HeightPyramid& pyramid() const { return pyramid_; }
  // Bytes the tracer allocated (the pyramid; the heights are the field's).
  std::size_t bytes() const { return pyramid_.bytes(); }

private:
  struct Walk;
  struct Leaf;
  struct Lane;
  bool start(Lane& lane, const Vec3<double>& origin, const Vec3<double>& dir,
             std::optional<std::uint32_t> skip_triangle) const;
  bool step(Lane& lane) const;
  bool test_cell(Walk& w, Leaf& leaf, HeightfieldHit& out) const;
  void advance(Walk& w, int ax, int bx, int ay, int by, double tx, double ty) const;
  HeightfieldHit trace_vertical(const Vec3<double>& origin, const Vec3<double>& dir,
                                std::optional<std::uint32_t> skip_triangle) const;
  void finish_hit(const Walk& w, double t, int tri, HeightfieldHit& out) const;
  struct Batch;
  void run_batch(Batch& batch) const;
  bool settle(Batch& batch, std::size_t lane) const;

  const microgeom::Heightfield& field_;
  HeightPyramid pyramid_;
  int n_ = 0;
  double tile_ = 0, cell_ = 0, inv_cell_ = 0;
  double escape_height_ = 0, floor_height_ = 0;
  double margin_ = 0;  // of the node tests
  int batch_lanes_ = 0;  // 0: the default of the SIMD target
  bool batch_prefetch_ = false;
  std::vector<double> level_offset_;  // HeightPyramid::level_offset per level 0 .. K, for the lanes (0 at 0)
};

}  // namespace microsim
