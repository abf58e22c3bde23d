// microsim: the min-max pyramid and its exact heightfield tracer (see heightfield_pyramid.h).
#include "trace/heightfield_pyramid.h"

#include "trace/heightfield_pyramid_lanes.h"
#include "trace/heightfield_trace.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <memory>
#include <span>

namespace microsim {

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

HeightPyramid::HeightPyramid(const microgeom::Heightfield& field) {
  const int n = field.resolution();
  std::size_t total = 0;
  for (int m = n; m > 1;) {
    m = (m + 1) / 2;
    levels_.push_back({m, total});
    total += std::size_t(m) * std::size_t(m);
  }
  nodes_.resize(total);
  for (std::size_t k = 0; k < levels_.size(); ++k) {
    const Level& level = levels_[k];
    const Level* child = k > 0 ? &levels_[k - 1] : nullptr;
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
              const auto& c = nodes_[child->offset + std::size_t(y) * std::size_t(child->n) + std::size_t(x)];
              lo = std::min(lo, c[0]), hi = std::max(hi, c[1]);
            }
        }
        nodes_[level.offset + std::size_t(b) * std::size_t(level.n) + std::size_t(a)] = {lo, hi};
      }
    });
  }
}

// ---- the tracer -----------------------------------------------------------------------------------------

PyramidTracer::PyramidTracer(const microgeom::Heightfield& field, double escape_height, double floor_height)
    : field_(field), pyramid_(field), n_(field.resolution()), tile_(field.tile_size()), cell_(field.cell_size()),
      inv_cell_(1.0 / field.cell_size()), escape_height_(escape_height), floor_height_(floor_height) {
  const double zmax = field.max_height(), zmin = field.min_height();
  margin_ = 1e-9 * (std::max(std::abs(zmax), std::abs(zmin)) + (zmax - zmin));
  batch_prefetch_ = n_ >= kPrefetchResolution;
  level_offset_.assign(1, 0.0);
  for (int k = 1; k <= pyramid_.top_level(); ++k) level_offset_.push_back(double(pyramid_.level_offset(k)));
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

// One ray's walk and its level.
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
  lane.k = skip_triangle ? 0 : pyramid_.top_level();
  return false;
}

// One step of the walk: a node passed or entered, or a cell tested. Returns true when the ray is done
// (lane.out holds its result).
bool PyramidTracer::step(Lane& lane) const {
  Walk& w = lane.w;
  int& k = lane.k;
  const double z = w.oz + w.t * w.dz;
  if (w.dz >= 0 && z > escape_height_) return lane.out.outcome = RayOutcome::escaped, true;
  if (w.dz <= 0 && z < floor_height_) return lane.out.outcome = RayOutcome::leaked, true;
  const int ax = (w.ci >> k) << k, ay = (w.cj >> k) << k;
  const int bx = std::min(n_, ax + (1 << k)), by = std::min(n_, ay + (1 << k));
  const double tx = w.sx > 0 ? (bx - w.ox) * w.idx : (w.sx < 0 ? (ax - w.ox) * w.idx : kUnbounded);
  const double ty = w.sy > 0 ? (by - w.oy) * w.idy : (w.sy < 0 ? (ay - w.oy) * w.idy : kUnbounded);
  const double t1 = std::max(std::min(tx, ty), w.t);
  if (k > 0) {
    const auto& mm = pyramid_.node(k, w.ci >> k, w.cj >> k);
    const double z1 = w.oz + t1 * w.dz;
    if (!(std::min(z, z1) > mm[1] + margin_ || std::max(z, z1) < mm[0] - margin_)) {
      --k;
      return false;
    }
    const int pi = w.ci >> (k + 1), pj = w.cj >> (k + 1);  // nothing in the node: pass it
    advance(w, ax, bx, ay, by, tx, ty);
    w.g_known = false;
    if (k < pyramid_.top_level() && (pi != w.ci >> (k + 1) || pj != w.cj >> (k + 1))) ++k;  // left the parent
  } else {
    const int i1 = w.ci + 1 == n_ ? 0 : w.ci + 1, j1 = w.cj + 1 == n_ ? 0 : w.cj + 1;
    Leaf c{field_.height_unchecked(w.ci, w.cj), field_.height_unchecked(i1, w.cj), field_.height_unchecked(w.ci, j1),
           field_.height_unchecked(i1, j1), t1, (tx <= ty ? 1 : 0) | (ty <= tx ? 2 : 0)};
    if (test_cell(w, c, lane.out)) {
      lane.out.segments = int(std::min<long>(w.wraps + 1, kMaxSegments));
      return true;
    }
    const int pi = w.ci >> 1, pj = w.cj >> 1;
    advance(w, ax, bx, ay, by, tx, ty);
    if (pi != w.ci >> 1 || pj != w.cj >> 1) k = 1;  // left the 2 x 2 node: try the next one
  }
  if (w.wraps < kMaxSegments) return false;
  lane.out.outcome = RayOutcome::unresolved;
  lane.out.segments = kMaxSegments;
  return true;
}

HeightfieldHit PyramidTracer::trace(const Vec3<double>& origin, const Vec3<double>& dir,
                                    std::optional<std::uint32_t> skip_triangle) const {
  Lane lane;
  if (!start(lane, origin, dir, skip_triangle))
    while (!step(lane)) {
    }
  return lane.out;
}

// ---- many rays in SIMD lanes ------------------------------------------------------------------------------

