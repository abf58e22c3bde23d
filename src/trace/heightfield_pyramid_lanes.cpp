// microsim: the pyramid walk's node step in SIMD lanes (heightfield_pyramid_lanes.h). Compiled once per
// Highway target (hwy/foreach_target.h includes this file again for each) and called through
// HWY_DYNAMIC_DISPATCH. Every expression is the scalar step's (PyramidTracer::step and advance in
// heightfield_pyramid.cpp), in double, compiled without FMA contraction (CMakeLists.txt), with
// std::min / std::max's choice on ties, so that each lane's walk is the scalar walk to the bit.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "trace/heightfield_pyramid_lanes.cpp"
#include <hwy/foreach_target.h>  // before highway.h
#include <hwy/highway.h>

#include "trace/heightfield_pyramid_lanes.h"

#include <hwy/targets.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

HWY_BEFORE_NAMESPACE();
namespace microsim::pyramid_lanes::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;
using D = hn::ScalableTag<double>;
using DI = hn::RebindToSigned<D>;
using DU = hn::RebindToUnsigned<D>;
using V = hn::Vec<D>;
using VI = hn::Vec<DI>;
using M = hn::Mask<D>;
using MI = hn::Mask<DI>;

// A vector's cell tests wait for this many of its lanes at cells (or for no lane at a node).
constexpr std::size_t kCellBatch = 2;

// std::min(a, b) and std::max(a, b): b only if it is strictly less (greater), as <algorithm> chooses.
HWY_INLINE V std_min(V a, V b) { return hn::IfThenElse(hn::Lt(b, a), b, a); }
HWY_INLINE V std_max(V a, V b) { return hn::IfThenElse(hn::Lt(a, b), b, a); }

// The floats of a node's {min, max}, widened to double: min in the low 32 bits of each lane, max above.
HWY_INLINE void node_bounds(hn::Vec<DU> mm, V& lo, V& hi) {
  const D d;
  const hn::Rebind<std::uint32_t, D> du32;
  const hn::Rebind<float, D> df;
  lo = hn::PromoteTo(d, hn::BitCast(df, hn::TruncateTo(du32, mm)));
  hi = hn::PromoteTo(d, hn::BitCast(df, hn::TruncateTo(du32, hn::ShiftRight<32>(mm))));
}

// The exit distance of a node along one axis (step's tx, ty): to its far edge b or near edge a.
HWY_INLINE V exit_distance(VI s, VI a, VI b, V o, V inv) {
  const D d;
  const DI di;
  const V far = hn::Mul(hn::Sub(hn::ConvertTo(d, b), o), inv), near = hn::Mul(hn::Sub(hn::ConvertTo(d, a), o), inv);
  const V inf = hn::Set(d, std::numeric_limits<double>::infinity());
  return hn::IfThenElse(hn::RebindMask(d, hn::Gt(s, hn::Zero(di))), far,
                        hn::IfThenElse(hn::RebindMask(d, hn::Lt(s, hn::Zero(di))), near, inf));
}

// One axis of advance(): the cell the walk moves to (across the edge if it steps on this axis, else where
// the ray is at t1, clamped to the node), wrapped into the tile; o, tile and wraps updated alike.
HWY_INLINE VI advance_axis(const Grid& g, M step, VI s, VI a, VI b, V o_dir_t1, V& o, VI& tile, VI& wraps) {
  const D d;
  const DI di;
  const VI one = hn::Set(di, 1), n = hn::Set(di, g.n);
  const VI across = hn::IfThenElse(hn::Gt(s, hn::Zero(di)), b, hn::Sub(a, one));
  const VI at = hn::Min(hn::Max(hn::ConvertTo(di, hn::Floor(o_dir_t1)), a), hn::Sub(b, one));
  VI c = hn::IfThenElse(hn::RebindMask(di, step), across, at);
  const MI high = hn::Gt(c, hn::Sub(n, one)), low = hn::Lt(c, hn::Zero(di));
  const V nd = hn::Set(d, double(g.n));
  c = hn::IfThenElse(high, hn::Sub(c, n), hn::IfThenElse(low, hn::Add(c, n), c));
  o = hn::IfThenElse(hn::RebindMask(d, high), hn::Sub(o, nd), hn::IfThenElse(hn::RebindMask(d, low), hn::Add(o, nd), o));
  tile = hn::IfThenElse(high, hn::Add(tile, one), hn::IfThenElse(low, hn::Sub(tile, one), tile));
  wraps = hn::IfThenElse(hn::Or(high, low), hn::Add(wraps, one), wraps);
  return c;
}

