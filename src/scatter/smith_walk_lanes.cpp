// scatter: the Smith walk with paths in SIMD lanes (smith_walk_lanes.h). The step below is compiled once per
// Highway target (hwy/foreach_target.h includes this file again for each) and the best one the CPU supports
// is called through HWY_DYNAMIC_DISPATCH; the rest is compiled once (HWY_ONCE).
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "scatter/smith_walk_lanes.cpp"
#include <hwy/foreach_target.h>  // before highway.h
#include <hwy/highway.h>
#include <hwy/contrib/math/math-inl.h>

#include "scatter/smith_walk_lanes.h"

#include "core/math.h"
#include "core/random.h"

#include <hwy/targets.h>

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <stdexcept>

// ---- the lanes' state (compiled once) ----------------------------------------------------------------------
#ifndef MICROSIM_SMITH_WALK_LANES_SHARED
#define MICROSIM_SMITH_WALK_LANES_SHARED
namespace microsim::walk_lanes {

// The most lanes of doubles of any target (2048-bit SVE); x86 has at most 8 (AVX-512).
inline constexpr std::size_t kMaxLanes = 32;

// ln C1 kept in [ln DBL_MIN, ln(1 - 2^-53)] after a meeting, as the scalar walk keeps it (smith_walk.cpp).
inline constexpr double kLogCdfMin = -708.39641853226410622;
inline constexpr double kLogCdfMax = -1.1102230246251565e-16;

// Ends of a step, per lane (a double, so that the vector code stores it as it stores the state).
inline constexpr double kGoesOn = 0, kEscaped = 1, kUnfinished = 2, kLost = 3;

// The state of the paths in the lanes, structure of arrays: lane i holds path[i] of the block (while live).
struct Lanes {
  alignas(64) double wx[kMaxLanes], wy[kMaxLanes], wz[kMaxLanes];  // travel direction, in the side's frame
  alignas(64) double g[kMaxLanes];                                   // ln C1(h) of the last meeting, 0 before
  alignas(64) double events[kMaxLanes];                              // facet events so far
  alignas(64) double inside[kMaxLanes];                              // 1 in the dielectric's solid, else 0
  alignas(64) double end[kMaxLanes];                                 // this step's outcome (kGoesOn, ...)
  alignas(64) std::uint64_t counter[kMaxLanes];                      // the path's stream: draws so far
  alignas(64) double weight[Material::kMaxChannels][kMaxLanes];      // conductor only (else 1)
  std::uint64_t path[kMaxLanes];
};

}  // namespace microsim::walk_lanes
#endif  // MICROSIM_SMITH_WALK_LANES_SHARED

// ---- one step of every lane: compiled once per target ------------------------------------------------------
HWY_BEFORE_NAMESPACE();
namespace microsim::walk_lanes::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;
using D = hn::ScalableTag<double>;
using V = hn::Vec<D>;
using M = hn::Mask<D>;
using DU = hn::RebindToUnsigned<D>;
using VU = hn::Vec<DU>;

// SplitMix64's output mixing (core/random.h mix64), lane by lane.
HWY_INLINE VU mix64(DU du, VU z) {
  z = hn::Mul(hn::Xor(z, hn::ShiftRight<30>(z)), hn::Set(du, 0xbf58476d1ce4e5b9ULL));
  z = hn::Mul(hn::Xor(z, hn::ShiftRight<27>(z)), hn::Set(du, 0x94d049bb133111ebULL));
  return hn::Xor(z, hn::ShiftRight<31>(z));
}

// Draw i of a path's stream, uniform in [0, 1) with 53 random bits: mix64(key + 0x9e3779b97f4a7c15 i), the
// form of CounterRng's draws (core/random.h), with the block's key.
HWY_INLINE V uniform(D d, VU key, VU i) {
  const DU du;
  const VU bits = hn::ShiftRight<11>(mix64(du, hn::Add(key, hn::Mul(hn::Set(du, 0x9e3779b97f4a7c15ULL), i))));
  return hn::Mul(hn::ConvertTo(d, hn::BitCast(hn::RebindToSigned<D>(), bits)), hn::Set(d, 0x1.0p-53));
}

