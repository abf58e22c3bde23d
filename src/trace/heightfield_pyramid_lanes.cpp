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
#include <limits>

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

// The node step of lanes [i, i + Lanes(d)); returns their bits of k = 0 or done.
HWY_INLINE std::uint64_t step_vector(const Grid& g, State& s, std::size_t i) {
  const D d;
  const DI di;
  const DU du;
  const VI zero = hn::Zero(di), one = hn::Set(di, 1);
  const V ox0 = hn::Load(d, s.ox + i), oy0 = hn::Load(d, s.oy + i), oz = hn::Load(d, s.oz + i);
  const V dx = hn::Load(d, s.dx + i), dy = hn::Load(d, s.dy + i), dz = hn::Load(d, s.dz + i);
  const V t = hn::Load(d, s.t + i);
  const VI sx = hn::Load(di, s.sx + i), sy = hn::Load(di, s.sy + i);
  const VI ci = hn::Load(di, s.ci + i), cj = hn::Load(di, s.cj + i), k = hn::Load(di, s.k + i);
  const VI done0 = hn::Load(di, s.done + i);
  const MI live = hn::And(hn::Gt(k, zero), hn::Eq(done0, zero));
  const V z = hn::Add(oz, hn::Mul(t, dz));
  const M escaped = hn::And(hn::Ge(dz, hn::Zero(d)), hn::Gt(z, hn::Set(d, g.escape_height)));
  const M leaked = hn::And(hn::Le(dz, hn::Zero(d)), hn::Lt(z, hn::Set(d, g.floor_height)));
  const VI ax = (ci >> k) << k, ay = (cj >> k) << k;
  const VI size = one << k, n = hn::Set(di, g.n);
  const VI bx = hn::Min(n, hn::Add(ax, size)), by = hn::Min(n, hn::Add(ay, size));
  const V tx = exit_distance(sx, ax, bx, ox0, hn::Load(d, s.idx + i));
  const V ty = exit_distance(sy, ay, by, oy0, hn::Load(d, s.idy + i));
  const V t1 = std_max(std_min(tx, ty), t);
  // The node's {min, max}: level_offset[k] + (cj >> k) n_k + (ci >> k), exact integers in double.
  const V index = hn::Add(hn::Add(hn::GatherIndex(d, g.level_offset, k),
                                  hn::Mul(hn::ConvertTo(d, cj >> k), hn::GatherIndex(d, g.level_n, k))),
                          hn::ConvertTo(d, ci >> k));
  V lo, hi;
  node_bounds(hn::GatherIndex(du, g.nodes, hn::IfThenElseZero(live, hn::ConvertTo(di, index))), lo, hi);
  const V z1 = hn::Add(oz, hn::Mul(t1, dz));
  const V margin = hn::Set(d, g.margin);
  const M pass = hn::Or(hn::Gt(hn::Min(z, z1), hn::Add(hi, margin)), hn::Lt(hn::Max(z, z1), hn::Sub(lo, margin)));
  const M active = hn::AndNot(hn::Or(escaped, leaked), hn::RebindMask(d, live));
  const M moves = hn::And(active, pass);
  // Passed: advance() to the neighbouring cell across the node's exit edge(s), up a level if it left
  // the parent.
  V ox = ox0, oy = oy0;
  VI tile_x = hn::Load(di, s.tile_x + i), tile_y = hn::Load(di, s.tile_y + i), wraps = hn::Load(di, s.wraps + i);
  const M step_x = hn::Le(tx, ty), step_y = hn::Le(ty, tx);
  const VI ci1 = advance_axis(g, step_x, sx, ax, bx, hn::Add(ox0, hn::Mul(t1, dx)), ox, tile_x, wraps);
  const VI cj1 = advance_axis(g, step_y, sy, ay, by, hn::Add(oy0, hn::Mul(t1, dy)), oy, tile_y, wraps);
  const VI entry = hn::Or(hn::IfThenElseZero(hn::RebindMask(di, step_x), one),
                          hn::IfThenElseZero(hn::RebindMask(di, step_y), hn::Set(di, 2)));
  const VI k1 = hn::Add(k, one);
  const MI left = hn::Or(hn::Ne(ci >> k1, ci1 >> k1), hn::Ne(cj >> k1, cj1 >> k1));
  const VI k_passed = hn::IfThenElse(hn::And(left, hn::Lt(k, hn::Set(di, g.top))), k1, k);
  const MI mi = hn::RebindMask(di, moves), enters = hn::RebindMask(di, hn::AndNot(pass, active));
  const MI unresolved = hn::And(mi, hn::Gt(wraps, hn::Set(di, g.max_segments - 1)));
  hn::Store(hn::IfThenElse(moves, ox, ox0), d, s.ox + i);
  hn::Store(hn::IfThenElse(moves, oy, oy0), d, s.oy + i);
  hn::Store(hn::IfThenElse(moves, t1, t), d, s.t + i);
  hn::Store(hn::IfThenElse(mi, ci1, ci), di, s.ci + i);
  hn::Store(hn::IfThenElse(mi, cj1, cj), di, s.cj + i);
  hn::Store(hn::IfThenElse(mi, entry, hn::Load(di, s.entry + i)), di, s.entry + i);
  hn::Store(hn::IfThenElseZero(hn::Not(mi), hn::Load(di, s.g_known + i)), di, s.g_known + i);
  hn::Store(hn::IfThenElse(mi, tile_x, hn::Load(di, s.tile_x + i)), di, s.tile_x + i);
  hn::Store(hn::IfThenElse(mi, tile_y, hn::Load(di, s.tile_y + i)), di, s.tile_y + i);
  hn::Store(hn::IfThenElse(mi, wraps, hn::Load(di, s.wraps + i)), di, s.wraps + i);
  const VI k_new = hn::IfThenElse(mi, k_passed, hn::IfThenElse(enters, hn::Sub(k, one), k));
  hn::Store(k_new, di, s.k + i);
  const VI done = hn::IfThenElse(hn::RebindMask(di, hn::And(escaped, hn::RebindMask(d, live))), one,
                                 hn::IfThenElse(hn::RebindMask(di, hn::And(leaked, hn::RebindMask(d, live))),
                                                hn::Set(di, 2), hn::IfThenElse(unresolved, hn::Set(di, 3), done0)));
  hn::Store(done, di, s.done + i);
  std::uint8_t bits[8] = {};
  hn::StoreMaskBits(di, hn::Or(hn::Eq(k_new, zero), hn::Ne(done, zero)), bits);
  std::uint64_t out = 0;
  for (std::size_t b = 0; b < 8; ++b) out |= std::uint64_t(bits[b]) << (8 * b);
  return out;
}

std::uint64_t step_lanes(const Grid& g, State& s, std::size_t lanes) {
  const std::size_t w = hn::Lanes(D());
  std::uint64_t flags = 0;
  for (int round = 0; round < g.rounds; ++round)
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
