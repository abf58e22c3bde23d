// microsim: the binning kernel (see direction_binner.h). Pass 1's vector code is compiled once per
// Highway target (hwy/foreach_target.h includes this file again for each) and the best one the CPU
// supports is called through HWY_DYNAMIC_DISPATCH; everything else is compiled once (HWY_ONCE).
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "stats/direction_binner.cpp"
#include <hwy/foreach_target.h>  // before highway.h
#include <hwy/highway.h>

#include "stats/direction_binner.h"

#include "core/math.h"

#include <fmt/core.h>
#include <hwy/targets.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <stdexcept>

// ---- pass 1's constants and its scalar reference (compiled once, used by every target) -----------------
#ifndef MICROSIM_DIRECTION_BINNER_SHARED
#define MICROSIM_DIRECTION_BINNER_SHARED
namespace microsim::binner_detail {

// Every bin index is below 2^23 (pass 1's vector code reads it from a float's mantissa).
static_assert(2LL * kMaxBinningRows * kMaxBinningRows < (1LL << 23));

// The constants of bin_floats' pass 1, in float.
struct FloatBinParams {
  float sx, sy, z_max, inv_dz, cols_per_radian, rows, row_guard, col_guard, half_pi, pi, two_pi;
  int cols, last_row, last_col;
};

// arctan on [0, 1] (Abramowitz & Stegun 1964, eq. 4.4.49: |error| <= 2e-8 rad; 1.4e-8 measured), in float:
// t p(t^2), p by Horner's rule from the highest coefficient down.
inline constexpr float kAtanCoefficients[] = {0.0028662257f, -0.0161657367f, 0.0429096138f, -0.0752896400f, 0.1065626393f,
                                               -0.1420889944f, 0.1999355085f, -0.3333314528f, 1.0f};
inline float atan_unit_float(float t) {
  const float t2 = t * t;
  float acc = kAtanCoefficients[0];
  for (std::size_t k = 1; k < std::size(kAtanCoefficients); ++k) acc = acc * t2 + kAtanCoefficients[k];
  return t * acc;
}

// Pass 1 in plain scalar code for directions [first, n): the reference of the vector code, which does the
// same operations lane by lane (with fused multiply-adds where the target has them).
inline void classify_scalar(const FloatBinParams& p, const float* x, const float* y, const float* z, int first, int n,
                            int* bins) {
  constexpr int kNeedsExact = FastDirectionBinner::kNeedsExact;
  for (int i = first; i < n; ++i) {
    // A point along the parameter-space direction (lobe: (x / ax, y / ay, z); sphere: sx = sy = 1).
    const float vx = x[i] * p.sx, vy = y[i] * p.sy, vz = z[i];
    const float len2 = vx * vx + vy * vy + vz * vz;
    // Fractional row and column indices, clamped (NaN to the upper end) so the conversions to int are
    // defined; a clamped value is never `inside`.
    const float r_raw = (p.z_max - vz / std::sqrt(len2)) * p.inv_dz;
    const float r_top = r_raw < p.rows + 1.0f ? r_raw : p.rows + 1.0f;
    const float r = r_top > -1.0f ? r_top : -1.0f;
    const float ax = std::fabs(vx), ay = std::fabs(vy);
    const float hi = ay > ax ? ay : ax, lo = ay > ax ? ax : ay;
    const float a = atan_unit_float(lo / hi);
    // phi in [0, 2 pi) by octant: first quadrant q, then pi - q (x < 0), and 2 pi - that (y < 0).
    const float q = ay > ax ? p.half_pi - a : a;
    const float phi_upper = vx < 0.0f ? p.pi - q : q;
    const float phi = vy < 0.0f ? p.two_pi - phi_upper : phi_upper;
    const float c_raw = phi * p.cols_per_radian, c_top = c_raw < float(p.cols + 1) ? c_raw : float(p.cols + 1);
    const float c = c_top > 0.0f ? c_top : 0.0f;
    const int row = int(r), col = int(c);  // truncation; r in (-1, 0) is caught by the guard below
    const float row_frac = r - float(row), col_frac = c - float(col);
    // Normal magnitudes only (NaN, zero, denormal or huge inputs fail these and go to bin_of).
    const bool regular = (len2 > 1e-30f) & (len2 < 1e30f) & (hi > 1e-15f);
    const bool inside = (row_frac > p.row_guard) & (row_frac < 1.0f - p.row_guard) & (col_frac > p.col_guard) &
                        (col_frac < 1.0f - p.col_guard) & (row <= p.last_row) & (col <= p.last_col);
    // Certainly beyond z_max or below z_min (lobe bins: the far side of the parameter space).
    const bool outside = (r < -p.row_guard) | (r > p.rows + p.row_guard);
    const int certain = inside ? row * p.cols + col : (outside ? -1 : kNeedsExact);
    bins[i] = regular ? certain : kNeedsExact;
  }
}

}  // namespace microsim::binner_detail
#endif  // MICROSIM_DIRECTION_BINNER_SHARED