// The rays of a batch (rays[i], or origins[i] along dir), their results, and the walks in the lanes: the
// fields the vector steps use in `state` (pyramid_lanes::State), the rest of each walk in `lane`.
struct PyramidTracer::Batch {
  std::size_t n = 0, next = 0;
  const Ray* rays = nullptr;
  const Vec3<double>* origins = nullptr;
  Vec3<double> dir;
  HeightfieldHit* out = nullptr;
  pyramid_lanes::State state;
  std::array<Lane, pyramid_lanes::kMaxLanes> lane;
  std::array<std::size_t, pyramid_lanes::kMaxLanes> ray{};

  void to_state(std::size_t i) {
    const Walk& w = lane[i].w;
    pyramid_lanes::State& s = state;
    s.ox[i] = w.ox, s.oy[i] = w.oy, s.oz[i] = w.oz, s.dx[i] = w.dx, s.dy[i] = w.dy, s.dz[i] = w.dz;
    s.idx[i] = w.idx, s.idy[i] = w.idy, s.t[i] = w.t, s.g[i] = w.g, s.sx[i] = w.sx, s.sy[i] = w.sy;
    s.ci[i] = w.ci, s.cj[i] = w.cj, s.k[i] = lane[i].k, s.entry[i] = w.entry, s.g_known[i] = w.g_known;
    s.tile_x[i] = w.tile_x, s.tile_y[i] = w.tile_y, s.wraps[i] = w.wraps, s.done[i] = 0;
  }
  // The fields a vector step changes, back into lane i's walk.
  void from_state(std::size_t i) {
    Walk& w = lane[i].w;
    const pyramid_lanes::State& s = state;
    w.ox = s.ox[i], w.oy = s.oy[i], w.t = s.t[i], w.g = s.g[i], w.ci = int(s.ci[i]), w.cj = int(s.cj[i]);
    lane[i].k = int(s.k[i]), w.entry = int(s.entry[i]), w.g_known = s.g_known[i] != 0;
    w.tile_x = s.tile_x[i], w.tile_y = s.tile_y[i], w.wraps = s.wraps[i];
  }
};

// Lane i after the vector steps flagged it: its walk holding a cell the scalar code tests (one step(); a
// ray not finished by it goes back to the lanes), or no ray (finished, or at the start): then the batch's
// next ray not done at once is started in it. False when no ray is left for the lane (then parked).
bool PyramidTracer::settle(Batch& b, std::size_t i) const {
  Lane& lane = b.lane[i];
  if (b.ray[i] < b.n) {
    if (!step(lane)) {
      b.to_state(i);
      return true;
    }
    b.out[b.ray[i]] = lane.out;
  }
  for (b.ray[i] = b.n; b.next < b.n;) {
    const std::size_t r = b.next++;
    const bool done = b.rays ? start(lane, b.rays[r].origin, b.rays[r].dir, b.rays[r].skip_triangle)
                             : start(lane, b.origins[r], b.dir, std::nullopt);
    if (!done) {
      b.ray[i] = r;
      b.to_state(i);
      return true;
    }
    b.out[r] = lane.out;
  }
  b.state.done[i] = 4;  // parked: the vector steps leave it
  return false;
}

static_assert(PyramidTracer::kMaxBatchLanes == int(pyramid_lanes::kMaxLanes));

void PyramidTracer::run_batch(Batch& b) const {
  const std::size_t width = pyramid_lanes::vector_lanes();
  std::size_t lanes = batch_lanes_ > 0 ? std::size_t(batch_lanes_) : pyramid_lanes::kMaxLanes;
  lanes = std::min(pyramid_lanes::kMaxLanes / width * width, std::max(width, lanes / width * width));
  pyramid_lanes::Grid grid;
  grid.nodes = reinterpret_cast<const std::uint64_t*>(pyramid_.nodes().data());
  grid.heights = field_.heights().data();
  grid.level_offset = level_offset_.data();
  grid.margin = margin_, grid.escape_height = escape_height_, grid.floor_height = floor_height_;
  grid.n = n_, grid.top = pyramid_.top_level(), grid.max_segments = kMaxSegments, grid.prefetch = batch_prefetch_;
  std::uint64_t live = 0;
  for (std::size_t i = 0; i < lanes; ++i) {
    b.ray[i] = b.n;
    if (settle(b, i)) live |= std::uint64_t(1) << i;
  }
  while (live != 0) {
    for (std::uint64_t flagged = pyramid_lanes::step(grid, b.state, lanes) & live; flagged != 0; flagged &= flagged - 1) {
      const auto i = std::size_t(std::countr_zero(flagged));
      Lane& lane = b.lane[i];
      b.from_state(i);
      if (const std::int64_t done = b.state.done[i]; done != 0) {
        lane.out.outcome = done == 1 ? RayOutcome::escaped : (done == 2 ? RayOutcome::leaked : RayOutcome::unresolved);
        if (done == 3) lane.out.segments = kMaxSegments;
        b.out[b.ray[i]] = lane.out;
        b.ray[i] = b.n;  // finished: settle starts the next ray
      }
      if (!settle(b, i)) live &= ~(std::uint64_t(1) << i);
    }
  }
}

void PyramidTracer::trace_batch(std::span<const Vec3<double>> origins, const Vec3<double>& dir,
                                std::span<HeightfieldHit> out) const {
  auto b = std::make_unique<Batch>();
  b->n = origins.size(), b->origins = origins.data(), b->dir = dir, b->out = out.data();
  run_batch(*b);
}

void PyramidTracer::trace_batch(std::span<const Ray> rays, std::span<HeightfieldHit> out) const {
  auto b = std::make_unique<Batch>();
  b->n = rays.size(), b->rays = rays.data(), b->out = out.data();
  run_batch(*b);
}

}  // namespace microsim