// The height on a cell edge from ha to hb at fraction f, clamped (heightfield_pyramid.cpp edge_height).
HWY_INLINE V edge_height(V ha, V hb, V f) {
  const D d;
  const V zero = hn::Zero(d), one = hn::Set(d, 1.0);
  const V c = hn::IfThenElse(hn::Lt(f, zero), zero, hn::IfThenElse(hn::Lt(one, f), one, f));
  return hn::Add(ha, hn::Mul(c, hn::Sub(hb, ha)));
}

// A ray's walk at a step, as the lanes hold it.
struct Ray {
  V ox, oy, oz, dx, dy, dz, t;
  VI sx, sy, ci, cj, k;
};

// The four vertex heights of each lane's cell (h00, h10, h01, h11; lanes outside `lanes` read cell 0).
HWY_INLINE void cell_heights(const Grid& g, const Ray& r, MI lanes, V h[4]) {
  const D d;
  const DI di;
  const hn::Rebind<float, D> df;
  const hn::Rebind<std::int32_t, D> di32;
  const VI one = hn::Set(di, 1), n = hn::Set(di, g.n), zero = hn::Zero(di);
  const VI i1 = hn::IfThenElse(hn::Eq(hn::Add(r.ci, one), n), zero, hn::Add(r.ci, one));
  const VI j1 = hn::IfThenElse(hn::Eq(hn::Add(r.cj, one), n), zero, hn::Add(r.cj, one));
  const V nd = hn::Set(d, double(g.n));
  const V row0 = hn::Mul(hn::ConvertTo(d, hn::IfThenElseZero(lanes, r.cj)), nd);
  const V row1 = hn::Mul(hn::ConvertTo(d, hn::IfThenElseZero(lanes, j1)), nd);
  const V c0 = hn::ConvertTo(d, hn::IfThenElseZero(lanes, r.ci)), c1 = hn::ConvertTo(d, hn::IfThenElseZero(lanes, i1));
  const auto at = [&](V row, V col) {
    return hn::PromoteTo(d, hn::GatherIndex(df, g.heights, hn::DemoteTo(di32, hn::Add(row, col))));
  };
  h[0] = at(row0, c0), h[1] = at(row0, c1), h[2] = at(row1, c0), h[3] = at(row1, c1);
}