// ---- pass 1 in vectors: compiled once per target --------------------------------------------------------
HWY_BEFORE_NAMESPACE();
namespace microsim::binner_detail::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// Pass 1 on whole vectors of directions: the scalar reference's operations, lane by lane, without a
// branch. Returns how many directions it did (a multiple of the vector width, at most n).
int classify_vectors(const FloatBinParams& p, const float* HWY_RESTRICT x, const float* HWY_RESTRICT y,
                     const float* HWY_RESTRICT z, int n, int* HWY_RESTRICT bins) {
  const hn::ScalableTag<float> df;
  const hn::RebindToSigned<decltype(df)> di;
  using V = hn::Vec<decltype(df)>;
  const V sx = hn::Set(df, p.sx), sy = hn::Set(df, p.sy), z_max = hn::Set(df, p.z_max), inv_dz = hn::Set(df, p.inv_dz);
  const V cols_per_radian = hn::Set(df, p.cols_per_radian), zero = hn::Zero(df);
  const V half_pi = hn::Set(df, p.half_pi), pi = hn::Set(df, p.pi), two_pi = hn::Set(df, p.two_pi);
  const V row_guard = hn::Set(df, p.row_guard), row_guard_hi = hn::Set(df, 1.0f - p.row_guard);
  const V col_guard = hn::Set(df, p.col_guard), col_guard_hi = hn::Set(df, 1.0f - p.col_guard);
  const V outside_lo = hn::Set(df, -p.row_guard), outside_hi = hn::Set(df, p.rows + p.row_guard);
  const V len_lo = hn::Set(df, 1e-30f), len_hi = hn::Set(df, 1e30f), hi_lo = hn::Set(df, 1e-15f);
  // Row and column as floats: `row <= last_row` is `row < last_row + 0.5`.
  const V last_row = hn::Set(df, float(p.last_row) + 0.5f), last_col = hn::Set(df, float(p.last_col) + 0.5f);
  const V cols = hn::Set(df, float(p.cols)), two_23 = hn::Set(df, 8388608.0f);
  const auto two_23_bits = hn::Set(di, 0x4B000000);  // the bits of 2^23 as a float
  const auto needs_exact = hn::Set(di, FastDirectionBinner::kNeedsExact), outside_bin = hn::Set(di, -1);
  const int lanes = int(hn::Lanes(df));
  int i = 0;
  for (; i + lanes <= n; i += lanes) {
    const V vx = hn::Mul(hn::LoadU(df, x + i), sx), vy = hn::Mul(hn::LoadU(df, y + i), sy), vz = hn::LoadU(df, z + i);
    const V len2 = hn::MulAdd(vz, vz, hn::MulAdd(vy, vy, hn::Mul(vx, vx)));
    const V r = hn::Mul(hn::Sub(z_max, hn::Div(vz, hn::Sqrt(len2))), inv_dz);
    // Not clamped like the scalar loop's (which needs it for int(), undefined beyond int's range and for
    // NaN; Trunc is defined for any value): a clamped value is `outside` or not `inside` exactly when the
    // unclamped one is, and a NaN lane is never `regular`.
    const V ax = hn::Abs(vx), ay = hn::Abs(vy);
    const auto swap = ay > ax;
    const V hi = hn::IfThenElse(swap, ay, ax), lo = hn::IfThenElse(swap, ax, ay);
    const V t = hn::Div(lo, hi), t2 = hn::Mul(t, t);
    V acc = hn::Set(df, kAtanCoefficients[0]);
    for (std::size_t k = 1; k < std::size(kAtanCoefficients); ++k) acc = hn::MulAdd(acc, t2, hn::Set(df, kAtanCoefficients[k]));
    const V a = hn::Mul(t, acc);
    const V q = hn::IfThenElse(swap, hn::Sub(half_pi, a), a);
    const V phi_upper = hn::IfThenElse(vx < zero, hn::Sub(pi, q), q);
    const V phi = hn::IfThenElse(vy < zero, hn::Sub(two_pi, phi_upper), phi_upper);
    const V c = hn::Mul(phi, cols_per_radian);  // phi >= 0 (every term above is), also unclamped
    // Truncation: the integer parts that int() gives the scalar loop's clamped values, where it matters
    // (-0 for r in (-1, 0), which is not `inside`).
    const V row = hn::Trunc(r), col = hn::Trunc(c);
    const V row_frac = hn::Sub(r, row), col_frac = hn::Sub(c, col);
    const auto regular = hn::And(hn::And(len2 > len_lo, len2 < len_hi), hi > hi_lo);
    const auto inside = hn::And(hn::And(hn::And(row_frac > row_guard, row_frac < row_guard_hi),
                                        hn::And(col_frac > col_guard, col_frac < col_guard_hi)),
                                hn::And(row < last_row, col < last_col));
    const auto outside = hn::Or(r < outside_lo, r > outside_hi);
    // row * cols + col is an integer in [0, 2^23) for the lanes `inside` (it is below 2^24: exact in
    // float): adding 2^23 puts it in the low mantissa bits, read as an integer (cheaper than ConvertTo,
    // whose overflow fix-up these lanes do not need; other lanes are not used).
    const auto bin = hn::Sub(hn::BitCast(di, hn::Add(hn::MulAdd(row, cols, col), two_23)), two_23_bits);
    const auto certain = hn::IfThenElse(hn::RebindMask(di, inside), bin,
                                        hn::IfThenElse(hn::RebindMask(di, outside), outside_bin, needs_exact));
    hn::StoreU(hn::IfThenElse(hn::RebindMask(di, regular), certain, needs_exact), di, bins + i);
  }
  return i;
}