// Smith's Lambda for GGX (Heitz 2014, "Understanding the Masking-Shadowing Function", eq. 86), in the
// cancellation-free form of microfacet/ggx.h: (ax^2 wx^2 + ay^2 wy^2) / (2 |wz| (t + |wz|)), t the stretched
// length; 0 where the slope term is 0, +inf on the horizon. Symmetric in w -> -w, as the walk uses it.
HWY_INLINE V lambda_ggx(D d, V sx, V sy, V wz, V t) {
  const V a2 = hn::MulAdd(sx, sx, hn::Mul(sy, sy)), z = hn::Abs(wz);
  return hn::IfThenZeroElse(a2 == hn::Zero(d), hn::Div(a2, hn::Mul(hn::Set(d, 2.0), hn::Mul(z, hn::Add(t, z)))));
}

// (cos 2 pi u, sin 2 pi u) for u in [0, 1), by quadrant: 4u = k + f with k = round(4u) and f in [-1/2, 1/2]
// exact (4u and k share u's binary scale), so 2 pi u = k pi/2 + x with x = f pi/2 in [-pi/4, pi/4], rounded
// once; sin x and cos x by their Taylor series to x^15 and x^16 (the next terms are below 5e-17 on that
// interval), then the quarter turns k: (c, s), (-s, c), (-c, -s), (s, -c). One reduction for both, where
// hwy/contrib/math's Sin and Cos reduce twice.
HWY_INLINE void sincos_two_pi(D d, V u, V& cos_phi, V& sin_phi) {
  const V t = hn::Mul(hn::Set(d, 4.0), u), k = hn::Round(t);
  const V x = hn::Mul(hn::Sub(t, k), hn::Set(d, kPi<double> / 2)), x2 = hn::Mul(x, x);
  // 1 / n! for n = 1 .. 16.
  constexpr double f[17] = {1.0, 1.0, 1.0 / 2, 1.0 / 6, 1.0 / 24, 1.0 / 120, 1.0 / 720, 1.0 / 5040, 1.0 / 40320,
                            1.0 / 362880, 1.0 / 3628800, 1.0 / 39916800, 1.0 / 479001600, 1.0 / 6227020800.0,
                            1.0 / 87178291200.0, 1.0 / 1307674368000.0, 1.0 / 20922789888000.0};
  V ps = hn::Set(d, -f[15]), pc = hn::Set(d, f[16]);  // sin x = x sum (-1)^i x^2i / (2i+1)!, cos alike
  for (int i = 6; i >= 0; --i) ps = hn::MulAdd(ps, x2, hn::Set(d, (i % 2 ? -1.0 : 1.0) * f[2 * i + 1]));
  for (int i = 7; i >= 0; --i) pc = hn::MulAdd(pc, x2, hn::Set(d, (i % 2 ? -1.0 : 1.0) * f[2 * i]));
  const V s = hn::Mul(x, ps), c = pc;
  const M q1 = k == hn::Set(d, 1.0), q2 = k == hn::Set(d, 2.0), q3 = k == hn::Set(d, 3.0);
  const M swap = hn::Or(q1, q3);
  const V a = hn::IfThenElse(swap, s, c), b = hn::IfThenElse(swap, c, s);
  cos_phi = hn::IfThenElse(hn::Or(q1, q2), hn::Neg(a), a);
  sin_phi = hn::IfThenElse(hn::Or(q2, q3), hn::Neg(b), b);
}