// The cell test of test_cell without its hit: true for the lanes whose g = z - surface height keeps its
// sign over the cell's parts (entry, diagonal crossing, exit: the same expressions). g1: g at the exit.
HWY_INLINE M cell_clear(const Grid& g, const State& s, std::size_t i, const Ray& r, MI lanes, V t1, M step_x, M step_y,
                        V& g1) {
  const D d;
  const DI di;
  V h[4];
  cell_heights(g, r, lanes, h);
  const V ci = hn::ConvertTo(d, r.ci), cj = hn::ConvertTo(d, r.cj), zero = hn::Zero(d);
  const auto u_at = [&](V t) { return hn::Sub(hn::Add(r.ox, hn::Mul(t, r.dx)), ci); };
  const auto v_at = [&](V t) { return hn::Sub(hn::Add(r.oy, hn::Mul(t, r.dy)), cj); };
  const auto g_at = [&](V t, V hs) { return hn::Sub(hn::Add(r.oz, hn::Mul(t, r.dz)), hs); };
  const V u0 = u_at(r.t), v0 = v_at(r.t), u1 = u_at(t1), v1 = v_at(t1);
  const M xp = hn::RebindMask(d, hn::Gt(r.sx, hn::Zero(di))), yp = hn::RebindMask(d, hn::Gt(r.sy, hn::Zero(di)));
  const VI entry = hn::Load(di, s.entry + i);
  const M known = hn::RebindMask(d, hn::Ne(hn::Load(di, s.g_known + i), hn::Zero(di)));
  const M e1 = hn::RebindMask(d, hn::Eq(entry, hn::Set(di, 1))), e2 = hn::RebindMask(d, hn::Eq(entry, hn::Set(di, 2)));
  // Entry 0 (the ray's start cell): the plane of the triangle under the start (plane_slopes).
  const M lower = hn::Ge(u0, v0);
  const V plane_x = hn::IfThenElse(lower, hn::Sub(h[1], h[0]), hn::Sub(h[3], h[2]));
  const V plane_y = hn::IfThenElse(lower, hn::Sub(h[3], h[1]), hn::Sub(h[2], h[0]));
  const V at_start = hn::Add(hn::Add(h[0], hn::Mul(plane_x, u0)), hn::Mul(plane_y, v0));
  const M e3 = hn::RebindMask(d, hn::Eq(entry, hn::Set(di, 3)));
  const V hs0 = hn::IfThenElse(
      e1, hn::IfThenElse(xp, edge_height(h[0], h[2], v0), edge_height(h[1], h[3], v0)),
      hn::IfThenElse(e2, hn::IfThenElse(yp, edge_height(h[0], h[1], u0), edge_height(h[2], h[3], u0)),
                     hn::IfThenElse(e3, hn::IfThenElse(xp, hn::IfThenElse(yp, h[0], h[2]), hn::IfThenElse(yp, h[1], h[3])),
                                    at_start)));
  const V g0 = hn::IfThenElse(known, hn::Load(d, s.g + i), g_at(r.t, hs0));
  const V hs1 = hn::IfThenElse(
      hn::AndNot(step_y, step_x), hn::IfThenElse(xp, edge_height(h[1], h[3], v1), edge_height(h[0], h[2], v1)),
      hn::IfThenElse(hn::AndNot(step_x, step_y),
                     hn::IfThenElse(yp, edge_height(h[2], h[3], u1), edge_height(h[0], h[1], u1)),
                     hn::IfThenElse(xp, hn::IfThenElse(yp, h[3], h[1]), hn::IfThenElse(yp, h[2], h[0]))));
  g1 = g_at(t1, hs1);
  const V d0 = hn::Sub(u0, v0), d1 = hn::Sub(u1, v1);
  const M crosses = hn::Or(hn::And(hn::Gt(d0, zero), hn::Lt(d1, zero)), hn::And(hn::Lt(d0, zero), hn::Gt(d1, zero)));
  const V td = hn::Add(r.t, hn::Mul(hn::Sub(t1, r.t), hn::Div(d0, hn::Sub(d0, d1))));
  const V sd = hn::Mul(hn::Set(d, 0.5), hn::Add(u_at(td), v_at(td)));
  const V gd = g_at(td, edge_height(h[0], h[3], sd));
  const M p0 = hn::Gt(g0, zero), p1 = hn::Gt(g1, zero), pd = hn::Gt(gd, zero);
  const M change = hn::Or(hn::And(crosses, hn::Or(hn::Xor(p0, pd), hn::Xor(pd, p1))), hn::AndNot(crosses, hn::Xor(p0, p1)));
  return hn::Not(change);
}

// The node test of step: true for the lanes whose part in the node [t, t1] lies above its maximum or
// below its minimum (by the margin).
HWY_INLINE M node_passed(const Grid& g, const Ray& r, MI lanes, V z, V z1) {
  const D d;
  const DI di;
  const DU du;
  // The node's {min, max}: level_offset[k] + (cj >> k) n_k + (ci >> k), exact integers in double.
  // Nodes per side of level k: ceil(N / 2^k).
  const VI nk = hn::Add(hn::Set(di, g.n), hn::Sub(hn::Set(di, 1) << r.k, hn::Set(di, 1))) >> r.k;
  const V index = hn::Add(hn::Add(hn::GatherIndex(d, g.level_offset, r.k),
                                  hn::Mul(hn::ConvertTo(d, r.cj >> r.k), hn::ConvertTo(d, nk))),
                          hn::ConvertTo(d, r.ci >> r.k));
  V lo, hi;
  node_bounds(hn::GatherIndex(du, g.nodes, hn::IfThenElseZero(lanes, hn::ConvertTo(di, index))), lo, hi);
  const V margin = hn::Set(d, g.margin);
  return hn::Or(hn::Gt(hn::Min(z, z1), hn::Add(hi, margin)), hn::Lt(hn::Max(z, z1), hn::Sub(lo, margin)));
}

