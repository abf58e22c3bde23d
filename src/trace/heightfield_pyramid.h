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
// The wide layout (PyramidLayout::wide, the default): the levels 1, 3, 5, .. only, each node's 4 x 4
// children (two levels down) in one 128-byte block (their minima, then their maxima: two cache lines, read
// together), so that one step tests all children of a node against the ray's part in each (slab
// intervals and the height range over them, with the same margin) and moves straight to the first child
// the ray may hit, or passes the node: half the levels, and a walk's neighbouring nodes in the same block
// (the 4 x 4 nodes of maximum mipmaps' quadtree, Tevs, Ihrke and Seidel 2008, section 3, stored by
// parent). The cells of a level-1 node are walked and tested as in the binary layout. Both layouts pass only
// nodes the ray's part clears by the margin and test every other cell the ray crosses with the same cell
// test, so they hit the same triangle (the point where a node is entered can differ by rounding only where
// the ray is farther than the margin from the surface).
//
// Determinism: a ray's result depends on the ray only. Thread-safe (const after construction).
#pragma once

#include "microgeom/heightfield.h"
#include "core/math.h"

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <type_traits>
#include <new>
#include <memory>
#include <optional>
#include <span>
#include <vector>

namespace microsim {

// Storage the kernel may back with 2 MiB pages (huge = true: arrays of 2 MiB or more, aligned to 2 MiB and
// madvise'd for transparent huge pages): a walk's random reads over a large tile then miss the TLB far less
// often. A hint only: values and layout are a vector's.
void huge_page_hint(void* p, std::size_t bytes);

template <class T>
struct HugePageAllocator {
  using value_type = T;
  using propagate_on_container_move_assignment = std::true_type;
  bool huge = false;
  HugePageAllocator() = default;
  explicit HugePageAllocator(bool h) : huge(h) {}
  template <class U>
  HugePageAllocator(const HugePageAllocator<U>& o) : huge(o.huge) {}
  T* allocate(std::size_t n) {
    constexpr std::size_t kHuge = std::size_t(1) << 21;
    const std::size_t bytes = (n * sizeof(T) + kHuge - 1) / kHuge * kHuge;
    const bool big = huge && n * sizeof(T) >= kHuge;
    void* p = big ? std::aligned_alloc(kHuge, bytes) : std::malloc(n * sizeof(T));
    if (!p) throw std::bad_alloc();
    if (big) huge_page_hint(p, bytes);
    return static_cast<T*>(p);
  }
  void deallocate(T* p, std::size_t) { std::free(p); }
  template <class U>
  bool operator==(const HugePageAllocator<U>& o) const { return huge == o.huge; }
};

struct HeightfieldHit;  // trace/heightfield_trace.h

// The min-max pyramid of a heightfield's vertex heights (levels 1 .. K, see above).
class HeightPyramid {
public:
  explicit HeightPyramid(const microgeom::Heightfield& field, bool huge_pages = false);
  int top_level() const { return int(levels_.size()); }
  // Nodes per side of level k (1 <= k <= top_level()): ceil(N / 2^k).
  int nodes_per_side(int k) const { return levels_[std::size_t(k - 1)].n; }
  // {min, max} of node (a, b) of level k: the vertices of cells [a 2^k, (a+1) 2^k] x [b 2^k, (b+1) 2^k]
  // (clipped to the tile, wrapped).
  const std::array<float, 2>& node(int k, int a, int b) const {
    const Level& l = levels_[std::size_t(k - 1)];
    return l.minmax[std::size_t(b) * std::size_t(l.n) + std::size_t(a)];
  }
  std::size_t bytes() const;

private:
  struct Level {
    int n = 0;
    std::vector<std::array<float, 2>, HugePageAllocator<std::array<float, 2>>> minmax;
  };
  std::vector<Level> levels_;
};

// The wide layout of a HeightPyramid: levels 1, 3, 5, .. up to the first level L with L + 2 >= K; block
// (pa, pb) of level L holds the {min, max} of the 4 x 4 nodes (4 pa + a, 4 pb + b) of level L, index
// 4 b + a (nodes beyond the tile: min +inf, max -inf, never entered), i.e. the children of node (pa, pb) of
// level L + 2.
class WidePyramid {
public:
  struct alignas(64) Block {
    std::array<float, 16> lo, hi;
  };
  // margin: the node tests' (the minima are stored less it, the maxima plus it, rounded outwards).
  WidePyramid(const HeightPyramid& binary, double margin);
  // The highest level held (0 if the tile is one cell).
  int top_level() const { return levels_.empty() ? 0 : 2 * int(levels_.size()) - 1; }
  const Block& block(int level, int pa, int pb) const {
    const Level& l = levels_[std::size_t(level / 2)];
    return l.blocks[std::size_t(pb) * std::size_t(l.n) + std::size_t(pa)];
  }
  std::size_t bytes() const;

private:
  struct Level {
    int n = 0;  // blocks per side
    std::vector<Block> blocks;
  };
  std::vector<Level> levels_;
};

// Which pyramid the tracer walks: the binary min-max pyramid, or its wide layout (see above).
enum class PyramidLayout { binary, wide };

class PyramidTracer {
public:
  // escape_height / floor_height: as HeightfieldScene's (above / below them nothing can be hit).
  PyramidTracer(const microgeom::Heightfield& field, double escape_height, double floor_height,
                PyramidLayout layout = PyramidLayout::wide, bool huge_pages = false);