// The microfacet normal a ray travelling in w meets: a sample of the upper visible normals of v = -w
// (upper_vndf.h). Stretched to alpha = 1 (Heitz 2018, "Sampling the GGX Distribution of Visible Normals",
// JCGT 7(4), sec. 4, step 1: Vh = normalize(ax vx, ay vy, vz)), the visible normals of the hemisphere
// configuration are the half vectors of Vh and of a uniform direction c on the spherical cap z >= -Vh.z
// (Dupuy & Benyoub 2023, "Sampling Visible GGX Normals with Spherical Caps", CGF 42(8), sec. 3-4; the same
// density as Heitz 2018's disk construction for Vh above the horizon, and below it the construction
// upper_vndf.h uses), unstretched as a normal (Heitz 2018 sec. 4, step 4: normalize(ax Nh.x, ay Nh.y, Nh.z)).
// Nh = c + Vh need not be unit: the last normalisation absorbs its length. mz is NaN or <= 0 only where
// nothing faces v (v straight down).
HWY_INLINE void visible_normal(D d, V ax, V ay, V sx, V sy, V wz, V t, V u1, V u2, V& mx, V& my, V& mz) {
  const V one = hn::Set(d, 1.0), inv_t = hn::Div(one, t);
  const V vx = hn::Neg(hn::Mul(sx, inv_t)), vy = hn::Neg(hn::Mul(sy, inv_t)), vz = hn::Neg(hn::Mul(wz, inv_t));
  V cos_phi, sin_phi;
  sincos_two_pi(d, u1, cos_phi, sin_phi);
  const V cz = hn::MulSub(hn::Sub(one, u2), hn::Add(one, vz), vz);  // uniform in (-vz, 1]
  const V sin_theta = hn::Sqrt(hn::Max(hn::Zero(d), hn::NegMulAdd(cz, cz, one)));
  const V hx = hn::MulAdd(sin_theta, cos_phi, vx), hy = hn::MulAdd(sin_theta, sin_phi, vy);
  const V hz = hn::Add(cz, vz);
  const V nx = hn::Mul(ax, hx), ny = hn::Mul(ay, hy);
  const V inv_len = hn::Div(one, hn::Sqrt(hn::MulAdd(nx, nx, hn::MulAdd(ny, ny, hn::Mul(hz, hz)))));
  mx = hn::Mul(nx, inv_len);
  my = hn::Mul(ny, inv_len);
  mz = hn::Mul(hz, inv_len);
}

// The Fresnel reflectance of a conductor of complex index eta = n + i k at cos_i (Born & Wolf, "Principles
// of Optics", sec. 14.4.1, in the real form with a^2 + b^2 = sqrt((n^2 - k^2 - sin^2)^2 + 4 n^2 k^2),
// a^2 = (a^2 + b^2 + n^2 - k^2 - sin^2) / 2): (Rs + Rp) / 2, equal to microfacet/bsdf.h's fresnel_conductor.
HWY_INLINE V fresnel_conductor(D d, V cos_i, double n, double k) {
  const V c = hn::Min(hn::Max(cos_i, hn::Zero(d)), hn::Set(d, 1.0)), c2 = hn::Mul(c, c);
  const V s2 = hn::Sub(hn::Set(d, 1.0), c2);
  const V t0 = hn::Sub(hn::Set(d, n * n - k * k), s2);
  const V ab = hn::Sqrt(hn::MulAdd(t0, t0, hn::Set(d, 4 * n * n * k * k)));
  const V a = hn::Sqrt(hn::Max(hn::Zero(d), hn::Mul(hn::Set(d, 0.5), hn::Add(ab, t0))));
  const V two_ac = hn::Mul(hn::Set(d, 2.0), hn::Mul(a, c)), ab_c2 = hn::Add(ab, c2);
  const V rs = hn::Div(hn::Sub(ab_c2, two_ac), hn::Add(ab_c2, two_ac));
  const V t3 = hn::MulAdd(c2, ab, hn::Mul(s2, s2)), t4 = hn::Mul(two_ac, s2);
  const V rp = hn::Mul(rs, hn::Div(hn::Sub(t3, t4), hn::Add(t3, t4)));
  return hn::Mul(hn::Set(d, 0.5), hn::Add(rs, rp));
}

// ln(1 - e^g) for g <= 0: the side change of the heights, C1 -> 1 - C1 (smith_walk.cpp), as ln(-expm1(g)),
// two transcendentals where the scalar walk's two-branch form (Maechler 2012, "Accurately computing
// log(1 - exp(-|a|))") takes four for a vector. The same near g = 0 (C1 = 1, where 1 - C1 needs expm1); for
// g < -ln 2 it computes 1 - C1 rounded to double (an absolute error of 2^-53 in C1', the resolution at
// which the walk already clamps C1 <= 1 - 2^-53), where the two-branch form keeps ln(1 - C1) to a relative
// 2^-53: a difference in escape probabilities of order Lambda 1e-16 per refraction.
HWY_INLINE V log_one_minus_exp(D d, V g) { return hn::Log(d, hn::Neg(hn::Expm1(d, g))); }