// One step of lanes [i, i + Lanes(d)) (step: a node entered or passed, or a cell without a hit passed);
// returns their bits of done or of a cell the scalar code must test.
HWY_INLINE std::uint64_t step_vector(const Grid& g, State& s, std::size_t i) {
  const D d;
  const DI di;
  const VI zero = hn::Zero(di), one = hn::Set(di, 1);
  Ray r{hn::Load(d, s.ox + i), hn::Load(d, s.oy + i), hn::Load(d, s.oz + i), hn::Load(d, s.dx + i),
        hn::Load(d, s.dy + i), hn::Load(d, s.dz + i), hn::Load(d, s.t + i), hn::Load(di, s.sx + i),
        hn::Load(di, s.sy + i), hn::Load(di, s.ci + i), hn::Load(di, s.cj + i), hn::Load(di, s.k + i)};
  const VI done0 = hn::Load(di, s.done + i);
  const MI live = hn::Eq(done0, zero);
  if (hn::AllFalse(di, live)) return 0;  // every lane done or parked (a batch's tail)
  const MI at_node = hn::And(live, hn::Gt(r.k, zero)), at_cell = hn::AndNot(at_node, live);
  const V z = hn::Add(r.oz, hn::Mul(r.t, r.dz));
  const M escaped = hn::And(hn::Ge(r.dz, hn::Zero(d)), hn::Gt(z, hn::Set(d, g.escape_height)));
  const M leaked = hn::And(hn::Le(r.dz, hn::Zero(d)), hn::Lt(z, hn::Set(d, g.floor_height)));
  const VI ax = (r.ci >> r.k) << r.k, ay = (r.cj >> r.k) << r.k, size = one << r.k, n = hn::Set(di, g.n);
  const VI bx = hn::Min(n, hn::Add(ax, size)), by = hn::Min(n, hn::Add(ay, size));
  const V tx = exit_distance(r.sx, ax, bx, r.ox, hn::Load(d, s.idx + i));
  const V ty = exit_distance(r.sy, ay, by, r.oy, hn::Load(d, s.idy + i));
  const V t1 = std_max(std_min(tx, ty), r.t);
  const M step_x = hn::Le(tx, ty), step_y = hn::Le(ty, tx);
  // Each test only where a lane needs it (most steps of a walk are node steps).
  const M none = hn::FirstN(d, 0);
  const M pass = hn::AllFalse(di, at_node) ? none : node_passed(g, r, at_node, z, hn::Add(r.oz, hn::Mul(t1, r.dz)));
  V g1 = hn::Zero(d);
  // The cells' tests once enough lanes wait at cells (or no lane is at a node): they cost as much as the
  // node test, and a vector's lanes reach cells at different steps.
  const std::size_t cells = hn::CountTrue(di, at_cell);
  const bool test_cells = cells >= kCellBatch || (cells > 0 && hn::AllFalse(di, at_node));
  const M clear = test_cells ? cell_clear(g, s, i, r, at_cell, t1, step_x, step_y, g1) : none;
  const MI active = hn::AndNot(hn::RebindMask(di, hn::Or(escaped, leaked)), live);
  const MI moves = hn::And(active, hn::Or(hn::And(at_node, hn::RebindMask(di, pass)),
                                          hn::And(at_cell, hn::RebindMask(di, clear))));
  const MI enters = hn::And(active, hn::AndNot(hn::RebindMask(di, pass), at_node));
  const MI scalar = test_cells ? hn::And(active, hn::AndNot(hn::RebindMask(di, clear), at_cell)) : hn::FirstN(di, 0);
  // Moving on: advance() to the neighbouring cell across the exit edge(s); up a level if it left the
  // parent (a cell: its 2 x 2 node); g at the entry known after a cell, not after a node.
  const M md = hn::RebindMask(d, moves);
  V ox = r.ox, oy = r.oy;
  VI tile_x = hn::Load(di, s.tile_x + i), tile_y = hn::Load(di, s.tile_y + i), wraps = hn::Load(di, s.wraps + i);
  const VI ci1 = advance_axis(g, step_x, r.sx, ax, bx, hn::Add(r.ox, hn::Mul(t1, r.dx)), ox, tile_x, wraps);
  const VI cj1 = advance_axis(g, step_y, r.sy, ay, by, hn::Add(r.oy, hn::Mul(t1, r.dy)), oy, tile_y, wraps);
  const VI entry = hn::Or(hn::IfThenElseZero(hn::RebindMask(di, step_x), one),
                          hn::IfThenElseZero(hn::RebindMask(di, step_y), hn::Set(di, 2)));
  const VI k1 = hn::Add(r.k, one);
  const MI left = hn::Or(hn::Ne(r.ci >> k1, ci1 >> k1), hn::Ne(r.cj >> k1, cj1 >> k1));
  const VI k_moved = hn::IfThenElse(hn::And(left, hn::Lt(r.k, hn::Set(di, g.top))), k1, r.k);
  hn::Store(hn::IfThenElse(md, ox, r.ox), d, s.ox + i);
  hn::Store(hn::IfThenElse(md, oy, r.oy), d, s.oy + i);
  hn::Store(hn::IfThenElse(md, t1, r.t), d, s.t + i);
  hn::Store(hn::IfThenElse(moves, ci1, r.ci), di, s.ci + i);
  hn::Store(hn::IfThenElse(moves, cj1, r.cj), di, s.cj + i);
  hn::Store(hn::IfThenElse(moves, entry, hn::Load(di, s.entry + i)), di, s.entry + i);
  hn::Store(hn::IfThenElse(moves, hn::IfThenElseZero(at_cell, one), hn::Load(di, s.g_known + i)), di, s.g_known + i);
  hn::Store(hn::IfThenElse(hn::RebindMask(d, hn::And(moves, at_cell)), g1, hn::Load(d, s.g + i)), d, s.g + i);
  hn::Store(hn::IfThenElse(moves, tile_x, hn::Load(di, s.tile_x + i)), di, s.tile_x + i);
  hn::Store(hn::IfThenElse(moves, tile_y, hn::Load(di, s.tile_y + i)), di, s.tile_y + i);
  hn::Store(hn::IfThenElse(moves, wraps, hn::Load(di, s.wraps + i)), di, s.wraps + i);
  hn::Store(hn::IfThenElse(moves, k_moved, hn::IfThenElse(enters, hn::Sub(r.k, one), r.k)), di, s.k + i);
  const MI unresolved = hn::And(moves, hn::Gt(wraps, hn::Set(di, g.max_segments - 1)));
  const MI live_escaped = hn::And(live, hn::RebindMask(di, escaped)), live_leaked = hn::And(live, hn::RebindMask(di, leaked));
  const VI done = hn::IfThenElse(live_escaped, one, hn::IfThenElse(live_leaked, hn::Set(di, 2),
                                                                  hn::IfThenElse(unresolved, hn::Set(di, 3), done0)));
  hn::Store(done, di, s.done + i);
  std::uint8_t bits[8] = {};
  hn::StoreMaskBits(di, hn::And(live, hn::Or(scalar, hn::Ne(done, zero))), bits);
  std::uint64_t out = 0;
  std::memcpy(&out, bits, sizeof(out));  // lane b: bit b (little-endian)
  return out;
}

