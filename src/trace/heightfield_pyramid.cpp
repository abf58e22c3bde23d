// microsim: the min-max pyramid and its exact heightfield tracer (see heightfield_pyramid.h).
#include "trace/heightfield_pyramid.h"

#include "trace/heightfield_trace.h"

#include <tbb/parallel_for.h>
#include <sys/mman.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <span>

namespace microsim {
void huge_page_hint(void* p, std::size_t bytes) { madvise(p, bytes, MADV_HUGEPAGE); }

namespace {

constexpr double kUnbounded = std::numeric_limits<double>::infinity();

// x mod L into [0, L) (as heightfield_trace.cpp).
inline double wrap_into(double x, double tile) {
  double r = x - tile * std::floor(x / tile);
  if (!(r < tile) || r < 0.0) r = 0.0;
  return r;
}

}  // namespace

// ---- the pyramid ---------------------------------------------------------------------------------------

HeightPyramid::HeightPyramid(const microgeom::Heightfield& field, bool huge_pages) {
  const int n = field.resolution();
  int prev_n = n;
  for (int k = 1; prev_n > 1; ++k) {
    Level level{0, decltype(Level::minmax)(HugePageAllocator<std::array<float, 2>>(huge_pages))};
    level.n = (prev_n + 1) / 2;
    level.minmax.resize(std::size_t(level.n) * std::size_t(level.n));
    const Level* child = k > 1 ? &levels_.back() : nullptr;
    tbb::parallel_for(0, level.n, [&](int b) {
      for (int a = 0; a < level.n; ++a) {
        float lo = std::numeric_limits<float>::infinity(), hi = -lo;
        if (!child) {  // level 1 from the vertices of its (up to) 2 x 2 cells, the far edge's included
          for (int y = 2 * b; y <= std::min(n, 2 * b + 2); ++y)
            for (int x = 2 * a; x <= std::min(n, 2 * a + 2); ++x) {
              const float z = field.height_unchecked(x == n ? 0 : x, y == n ? 0 : y);
              lo = std::min(lo, z), hi = std::max(hi, z);
            }
        } else {  // from the (up to) 2 x 2 children: their vertex ranges make up the node's
          for (int y = 2 * b; y < std::min(child->n, 2 * b + 2); ++y)
            for (int x = 2 * a; x < std::min(child->n, 2 * a + 2); ++x) {
              const auto& c = child->minmax[std::size_t(y) * std::size_t(child->n) + std::size_t(x)];
              lo = std::min(lo, c[0]), hi = std::max(hi, c[1]);
            }
        }
        level.minmax[std::size_t(b) * std::size_t(level.n) + std::size_t(a)] = {lo, hi};
      }
    });
    levels_.push_back(std::move(level));
    prev_n = levels_.back().n;
  }
}

std::size_t HeightPyramid::bytes() const {
  std::size_t total = 0;
  for (const Level& l : levels_) total += l.minmax.size() * sizeof(l.minmax[0]);
  return total;
}

// ---- the wide layout ------------------------------------------------------------------------------------

namespace {

// x - margin (x + margin for up) rounded outwards to a float.
float widened(float x, double margin, bool up) {
  const double v = up ? double(x) + margin : double(x) - margin;
  const float f = float(v), outwards = up ? std::numeric_limits<float>::infinity() : -std::numeric_limits<float>::infinity();
  return (up ? double(f) < v : double(f) > v) ? std::nextafter(f, outwards) : f;
}

}  // namespace

WidePyramid::WidePyramid(const HeightPyramid& binary, double margin) {
  const int top = binary.top_level();
  for (int k = 1; top > 0; k += 2) {
    const int nodes = binary.nodes_per_side(k);
    Level level;
    level.n = (nodes + 3) / 4;
    level.blocks.resize(std::size_t(level.n) * std::size_t(level.n));
    tbb::parallel_for(0, level.n, [&](int pb) {
      for (int pa = 0; pa < level.n; ++pa) {
        Block& block = level.blocks[std::size_t(pb) * std::size_t(level.n) + std::size_t(pa)];
        for (int i = 0; i < 16; ++i) {
          const int a = 4 * pa + (i & 3), b = 4 * pb + (i >> 2);
          const bool in = a < nodes && b < nodes;
          block.lo[std::size_t(i)] = in ? widened(binary.node(k, a, b)[0], margin, false) : std::numeric_limits<float>::infinity();
          block.hi[std::size_t(i)] = in ? widened(binary.node(k, a, b)[1], margin, true) : -std::numeric_limits<float>::infinity();
        }
      }
    });
    levels_.push_back(std::move(level));
    if (k + 2 >= top) break;
  }
}

std::size_t WidePyramid::bytes() const {
  std::size_t total = 0;
  for (const Level& l : levels_) total += l.blocks.size() * sizeof(Block);
  return total;
}

// ---- the tracer -----------------------------------------------------------------------------------------

PyramidTracer::PyramidTracer(const microgeom::Heightfield& field, double escape_height, double floor_height,
                             PyramidLayout layout, bool huge_pages)
    : field_(field), binary_(std::make_unique<HeightPyramid>(field, huge_pages)), n_(field.resolution()), tile_(field.tile_size()), cell_(field.cell_size()),
      inv_cell_(1.0 / field.cell_size()), escape_height_(escape_height), floor_height_(floor_height) {
  const double zmax = field.max_height(), zmin = field.min_height();
  margin_ = 1e-9 * (std::max(std::abs(zmax), std::abs(zmin)) + (zmax - zmin));
  if (huge_pages) {
    heights_ = std::vector<float, HugePageAllocator<float>>(HugePageAllocator<float>(true));
    heights_.assign(field.heights().begin(), field.heights().end());
  }
  if (layout == PyramidLayout::wide) {
    wide_ = std::make_unique<WidePyramid>(*binary_, margin_);
    binary_.reset();
    top_ = wide_->top_level();
  } else {
    top_ = binary_->top_level();
  }
}

// One ray's state: origin and direction with x, y in cells (the origin shifted by N cells whenever the ray
// crosses a tile edge, so that the current cell stays in the tile), the current cell and how the ray
// entered it, g = z - surface height where it entered (when known from the previous cell).
struct PyramidTracer::Walk {
  double ox = 0, oy = 0, oz = 0, dx = 0, dy = 0, dz = 0, idx = 0, idy = 0;
  int sx = 0, sy = 0;
  int ci = 0, cj = 0;          // current cell, in the tile
  long tile_x = 0, tile_y = 0;  // tiles crossed (signed): the unwrapped cell is ci + tile_x N
  long ui0 = 0, uj0 = 0;        // the start cell, unwrapped
  double t = 0;
  int entry = 0;  // how the ray entered the cell: 0 it starts in it, 1 x edge, 2 y edge, 3 corner
  bool g_known = false;
  double g = 0;
  long wraps = 0;
  std::optional<microgeom::Heightfield::TriangleIndex> skip;
};

// A cell's heights and where the ray leaves it.
struct PyramidTracer::Leaf {
  double h00 = 0, h10 = 0, h01 = 0, h11 = 0;
  double t1 = 0;
  int exit = 0;  // 1 x edge, 2 y edge, 3 corner
};

namespace {

// The height on the edge from ha to hb at fraction f (clamped): the same expression from both cells.
inline double edge_height(double ha, double hb, double f) { return ha + std::clamp(f, 0.0, 1.0) * (hb - ha); }

// Slopes (per cell) of triangle t of a cell, as microgeom::Heightfield::triangle_slope.
inline void plane_slopes(double h00, double h10, double h01, double h11, int t, double& sx, double& sy) {
  sx = t == 0 ? h10 - h00 : h11 - h01;
  sy = t == 0 ? h11 - h10 : h01 - h00;
}

}  // namespace

void PyramidTracer::finish_hit(const Walk& w, double t, int tri, HeightfieldHit& out) const {
  out.outcome = RayOutcome::hit;
  out.t = t;
  out.triangle = field_.triangle_id(w.ci, w.cj, tri);
  out.point = Vec3<double>(wrap_into((w.ox + t * w.dx) * cell_, tile_), wrap_into((w.oy + t * w.dy) * cell_, tile_),
                           w.oz + t * w.dz);
}

// The cell's two triangles over the ray's part [w.t, leaf.t1]: g at the entry, the diagonal crossing (if
// any) and the exit; the first part over which g changes sign holds the hit (see the header).
bool PyramidTracer::test_cell(Walk& w, Leaf& c, HeightfieldHit& out) const {
  const double t0 = w.t, t1 = c.t1;
  const double u0 = w.ox + t0 * w.dx - w.ci, v0 = w.oy + t0 * w.dy - w.cj;
  const double u1 = w.ox + t1 * w.dx - w.ci, v1 = w.oy + t1 * w.dy - w.cj;
  double g0 = w.g;
  if (!w.g_known) {
    double hs;
    if (w.entry == 1) hs = w.sx > 0 ? edge_height(c.h00, c.h01, v0) : edge_height(c.h10, c.h11, v0);
    else if (w.entry == 2) hs = w.sy > 0 ? edge_height(c.h00, c.h10, u0) : edge_height(c.h01, c.h11, u0);
    else if (w.entry == 3) hs = w.sx > 0 ? (w.sy > 0 ? c.h00 : c.h01) : (w.sy > 0 ? c.h10 : c.h11);
    else {
      double sx, sy;
      plane_slopes(c.h00, c.h10, c.h01, c.h11, u0 >= v0 ? 0 : 1, sx, sy);
      hs = c.h00 + sx * u0 + sy * v0;
    }
    g0 = w.oz + t0 * w.dz - hs;
  }
  double hs1;
  if (c.exit == 1) hs1 = w.sx > 0 ? edge_height(c.h10, c.h11, v1) : edge_height(c.h00, c.h01, v1);
  else if (c.exit == 2) hs1 = w.sy > 0 ? edge_height(c.h01, c.h11, u1) : edge_height(c.h00, c.h10, u1);
  else hs1 = w.sx > 0 ? (w.sy > 0 ? c.h11 : c.h10) : (w.sy > 0 ? c.h01 : c.h00);
  const double g1 = w.oz + t1 * w.dz - hs1;
  // The part of triangle `tri` over [ta, tb], g from ga to gb: hit if g changes sign there.
  const auto part = [&](int tri, double ta, double tb, double ga, double gb) {
    if ((ga > 0) == (gb > 0)) return false;
    if (w.skip && w.skip->t == tri && w.skip->i == w.ci && w.skip->j == w.cj &&
        std::abs(w.ci + w.tile_x * n_ - w.ui0) <= 1 && std::abs(w.cj + w.tile_y * n_ - w.uj0) <= 1) {
      return false;
    }
    double sx, sy;
    plane_slopes(c.h00, c.h10, c.h01, c.h11, tri, sx, sy);
    const double a = w.oz - c.h00 - sx * (w.ox - w.ci) - sy * (w.oy - w.cj);
    const double b = w.dz - sx * w.dx - sy * w.dy;
    double t = b != 0 ? -a / b : ta;
    t = std::isnan(t) ? ta : std::clamp(t, ta, tb);
    finish_hit(w, t, tri, out);
    return true;
  };
  const double d0 = u0 - v0, d1 = u1 - v1;
  if ((d0 > 0 && d1 < 0) || (d0 < 0 && d1 > 0)) {  // crosses the diagonal
    const double td = t0 + (t1 - t0) * (d0 / (d0 - d1));
    const double s = 0.5 * ((w.ox + td * w.dx - w.ci) + (w.oy + td * w.dy - w.cj));
    const double gd = w.oz + td * w.dz - edge_height(c.h00, c.h11, s);
    const int first = d0 > 0 ? 0 : 1;
    if (part(first, t0, td, g0, gd) || part(1 - first, td, t1, gd, g1)) return true;
  } else if (part(d0 + d1 >= 0 ? 0 : 1, t0, t1, g0, g1)) {
    return true;
  }
  w.g_known = true;
  w.g = g1;
  return false;
}

// Moves the walk to where it leaves the node [ax, bx) x [ay, by) (exit distances tx, ty per axis): the
// neighbouring cell across the edge (both edges at a corner), in the tile.
void PyramidTracer::advance(Walk& w, int ax, int bx, int ay, int by, double tx, double ty) const {
  const bool step_x = tx <= ty, step_y = ty <= tx;
  const double t1 = std::max(std::min(tx, ty), w.t);
  w.ci = step_x ? (w.sx > 0 ? bx : ax - 1) : std::clamp(int(std::floor(w.ox + t1 * w.dx)), ax, bx - 1);
  w.cj = step_y ? (w.sy > 0 ? by : ay - 1) : std::clamp(int(std::floor(w.oy + t1 * w.dy)), ay, by - 1);
  w.entry = (step_x ? 1 : 0) | (step_y ? 2 : 0);
  w.t = t1;
  if (w.ci >= n_ || w.ci < 0) {
    const int s = w.ci >= n_ ? 1 : -1;
    w.ci -= s * n_, w.ox -= s * n_, w.tile_x += s, ++w.wraps;
  }
  if (w.cj >= n_ || w.cj < 0) {
    const int s = w.cj >= n_ ? 1 : -1;
    w.cj -= s * n_, w.oy -= s * n_, w.tile_y += s, ++w.wraps;
  }
}

// A vertical ray sees one point of the plane: the triangle over it.
HeightfieldHit PyramidTracer::trace_vertical(const Vec3<double>& origin, const Vec3<double>& dir,
                                             std::optional<std::uint32_t> skip_triangle) const {
  HeightfieldHit out;
  out.segments = 1;
  const double x = wrap_into(origin.x(), tile_), y = wrap_into(origin.y(), tile_);
  const std::uint32_t tri = field_.triangle_at(x, y);
  const double g0 = origin.z() - field_.height_at(x, y);
  const bool crosses = dir.z() > 0 ? !(g0 > 0) : g0 > 0;
  if (!crosses || (skip_triangle && *skip_triangle == tri)) {
    out.outcome = dir.z() > 0 ? RayOutcome::escaped : RayOutcome::leaked;
    return out;
  }
  out.outcome = RayOutcome::hit;
  out.triangle = tri;
  out.t = std::abs(g0 / dir.z());
  out.point = Vec3<double>(x, y, origin.z() + out.t * dir.z());
  return out;
}

// One ray's walk and its level, for tracing several in lockstep.
struct PyramidTracer::Lane {
  Walk w;
  int k = 0;
  HeightfieldHit out;
};

// Sets up the walk of a ray; returns true if it is done already (a vertical ray).
bool PyramidTracer::start(Lane& lane, const Vec3<double>& origin, const Vec3<double>& dir,
                          std::optional<std::uint32_t> skip_triangle) const {
  lane = Lane{};
  if (dir.x() == 0 && dir.y() == 0) {
    lane.out = trace_vertical(origin, dir, skip_triangle);
    return true;
  }
  lane.out.segments = 1;
  Walk& w = lane.w;
  w.ox = wrap_into(origin.x(), tile_) * inv_cell_, w.oy = wrap_into(origin.y(), tile_) * inv_cell_, w.oz = origin.z();
  w.dx = dir.x() * inv_cell_, w.dy = dir.y() * inv_cell_, w.dz = dir.z();
  w.sx = w.dx > 0 ? 1 : (w.dx < 0 ? -1 : 0), w.sy = w.dy > 0 ? 1 : (w.dy < 0 ? -1 : 0);
  w.idx = w.sx ? 1.0 / w.dx : 0.0, w.idy = w.sy ? 1.0 / w.dy : 0.0;
  w.ci = std::min(int(w.ox), n_ - 1), w.cj = std::min(int(w.oy), n_ - 1);
  w.ui0 = w.ci, w.uj0 = w.cj;
  if (skip_triangle) w.skip = field_.triangle_index(*skip_triangle);
  // A ray leaving the surface starts among the cells it is likely to hit: at level 0, going up as it
  // leaves nodes; a ray from above the surface starts at the top.
  lane.k = skip_triangle ? 0 : top_;
  return false;
}

// One step of the walk: a node passed or entered, or a cell tested. Returns true when the ray is done
// (lane.out holds its result).
bool PyramidTracer::step(Lane& lane) const {
  Walk& w = lane.w;
  const double z = w.oz + w.t * w.dz;
  if (w.dz >= 0 && z > escape_height_) return lane.out.outcome = RayOutcome::escaped, true;
  if (w.dz <= 0 && z < floor_height_) return lane.out.outcome = RayOutcome::leaked, true;
  if (lane.k == 0) {
    if (step_cell(lane)) return true;
  } else if (wide_) {
    step_wide(lane);
  } else {
    step_binary(lane);
  }
  if (w.wraps < kMaxSegments) return false;
  lane.out.outcome = RayOutcome::unresolved;
  lane.out.segments = kMaxSegments;
  return true;
}

// Level 0: the current cell's triangles; then the next cell, back to level 1 when the ray leaves the
// 2 x 2 node. Returns true on a hit.
bool PyramidTracer::step_cell(Lane& lane) const {
  Walk& w = lane.w;
  const int ax = w.ci, ay = w.cj, bx = std::min(n_, ax + 1), by = std::min(n_, ay + 1);
  const double tx = w.sx > 0 ? (bx - w.ox) * w.idx : (w.sx < 0 ? (ax - w.ox) * w.idx : kUnbounded);
  const double ty = w.sy > 0 ? (by - w.oy) * w.idy : (w.sy < 0 ? (ay - w.oy) * w.idy : kUnbounded);
  const double t1 = std::max(std::min(tx, ty), w.t);
  const int i1 = w.ci + 1 == n_ ? 0 : w.ci + 1, j1 = w.cj + 1 == n_ ? 0 : w.cj + 1;
  const float* h = !heights_.empty() ? heights_.data() : field_.heights().data();
  const std::size_t r0 = std::size_t(w.cj) * std::size_t(n_), r1 = std::size_t(j1) * std::size_t(n_);
  Leaf c{h[r0 + std::size_t(w.ci)], h[r0 + std::size_t(i1)], h[r1 + std::size_t(w.ci)], h[r1 + std::size_t(i1)], t1,
         (tx <= ty ? 1 : 0) | (ty <= tx ? 2 : 0)};
  if (test_cell(w, c, lane.out)) {
    lane.out.segments = int(std::min<long>(w.wraps + 1, kMaxSegments));
    return true;
  }
  const int pi = w.ci >> 1, pj = w.cj >> 1;
  advance(w, ax, bx, ay, by, tx, ty);
  if (pi != w.ci >> 1 || pj != w.cj >> 1) lane.k = 1;  // left the 2 x 2 node: try the next one
  return false;
}

// Binary layout, level k >= 1: the node holding the current cell, entered (a level down) or passed.
void PyramidTracer::step_binary(Lane& lane) const {
  Walk& w = lane.w;
  int& k = lane.k;
  const double z = w.oz + w.t * w.dz;
  const int ax = (w.ci >> k) << k, ay = (w.cj >> k) << k;
  const int bx = std::min(n_, ax + (1 << k)), by = std::min(n_, ay + (1 << k));
  const double tx = w.sx > 0 ? (bx - w.ox) * w.idx : (w.sx < 0 ? (ax - w.ox) * w.idx : kUnbounded);
  const double ty = w.sy > 0 ? (by - w.oy) * w.idy : (w.sy < 0 ? (ay - w.oy) * w.idy : kUnbounded);
  const double t1 = std::max(std::min(tx, ty), w.t);
  const auto& mm = binary_->node(k, w.ci >> k, w.cj >> k);
  const double z1 = w.oz + t1 * w.dz;
  if (!(std::min(z, z1) > mm[1] + margin_ || std::max(z, z1) < mm[0] - margin_)) {
    --k;
    return;
  }
  const int pi = w.ci >> (k + 1), pj = w.cj >> (k + 1);  // nothing in the node: pass it
  advance(w, ax, bx, ay, by, tx, ty);
  w.g_known = false;
  if (k < top_ && (pi != w.ci >> (k + 1) || pj != w.cj >> (k + 1))) ++k;  // left the parent
}

namespace {

// 2 doubles at once (GCC / Clang vector extensions: one SSE2 register, the same arithmetic as scalar).
using V2d = double __attribute__((vector_size(16)));

inline V2d broadcast(double x) { return V2d{x, x}; }

// The ray's t entering (in) and leaving (out) the 4 columns [base + a span, base + (a + 1) span) along one
// axis, in pairs of columns {0, 1}, {2, 3} (not cut at the tile edge: a node cut there holds the cells
// inside only, so its interval is only longer, and a node wholly beyond it is never entered): o, inv =
// the origin and 1 / direction in cells, s the direction's sign, c the current cell (a ray parallel to the
// axis stays in c's column).
inline void child_slabs(double o, double inv, int s, int c, int base, int span, V2d* in, V2d* out) {
  const double x0 = base, x1 = base + span, x2 = base + 2 * span, x3 = base + 3 * span, x4 = base + 4 * span;
  if (s == 0) {
    const auto inside = [&](double lo, double hi) { return c >= lo && c < hi ? kUnbounded : -kUnbounded; };
    in[0] = in[1] = broadcast(-kUnbounded);
    out[0] = V2d{inside(x0, x1), inside(x1, x2)}, out[1] = V2d{inside(x2, x3), inside(x3, x4)};
    return;
  }
  const V2d vo = broadcast(o), vi = broadcast(inv);
  const V2d e01 = (V2d{x0, x1} - vo) * vi, e23 = (V2d{x2, x3} - vo) * vi;
  const V2d e12 = (V2d{x1, x2} - vo) * vi, e34 = (V2d{x3, x4} - vo) * vi;
  in[0] = s > 0 ? e01 : e12, in[1] = s > 0 ? e23 : e34;
  out[0] = s > 0 ? e12 : e01, out[1] = s > 0 ? e34 : e23;
}

// The first (least t) of a block's 4 x 4 children whose part of the ray [ta, tb) (ta < tb: crossed) comes
// within the margin of the child's [min, max] (stored widened by it); its index 4 b + a in best (-1 if none)
// and its ta returned. The ray: z = oz + t dz, from t; xin .. yout: child_slabs'.
__attribute__((target_clones("avx2", "default"))) double first_child(double t, double oz_, double dz_, const WidePyramid::Block& block, const V2d* xin,
                          const V2d* xout, const V2d* yin, const V2d* yout, int& best) {
  const V2d t0 = broadcast(t), oz = broadcast(oz_), dz = broadcast(dz_);
  const V2d inf = broadcast(kUnbounded);
  alignas(16) double key[16];
  double yi_s[4], yo_s[4];
  std::memcpy(yi_s, yin, sizeof yi_s);
  std::memcpy(yo_s, yout, sizeof yo_s);
  for (int h = 0; h < 2; ++h) {  // columns 2 h, 2 h + 1
    const V2d xi = xin[h] > t0 ? xin[h] : t0, xo = xout[h];
    for (int b = 0; b < 4; ++b) {
      const V2d yi = broadcast(yi_s[b]), yo = broadcast(yo_s[b]);
      const V2d ta = xi > yi ? xi : yi, tb = xo < yo ? xo : yo;
      const V2d za = oz + ta * dz, zb = oz + tb * dz;
      const V2d zl = za < zb ? za : zb, zh = za < zb ? zb : za;
      const std::size_t i = std::size_t(4 * b + 2 * h);
      const V2d lo{double(block.lo[i]), double(block.lo[i + 1])}, hi{double(block.hi[i]), double(block.hi[i + 1])};
      const V2d k = (ta < tb) & (zl <= hi) & (zh >= lo) ? ta : inf;
      std::memcpy(&key[i], &k, sizeof k);
    }
  }
  V2d least = inf;  // the least key and the first child holding it, without a branch per child
  for (int i = 0; i < 16; i += 2) {
    V2d k;
    std::memcpy(&k, &key[i], sizeof k);
    least = k < least ? k : least;
  }
  const double first = least[0] < least[1] ? least[0] : least[1];
  unsigned mask = 0;
  for (int i = 0; i < 16; ++i) mask |= unsigned(key[i] == first) << i;
  best = first < kUnbounded ? __builtin_ctz(mask) : -1;
  return first;
}

}  // namespace

// Moves the walk into the child [ax, bx) x [ay, by) that the ray enters at tn (tin_x, tin_y: where it
// enters the child's column and row): the cell across the edge it enters through (at tn > w.t), else the
// cell holding the ray at tn.
void PyramidTracer::enter_child(Walk& w, int ax, int bx, int ay, int by, double tn, double tin_x, double tin_y) const {
  const bool step_x = tin_x >= tin_y && tin_x == tn && tn > w.t, step_y = tin_y >= tin_x && tin_y == tn && tn > w.t;
  w.ci = step_x ? (w.sx > 0 ? ax : bx - 1) : std::clamp(int(std::floor(w.ox + tn * w.dx)), ax, bx - 1);
  w.cj = step_y ? (w.sy > 0 ? ay : by - 1) : std::clamp(int(std::floor(w.oy + tn * w.dy)), ay, by - 1);
  w.entry = (step_x ? 1 : 0) | (step_y ? 2 : 0);
  if (tn > w.t) w.g_known = false;
  w.t = tn;
}

// Wide layout, level k (odd): the 4 x 4 children (level k) of the level-(k + 2) node holding the current
// cell, tested at once; the walk moves into the first the ray may hit (then works on its children, or its
// cells at k = 1) or passes the node.
void PyramidTracer::step_wide(Lane& lane) const {
  Walk& w = lane.w;
  const int k = lane.k, span = 1 << k, up = k + 2;
  const int px = (w.ci >> up) << up, py = (w.cj >> up) << up;
  const WidePyramid::Block& block = wide_->block(k, w.ci >> up, w.cj >> up);
  V2d xin[2], xout[2], yin[2], yout[2];
  child_slabs(w.ox, w.idx, w.sx, w.ci, px, span, xin, xout);
  child_slabs(w.oy, w.idy, w.sy, w.cj, py, span, yin, yout);
  int best = -1;
  const double first = first_child(w.t, w.oz, w.dz, block, xin, xout, yin, yout, best);
  if (best >= 0) {
    const int a = best & 3, b = best >> 2;
    const int ax = std::min(n_, px + a * span), ay = std::min(n_, py + b * span);
    const int bx = std::min(n_, ax + span), by = std::min(n_, ay + span);
    if (!(w.ci >= ax && w.ci < bx && w.cj >= ay && w.cj < by)) enter_child(w, ax, bx, ay, by, first, xin[a / 2][a % 2], yin[b / 2][b % 2]);
    lane.k = k == 1 ? 0 : k - 2;
    return;
  }
  const int bx = std::min(n_, px + 4 * span), by = std::min(n_, py + 4 * span);  // nothing in the node: pass it
  const double tx = w.sx > 0 ? (bx - w.ox) * w.idx : (w.sx < 0 ? (px - w.ox) * w.idx : kUnbounded);
  const double ty = w.sy > 0 ? (by - w.oy) * w.idy : (w.sy < 0 ? (py - w.oy) * w.idy : kUnbounded);
  const int gi = w.ci >> (up + 2), gj = w.cj >> (up + 2);
  advance(w, px, bx, py, by, tx, ty);
  w.g_known = false;
  if (k < top_ && (gi != w.ci >> (up + 2) || gj != w.cj >> (up + 2))) lane.k = k + 2;  // left the parent
}

HeightfieldHit PyramidTracer::trace(const Vec3<double>& origin, const Vec3<double>& dir,
                                    std::optional<std::uint32_t> skip_triangle) const {
  Lane lane;
  if (!start(lane, origin, dir, skip_triangle))
    while (!step(lane)) {
    }
  return lane.out;
}

void PyramidTracer::trace_batch(std::span<const Vec3<double>> origins, const Vec3<double>& dir,
                                std::span<HeightfieldHit> out) const {
  std::array<Lane, kLanes> lanes;
  std::array<std::size_t, kLanes> ray{};
  std::size_t next = 0;
  int live = 0;
  // Fills lane l with the next ray that is not done at once; false if none is left.
  const auto refill = [&](int l) {
    while (next < origins.size()) {
      const std::size_t i = next++;
      if (!start(lanes[std::size_t(l)], origins[i], dir, std::nullopt)) return ray[std::size_t(l)] = i, true;
      out[i] = lanes[std::size_t(l)].out;
    }
    return false;
  };
  std::array<bool, kLanes> active{};
  for (int l = 0; l < kLanes; ++l) live += (active[std::size_t(l)] = refill(l));
  while (live > 0) {
    for (int l = 0; l < kLanes; ++l) {
      if (!active[std::size_t(l)] || !step(lanes[std::size_t(l)])) continue;
      out[ray[std::size_t(l)]] = lanes[std::size_t(l)].out;
      if (!(active[std::size_t(l)] = refill(l))) --live;
    }
  }
}

}  // namespace microsim