// A lane's direction (and for a dielectric its side and height) after the facet event at m, for the lanes
// that meet; the rest keep theirs. w_m = <w, m> = -cos_i.
struct Event {
  V wx, wy, wz, g, inside;
};

// The dielectric's event (microfacet/material.cpp scatter_on_facet): reflect with probability
// F = fresnel_dielectric(cos_i, eta) (Walter et al. 2007 eq. 22; 1 beyond the critical angle), else refract
// (Snell's law in vector form, core/math.h refract: t = -wi / eta + (cos_i / eta - cos_t) m, wi = -w), and a
// refraction changes side: the direction -t, ln C1 -> ln(1 - C1) (Heitz et al. 2016 sec. 5.2).
HWY_INLINE void dielectric_event(D d, const LaneWalk& walk, M meets, V w_m, V mx, V my, V mz, V u3, Event& e) {
  const V zero = hn::Zero(d), one = hn::Set(d, 1.0);
  const M in = e.inside > hn::Set(d, 0.5);  // eta and 1 / eta of this side, without a division
  const V eta = hn::IfThenElse(in, hn::Set(d, 1 / walk.eta), hn::Set(d, walk.eta));
  const V inv_eta = hn::IfThenElse(in, hn::Set(d, walk.eta), hn::Set(d, 1 / walk.eta));
  const V cos_i = hn::Min(hn::Max(hn::Neg(w_m), zero), one);
  const V sin2_t = hn::Mul(hn::NegMulAdd(cos_i, cos_i, one), hn::Mul(inv_eta, inv_eta));
  const M tir = sin2_t >= one;
  const V cos_t = hn::Sqrt(hn::Max(zero, hn::Sub(one, sin2_t)));
  const V e_ci = hn::Mul(eta, cos_i), e_ct = hn::Mul(eta, cos_t);
  // F = (r_parl^2 + r_perp^2) / 2 with r_parl = a / b, r_perp = c / e, over one division.
  const V a = hn::Sub(e_ci, cos_t), b = hn::Add(e_ci, cos_t), c = hn::Sub(cos_i, e_ct), e_ = hn::Add(cos_i, e_ct);
  const V ae = hn::Mul(a, e_), cb = hn::Mul(c, b), be = hn::Mul(b, e_);
  const V f = hn::Div(hn::Mul(hn::Set(d, 0.5), hn::MulAdd(ae, ae, hn::Mul(cb, cb))), hn::Mul(be, be));
  const M refracts = hn::And(hn::And(meets, cos_i > zero), hn::AndNot(tir, u3 >= f));
  const V two_w_m = hn::Add(w_m, w_m);
  const V k = hn::Sub(hn::Mul(cos_i, inv_eta), cos_t);  // t = w / eta + k m
  const V tx = hn::MulAdd(e.wx, inv_eta, hn::Mul(k, mx)), ty = hn::MulAdd(e.wy, inv_eta, hn::Mul(k, my));
  const V tz = hn::MulAdd(e.wz, inv_eta, hn::Mul(k, mz));
  const V neg_inv_len = hn::Neg(hn::Div(one, hn::Sqrt(hn::MulAdd(tx, tx, hn::MulAdd(ty, ty, hn::Mul(tz, tz))))));
  const V rx = hn::NegMulAdd(two_w_m, mx, e.wx), ry = hn::NegMulAdd(two_w_m, my, e.wy), rz = hn::NegMulAdd(two_w_m, mz, e.wz);
  e.wx = hn::IfThenElse(refracts, hn::Mul(tx, neg_inv_len), hn::IfThenElse(meets, rx, e.wx));
  e.wy = hn::IfThenElse(refracts, hn::Mul(ty, neg_inv_len), hn::IfThenElse(meets, ry, e.wy));
  e.wz = hn::IfThenElse(refracts, hn::Mul(tz, neg_inv_len), hn::IfThenElse(meets, rz, e.wz));
  e.inside = hn::IfThenElse(refracts, hn::Sub(one, e.inside), e.inside);
  if (!hn::AllFalse(d, refracts)) {
    const V other = hn::Min(hn::Max(log_one_minus_exp(d, e.g), hn::Set(d, kLogCdfMin)), hn::Set(d, kLogCdfMax));
    e.g = hn::IfThenElse(refracts, other, e.g);
  }
}