// Software prefetch of what each lane's next step reads: its node's {min, max}, or its cell's two rows
// of heights. Issued for all lanes before the steps, so that their reads are in flight together (a
// vector's gather holds up the steps after it until its slowest lane's read is back).
HWY_INLINE void prefetch(const Grid& g, const State& s, std::size_t lanes) {
  for (std::size_t j = 0; j < lanes; ++j) {
    const std::int64_t k = s.k[j], ci = s.ci[j], cj = s.cj[j], j1 = cj + 1 == g.n ? 0 : cj + 1;
    const std::int64_t nk = (g.n + (std::int64_t(1) << k) - 1) >> k;
    const std::int64_t node = std::int64_t(g.level_offset[k]) + (cj >> k) * nk + (ci >> k);
    const char* a = k > 0 ? reinterpret_cast<const char*>(g.nodes + node)
                          : reinterpret_cast<const char*>(g.heights + cj * g.n + ci);
    const char* b = k > 0 ? a : reinterpret_cast<const char*>(g.heights + j1 * g.n + ci);
    __builtin_prefetch(a);
    __builtin_prefetch(b);
  }
}

std::uint64_t step_lanes(const Grid& g, State& s, std::size_t lanes) {
  const std::size_t w = hn::Lanes(D());
  std::uint64_t flags = 0;
  if (g.prefetch) prefetch(g, s, lanes);
  for (std::size_t i = 0; i < lanes; i += w) flags |= step_vector(g, s, i) << i;
  return flags;
}

std::size_t lanes_of_target() { return hn::Lanes(D()); }
std::int64_t target_bit() { return HWY_TARGET; }

}  // namespace microsim::pyramid_lanes::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace microsim::pyramid_lanes {

HWY_EXPORT(step_lanes);
HWY_EXPORT(lanes_of_target);
HWY_EXPORT(target_bit);

std::uint64_t step(const Grid& grid, State& state, std::size_t lanes) {
  return HWY_DYNAMIC_DISPATCH(step_lanes)(grid, state, lanes);
}
std::size_t vector_lanes() { return HWY_DYNAMIC_DISPATCH(lanes_of_target)(); }
std::string target_name() { return hwy::TargetName(HWY_DYNAMIC_DISPATCH(target_bit)()); }

}  // namespace microsim::pyramid_lanes
#endif  // HWY_ONCE