  // Closest hit of origin + t dir, t >= 0 (dir: unit; origin: any x, y), skipping skip_triangle near the
  // origin (see above). The origin is used as given (lifting it is the caller's).
  HeightfieldHit trace(const Vec3<double>& origin, const Vec3<double>& dir,
                       std::optional<std::uint32_t> skip_triangle) const;

  // trace() of the rays origins[i] along dir (no skip) into out[i], kLanes walks in lockstep: one step of
  // each in turn, so that their memory reads could overlap (a walk's next node depends on its last read).
  // Every ray's result is trace()'s. Measured slower than one ray after the other (bench_tracers,
  // trace_pyramid_lockstep): kept for that benchmark, not used by the pipelines.
  static constexpr int kLanes = 4;
  void trace_batch(std::span<const Vec3<double>> origins, const Vec3<double>& dir, std::span<HeightfieldHit> out) const;

  PyramidLayout layout() const { return wide_ ? PyramidLayout::wide : PyramidLayout::binary; }
  // Bytes the tracer allocated (the pyramid; the heights are the field's).
  std::size_t bytes() const { return wide_ ? wide_->bytes() : binary_->bytes(); }

private:
  struct Walk;
  struct Leaf;
  struct Lane;
  bool start(Lane& lane, const Vec3<double>& origin, const Vec3<double>& dir,
             std::optional<std::uint32_t> skip_triangle) const;
  bool step(Lane& lane) const;
  void step_binary(Lane& lane) const;
  void prefetch_heights(int ax, int bx, int ay, int by) const;
  void step_wide(Lane& lane) const;
  bool step_cell(Lane& lane) const;
  void enter_child(Walk& w, int ax, int bx, int ay, int by, double tn, double tin_x, double tin_y) const;
  bool test_cell(Walk& w, Leaf& leaf, HeightfieldHit& out) const;
  void advance(Walk& w, int ax, int bx, int ay, int by, double tx, double ty) const;
  HeightfieldHit trace_vertical(const Vec3<double>& origin, const Vec3<double>& dir,
                                std::optional<std::uint32_t> skip_triangle) const;
  void finish_hit(const Walk& w, double t, int tri, HeightfieldHit& out) const;

  const microgeom::Heightfield& field_;
  std::vector<float, HugePageAllocator<float>> heights_;  // huge_pages: a copy of the field's in huge pages
  std::unique_ptr<HeightPyramid> binary_;  // the binary layout's (else null)
  std::unique_ptr<WidePyramid> wide_;      // the wide layout's (else null)
  int top_ = 0;                            // the walk's top level
  int n_ = 0;
  double tile_ = 0, cell_ = 0, inv_cell_ = 0;
  double escape_height_ = 0, floor_height_ = 0;
  double margin_ = 0;  // of the node tests
};

}  // namespace microsim