// The mirror's and the conductor's event: w' = w - 2 <w, m> m, the conductor's F per channel.
HWY_INLINE void reflecting_event(D d, const LaneWalk& walk, Lanes& st, std::size_t first, M meets, V w_m, V mx, V my,
                                 V mz, Event& e) {
  const V two_w_m = hn::Add(w_m, w_m);
  e.wx = hn::IfThenElse(meets, hn::NegMulAdd(two_w_m, mx, e.wx), e.wx);
  e.wy = hn::IfThenElse(meets, hn::NegMulAdd(two_w_m, my, e.wy), e.wy);
  e.wz = hn::IfThenElse(meets, hn::NegMulAdd(two_w_m, mz, e.wz), e.wz);
  if (!walk.conductor) return;
  for (int c = 0; c < walk.channels; ++c) {
    double* w = st.weight[c] + first;
    const V f = fresnel_conductor(d, hn::Neg(w_m), walk.n[std::size_t(c)], walk.k[std::size_t(c)]);
    hn::Store(hn::IfThenElse(meets, hn::Mul(hn::Load(d, w), f), hn::Load(d, w)), d, w);
  }
}

// One step of the walk (Heitz et al. 2016 sec. 3-5) for lanes [first, first + Lanes): the step's random
// numbers from each path's stream, the next meeting's height from g = ln C1(h) (escape upward iff
// ln U <= Lambda g, else g' = g - ln U / Lambda; downward g' = g + ln U / (1 + Lambda); smith_walk.cpp states
// the rules), then, for the lanes that meet the surface below the order cap, the normal and the facet event.
// Writes each lane's outcome to st.end (a lane that ended keeps its direction and weights) and returns the
// lanes that ended as bits (bit i: lane first + i).
std::uint64_t step_vector(const LaneWalk& walk, Lanes& st, std::size_t first, std::uint64_t block_key) {
  const D d;
  const DU du;
  const VU key = hn::Set(du, block_key), counter = hn::Load(du, st.counter + first);
  const V u0 = uniform(d, key, hn::Add(counter, hn::Set(du, 1))), u1 = uniform(d, key, hn::Add(counter, hn::Set(du, 2)));
  const V u2 = uniform(d, key, hn::Add(counter, hn::Set(du, 3)));
  hn::Store(hn::Add(counter, hn::Set(du, walk.dielectric ? 4 : 3)), du, st.counter + first);
  const V zero = hn::Zero(d), one = hn::Set(d, 1.0), ax = hn::Set(d, walk.alpha_x), ay = hn::Set(d, walk.alpha_y);
  Event e{hn::Load(d, st.wx + first), hn::Load(d, st.wy + first), hn::Load(d, st.wz + first), hn::Load(d, st.g + first),
          hn::Load(d, st.inside + first)};
  const V events = hn::Load(d, st.events + first);
  const V sx = hn::Mul(ax, e.wx), sy = hn::Mul(ay, e.wy);
  const V t = hn::Sqrt(hn::MulAdd(sx, sx, hn::MulAdd(sy, sy, hn::Mul(e.wz, e.wz))));
  const V lambda = lambda_ggx(d, sx, sy, e.wz, t);
  const V log_u = hn::Log(d, hn::Sub(one, u0));  // ln U, U = 1 - u in (0, 1]
  const M up = e.wz > zero;
  const M escaped = hn::And(up, hn::Or(e.g == zero, log_u <= hn::Mul(lambda, e.g)));
  const V g_raw = hn::IfThenElse(up, hn::Sub(e.g, hn::Div(log_u, lambda)), hn::Add(e.g, hn::Div(log_u, hn::Add(one, lambda))));
  const V g_next = hn::IfThenElse(g_raw == e.g, e.g, hn::Min(hn::Max(g_raw, hn::Set(d, kLogCdfMin)), hn::Set(d, kLogCdfMax)));
  const M capped = hn::AndNot(escaped, events == hn::Set(d, double(walk.max_order)));
  V mx, my, mz;
  visible_normal(d, ax, ay, sx, sy, e.wz, t, u1, u2, mx, my, mz);
  const M lost = hn::AndNot(hn::Or(escaped, capped), hn::Not(mz > zero));
  const M meets = hn::Not(hn::Or(hn::Or(escaped, capped), lost));
  const V w_m = hn::MulAdd(e.wx, mx, hn::MulAdd(e.wy, my, hn::Mul(e.wz, mz)));  // <w, m> = -cos_i
  e.g = hn::IfThenElse(meets, g_next, e.g);
  if (walk.dielectric) {
    dielectric_event(d, walk, meets, w_m, mx, my, mz, uniform(d, key, hn::Add(counter, hn::Set(du, 4))), e);
    hn::Store(e.inside, d, st.inside + first);
  } else {
    reflecting_event(d, walk, st, first, meets, w_m, mx, my, mz, e);
  }
  hn::Store(e.wx, d, st.wx + first);
  hn::Store(e.wy, d, st.wy + first);
  hn::Store(e.wz, d, st.wz + first);
  hn::Store(e.g, d, st.g + first);
  hn::Store(hn::IfThenElse(meets, hn::Add(events, one), events), d, st.events + first);
  const V end = hn::IfThenElse(escaped, hn::Set(d, kEscaped),
                               hn::IfThenElse(capped, hn::Set(d, kUnfinished), hn::IfThenElseZero(lost, hn::Set(d, kLost))));
  hn::Store(end, d, st.end + first);
  std::uint64_t bits = 0;  // StoreMaskBits writes (lanes + 7) / 8 <= 4 bytes, little-endian bit order
  std::uint8_t bytes[8] = {};
  hn::StoreMaskBits(d, hn::Not(meets), bytes);
  for (std::size_t b = 0; b < (hn::Lanes(d) + 7) / 8; ++b) bits |= std::uint64_t(bytes[b]) << (8 * b);
  return bits;
}