// This target's Highway bit (which target the dispatch chose).
std::int64_t target_bit() { return HWY_TARGET; }

}  // namespace microsim::binner_detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

// ---- the binner (compiled once) ----------------------------------------------------------------------------
#if HWY_ONCE
namespace microsim {

namespace binner_detail {
HWY_EXPORT(classify_vectors);  // the table of every target's classify_vectors
// The best target's classify_vectors for this CPU (chosen on the first call).
int classify_vectors_best(const FloatBinParams& p, const float* x, const float* y, const float* z, int n, int* bins) {
  return HWY_DYNAMIC_DISPATCH(classify_vectors)(p, x, y, z, n, bins);
}
HWY_EXPORT(target_bit);
std::int64_t current_target_bit() { return HWY_DYNAMIC_DISPATCH(target_bit)(); }

std::atomic<std::int64_t> g_forced_target{0};  // use_direction_binner_target's choice (0: none)

// The Highway bits of direction_binner_targets(), best first (the lowest bit is the best on each platform).
std::vector<std::int64_t> supported_target_bits() {
  const std::int64_t forced = g_forced_target.load();
  if (forced == 0) return hwy::SupportedAndGeneratedTargets();
  hwy::SetSupportedTargetsForTest(0);  // while a target is forced: the CPU's own list, not the forced one
  const std::vector<std::int64_t> bits = hwy::SupportedAndGeneratedTargets();
  hwy::SetSupportedTargetsForTest(forced);
  return bits;
}
}  // namespace binner_detail

std::vector<std::string> direction_binner_targets() {
  std::vector<std::string> names;
  for (const std::int64_t bit : binner_detail::supported_target_bits()) names.emplace_back(hwy::TargetName(bit));
  return names;
}

std::string direction_binner_target() { return hwy::TargetName(binner_detail::current_target_bit()); }

void use_direction_binner_target(const std::string& name) {
  std::int64_t chosen = 0;
  if (!name.empty()) {
    for (const std::int64_t bit : binner_detail::supported_target_bits()) {
      if (name == hwy::TargetName(bit)) chosen = bit;
    }
    if (chosen == 0) throw std::invalid_argument(fmt::format("SIMD target '{}' is not compiled in or not supported by this CPU", name));
  }
  binner_detail::g_forced_target.store(chosen);
  hwy::SetSupportedTargetsForTest(chosen);  // 0: the CPU's best again
}

FastDirectionBinner::FastDirectionBinner(const DirectionBinning& b) : binning_(&b) {
  const nlohmann::json d = b.describe();
  lobe_ = b.kind() == BinningKind::lobe;
  rows_ = b.rows();
  cols_ = b.cols();
  z_min_ = b.z_min();
  z_max_ = b.z_max();
  inv_dz_ = rows_ / (z_max_ - z_min_);
  if (lobe_) {
    inv_ax_ = 1.0 / d.at("alpha").at(0).get<double>();
    inv_ay_ = 1.0 / d.at("alpha").at(1).get<double>();
    exact_only_ = d.at("domain").get<std::string>() != "microfacet_normal";
  }
  if (cols_ < 8) exact_only_ = true;  // sectors of pi/4 or wider: keep the simple path
  cols_per_radian_ = cols_ / (2 * kPi<double>);
  // bin_floats: guard bands 16x its error bounds (see the header); beyond a twentieth of a bin, use bin_of.
  row_guard_ = float(1e-5 * rows_);
  col_guard_ = float(1e-5 * cols_);
  float_exact_only_ = exact_only_ || row_guard_ > 0.05f || col_guard_ > 0.05f;
  edge_cos_.resize(std::size_t(cols_) + 1);
  edge_sin_.resize(std::size_t(cols_) + 1);
  for (int j = 0; j <= cols_; ++j) {
    const double phi = 2 * kPi<double> * double(j % cols_) / double(cols_);
    edge_cos_[std::size_t(j)] = std::cos(phi);
    edge_sin_[std::size_t(j)] = std::sin(phi);
  }
}

namespace {
// arctan on [0, 1] (Abramowitz & Stegun 1964, eq. 4.4.47: |error| <= 1e-5 rad): only a first guess of
// the sector, which the edge tests below correct and confirm.
inline double atan_unit(double t) {
  const double t2 = t * t;
  return t * (0.9998660 + t2 * (-0.3302995 + t2 * (0.1801410 + t2 * (-0.0851330 + t2 * 0.0208351))));
}

// phi = base + sign * atan(min / max) by octant, index = (|y| > |x|) + 2 (x < 0) + 4 (y < 0):
// first quadrant q = a or pi/2 - a, then pi - q, pi + q, 2 pi - q for the other quadrants.
struct OctantMap {
  double base[8], sign[8];
  constexpr OctantMap() : base{}, sign{} {
    const double half_pi = kPi<double> / 2;
    for (int i = 0; i < 8; ++i) {
      const bool swap = i & 1, x_negative = i & 2, y_negative = i & 4;
      const double qb = swap ? half_pi : 0.0, qs = swap ? -1.0 : 1.0;  // q = qb + qs a
      double pb = 0.0, ps = 1.0;                                        // phi = pb + ps q
      if (x_negative && !y_negative) pb = kPi<double>, ps = -1.0;
      if (x_negative && y_negative) pb = kPi<double>, ps = 1.0;
      if (!x_negative && y_negative) pb = 2 * kPi<double>, ps = -1.0;
      base[i] = pb + ps * qb;
      sign[i] = ps * qs;
    }
  }
};
constexpr OctantMap kOctants;
}  // namespace

int FastDirectionBinner::operator()(const Vec3<double>& direction) const {
  if (exact_only_ || !direction.allFinite()) return exact(direction);
  // A point along the parameter-space direction (not normalised: the column needs only its direction).
  const Vec3<double> v = lobe_ ? Vec3<double>(direction.x() * inv_ax_, direction.y() * inv_ay_, direction.z()) : direction;
  const double len2 = v.squaredNorm();
  if (!(len2 > 1e-280) || !(len2 < 1e280)) return exact(direction);  // zero, or near under/overflow
  const double z = v.z() / std::sqrt(len2);
  if (lobe_ && (z < z_min_ || z > z_max_)) {
    // Outside the lobe's parameter space (bin_of: nullopt) unless within round-off of its rim.
    if (z < z_min_ - 1e-12 || z > z_max_ + 1e-12) return -1;
    return exact(direction);
  }
  // Row, with a guard band where round-off could move u.z across a row edge. r >= -1e-15 here, so
  // truncation is floor except in the guard band.
  const double r = (z_max_ - z) * inv_dz_;
  const double r_floor = double(static_cast<long long>(r));
  const double frac = r - r_floor;
  // Column: arctangent by octant (branch-free), then the sector whose edges bracket (x, y).
  const double x = v.x(), y = v.y(), ax = std::abs(x), ay = std::abs(y);
  const bool swap = ay > ax;
  const double lo = swap ? ax : ay, hi = swap ? ay : ax;
  const int octant = int(swap) | (int(x < 0) << 1) | (int(y < 0) << 2);
  if ((frac < 1e-9) | (frac > 1 - 1e-9) | !(hi > 1e-150 * std::sqrt(len2))) return exact(direction);  // row edge or pole
  const int row = std::min(int(r_floor), rows_ - 1);
  const double phi = kOctants.base[octant] + kOctants.sign[octant] * atan_unit(lo / hi);
  int col = std::clamp(int(phi * cols_per_radian_), 0, cols_ - 1);
  // cross(e_j, p) >= 0: p is at or counter-clockwise of edge j (less than pi away).
  const auto side = [&](int j) { return edge_cos_[std::size_t(j)] * y - edge_sin_[std::size_t(j)] * x; };
  while (col > 0 && side(col) < 0) --col;
  while (col < cols_ - 1 && side(col + 1) >= 0) ++col;
  const double margin = 1e-12 * hi;
  if (!(side(col) >= margin && side(col + 1) <= -margin)) return exact(direction);  // near an edge, or wrapped
  return row * cols_ + col;
}

void FastDirectionBinner::classify(const float* x, const float* y, const float* z, int n, int* bins, bool vector) const {
  const binner_detail::FloatBinParams p{
      float(inv_ax_), float(inv_ay_), float(z_max_), float(inv_dz_), float(cols_per_radian_), float(rows_),
      row_guard_, col_guard_, float(kPi<double> / 2), float(kPi<double>), float(2 * kPi<double>),
      cols_, rows_ - 1, cols_ - 1};
  const int done = vector ? binner_detail::classify_vectors_best(p, x, y, z, n, bins) : 0;
  binner_detail::classify_scalar(p, x, y, z, done, n, bins);
}

int FastDirectionBinner::classify_floats(const float* x, const float* y, const float* z, int n, int* bins,
                                         bool vector) const {
  if (float_exact_only_) throw std::logic_error("FastDirectionBinner::classify_floats: no pass 1 for this binning");
  classify(x, y, z, n, bins, vector);
  return int(std::count(bins, bins + n, kNeedsExact));
}

void FastDirectionBinner::bin(const float* x, const float* y, const float* z, int n, int* bins, bool vector) const {
  if (float_exact_only_) {
    for (int i = 0; i < n; ++i) bins[i] = exact(Vec3<double>(x[i], y[i], z[i]));
    return;
  }
  classify(x, y, z, n, bins, vector);
  // Pass 2: the rare directions near an edge, degenerate or extreme.
  for (int i = 0; i < n; ++i) {
    if (bins[i] == kNeedsExact) bins[i] = exact(Vec3<double>(x[i], y[i], z[i]));
  }
}

void FastDirectionBinner::bin_floats(const float* x, const float* y, const float* z, int n, int* bins) const {
  bin(x, y, z, n, bins, /*vector=*/true);
}

void FastDirectionBinner::bin_floats_scalar(const float* x, const float* y, const float* z, int n, int* bins) const {
  bin(x, y, z, n, bins, /*vector=*/false);
}

}  // namespace microsim
#endif  // HWY_ONCE