// sincos_two_pi over whole vectors of u (tests): returns how many it did (a multiple of the vector width).
std::size_t sincos_vectors(const double* u, std::size_t n, double* c, double* s) {
  const D d;
  std::size_t i = 0;
  for (; i + hn::Lanes(d) <= n; i += hn::Lanes(d)) {
    V cv, sv;
    sincos_two_pi(d, hn::LoadU(d, u + i), cv, sv);
    hn::StoreU(cv, d, c + i);
    hn::StoreU(sv, d, s + i);
  }
  return i;
}

// The number of lanes of this target (at most kMaxLanes).
std::size_t lanes() { return hn::Lanes(D()); }
std::int64_t target_bit() { return HWY_TARGET; }

}  // namespace microsim::walk_lanes::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

// ---- the block's loop (compiled once) ------------------------------------------------------------------------
#if HWY_ONCE
namespace microsim::walk_lanes {

HWY_EXPORT(step_vector);
HWY_EXPORT(lanes);
HWY_EXPORT(sincos_vectors);
HWY_EXPORT(target_bit);

namespace {

// Path j of the block in lane i: the incoming ray (travelling along -wi, from outside at g = 0, or from
// inside the dielectric for wi.z < 0: then in the inside frame, where it also travels down from above),
// weight 1, its stream from draw j 2^32 on.
void start(const LaneWalk& walk, Lanes& st, std::size_t i, std::uint64_t j) {
  const bool inside = walk.wi[2] < 0;
  const double s = inside ? 1.0 : -1.0;
  st.wx[i] = s * walk.wi[0];
  st.wy[i] = s * walk.wi[1];
  st.wz[i] = s * walk.wi[2];
  st.g[i] = 0;
  st.events[i] = 0;
  st.inside[i] = inside ? 1.0 : 0.0;
  for (int c = 0; c < walk.channels; ++c) st.weight[c][i] = 1;
  st.path[i] = j;
  st.counter[i] = j << 32;
}

// A lane with no path left: an upward ray above the surface, which escapes at once and is never recorded.
void park(Lanes& st, std::size_t i) {
  st.wx[i] = st.wy[i] = 0;
  st.wz[i] = 1;
  st.g[i] = st.events[i] = st.inside[i] = 0;
  st.counter[i] = 0;
}

// Lane i's path ended: its end and weights at its index (the direction in the global frame).
void record(const LaneWalk& walk, const Lanes& st, std::size_t i, LaneEnd* ends, double* weights) {
  const std::uint64_t j = st.path[i];
  const int kind = st.end[i] == kEscaped ? 0 : st.end[i] == kUnfinished ? 1 : 2;
  const double s = st.inside[i] > 0.5 ? -1.0 : 1.0;
  ends[j] = {kind, int(st.events[i]), s * st.wx[i], s * st.wy[i], s * st.wz[i]};
  double* w = weights + j * std::uint64_t(walk.channels);
  for (int c = 0; c < walk.channels; ++c) w[c] = walk.conductor ? st.weight[c][i] : 1.0;
}

}  // namespace

void walk_block(const LaneWalk& walk, std::uint64_t block, std::uint64_t paths, LaneEnd* ends, double* weights) {
  const std::size_t lanes = HWY_DYNAMIC_DISPATCH(walk_lanes::lanes)();
  if (lanes > kMaxLanes) throw std::logic_error("smith walk lanes: more SIMD lanes than the state holds");
  const auto step = HWY_DYNAMIC_DISPATCH(step_vector);
  // The block's key: the first draw of CounterRng(seed, block), a function of (seed, block) only.
  const std::uint64_t key = CounterRng(walk.seed, block).next_u64();
  Lanes st;
  std::uint64_t next = 0, live = 0;  // live: bit i for a lane holding a path
  for (std::size_t i = 0; i < lanes; ++i) {
    if (next < paths) {
      start(walk, st, i, next++);
      live |= std::uint64_t(1) << i;
    } else {
      park(st, i);
    }
  }
  while (live != 0) {
    // The lanes that ended, one after another (no test of the lanes that go on).
    for (std::uint64_t ended = step(walk, st, 0, key) & live; ended != 0; ended &= ended - 1) {
      const auto i = std::size_t(std::countr_zero(ended));
      record(walk, st, i, ends, weights);
      if (next < paths) {
        start(walk, st, i, next++);
      } else {
        park(st, i);
        live &= ~(std::uint64_t(1) << i);
      }
    }
  }
}

void bin_escaped(const FastDirectionBinner& bins, const LaneEnd* ends, int n, int* out) {
  constexpr int kChunk = 256;
  float x[kChunk], y[kChunk], z[kChunk];
  for (int first = 0; first < n; first += kChunk) {
    const int m = std::min(kChunk, n - first);
    for (int i = 0; i < m; ++i) {
      const LaneEnd& e = ends[first + i];
      x[i] = float(e.x);
      y[i] = float(e.y);
      z[i] = float(e.z);
    }
    if (bins.specialised_for_floats()) bins.classify_floats(x, y, z, m, out + first, /*vector=*/true);
    for (int i = 0; i < m; ++i) {
      const LaneEnd& e = ends[first + i];
      int& bin = out[first + i];
      if (e.kind != 0) bin = -1;
      else if (!bins.specialised_for_floats() || bin == FastDirectionBinner::kNeedsExact) bin = bins(Vec3<double>(e.x, e.y, e.z));
    }
  }
}

std::size_t sincos_two_pi(const double* u, std::size_t n, double* c, double* s) {
  return HWY_DYNAMIC_DISPATCH(sincos_vectors)(u, n, c, s);
}

std::string walk_lanes_target() { return hwy::TargetName(HWY_DYNAMIC_DISPATCH(target_bit)()); }

}  // namespace microsim::walk_lanes
#endif  // HWY_ONCE
