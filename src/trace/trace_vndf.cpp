#include "trace/trace_vndf.h"

#include "core/block_runner.h"
#include "core/random.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <time.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#endif

namespace microsim {

// ---- fast binning -----------------------------------------------------------------------------------------

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
  if (!((side(col) >= margin) & (side(col + 1) <= -margin))) return exact(direction);  // near an edge, or wrapped
  return row * cols_ + col;
}

namespace {
// The constants of bin_floats' pass 1.
struct FloatBinParams {
  float sx, sy, z_max, inv_dz, cols_per_radian, rows, row_guard, col_guard, half_pi, pi, two_pi;
  int cols, last_row, last_col;
};

// arctan on [0, 1] (Abramowitz & Stegun 1964, eq. 4.4.49: |error| <= 2e-8 rad; 1.4e-8 measured), in float.
inline float atan_unit_float(float t) {
  const float t2 = t * t;
  const float p = -0.0161657367f + t2 * 0.0028662257f;
  const float q = 0.1065626393f + t2 * (-0.0752896400f + t2 * (0.0429096138f + t2 * p));
  return t * (1.0f + t2 * (-0.3333314528f + t2 * (0.1999355085f + t2 * (-0.1420889944f + t2 * q))));
}
constexpr int kNeedsExact = std::numeric_limits<int>::min();

#if defined(__GNUC__) && defined(__x86_64__)
#define MICROSIM_HAVE_AVX2_BINNING 1
bool cpu_has_avx2_fma() {
  static const bool yes = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
  return yes;
}

#define MICROSIM_AVX2 __attribute__((target("avx2,fma"), always_inline)) inline
MICROSIM_AVX2 __m256 gt(__m256 a, __m256 b) { return _mm256_cmp_ps(a, b, _CMP_GT_OQ); }
MICROSIM_AVX2 __m256 lt(__m256 a, __m256 b) { return _mm256_cmp_ps(a, b, _CMP_LT_OQ); }
// select(mask, a, b): a where mask is set.
MICROSIM_AVX2 __m256 select(__m256 mask, __m256 a, __m256 b) { return _mm256_blendv_ps(b, a, mask); }
#undef MICROSIM_AVX2

// bin_floats' pass 1, eight directions at a time (AVX2 + FMA; chosen at run time): the same operations
// as the SSE2 and scalar loops of bin_floats, with fused multiply-adds (more accurate, so the same error
// bounds hold). Returns how many directions it did (a multiple of 8).
__attribute__((target("avx2,fma"))) int bin_floats_avx2(const FloatBinParams& p, const float* x, const float* y,
                                                         const float* z, int n, int* bins) {
  const __m256 v_sx = _mm256_set1_ps(p.sx), v_sy = _mm256_set1_ps(p.sy), v_z_max = _mm256_set1_ps(p.z_max);
  const __m256 v_inv_dz = _mm256_set1_ps(p.inv_dz), v_cpr = _mm256_set1_ps(p.cols_per_radian);
  const __m256 v_rows_hi = _mm256_set1_ps(p.rows + 1.0f), v_minus_one = _mm256_set1_ps(-1.0f);
  const __m256 v_cols_hi = _mm256_set1_ps(float(p.cols + 1)), v_zero = _mm256_setzero_ps();
  const __m256 v_half_pi = _mm256_set1_ps(p.half_pi), v_pi = _mm256_set1_ps(p.pi), v_two_pi = _mm256_set1_ps(p.two_pi);
  const __m256 v_abs = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256 v_rg = _mm256_set1_ps(p.row_guard), v_rg_hi = _mm256_set1_ps(1.0f - p.row_guard);
  const __m256 v_cg = _mm256_set1_ps(p.col_guard), v_cg_hi = _mm256_set1_ps(1.0f - p.col_guard);
  const __m256 v_out_lo = _mm256_set1_ps(-p.row_guard), v_out_hi = _mm256_set1_ps(p.rows + p.row_guard);
  const __m256 v_len_lo = _mm256_set1_ps(1e-30f), v_len_hi = _mm256_set1_ps(1e30f), v_hi_lo = _mm256_set1_ps(1e-15f);
  const __m256 v_last_row = _mm256_set1_ps(float(p.last_row) + 0.5f), v_last_col = _mm256_set1_ps(float(p.last_col) + 0.5f);
  const __m256 v_cols = _mm256_set1_ps(float(p.cols));
  const __m256 v_needs_exact = _mm256_castsi256_ps(_mm256_set1_epi32(kNeedsExact));
  const __m256 v_outside_bin = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
  int i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256 vx = _mm256_mul_ps(_mm256_loadu_ps(x + i), v_sx), vy = _mm256_mul_ps(_mm256_loadu_ps(y + i), v_sy);
    const __m256 vz = _mm256_loadu_ps(z + i);
    const __m256 len2 = _mm256_fmadd_ps(vz, vz, _mm256_fmadd_ps(vy, vy, _mm256_mul_ps(vx, vx)));
    const __m256 r_raw = _mm256_mul_ps(_mm256_sub_ps(v_z_max, _mm256_div_ps(vz, _mm256_sqrt_ps(len2))), v_inv_dz);
    const __m256 r = _mm256_max_ps(_mm256_min_ps(r_raw, v_rows_hi), v_minus_one);  // NaN -> upper end
    const __m256 ax = _mm256_and_ps(vx, v_abs), ay = _mm256_and_ps(vy, v_abs);
    const __m256 swap = gt(ay, ax);
    const __m256 hi = select(swap, ay, ax), lo = select(swap, ax, ay);
    const __m256 t = _mm256_div_ps(lo, hi), t2 = _mm256_mul_ps(t, t);
    __m256 acc = _mm256_set1_ps(0.0028662257f);
    for (const float c : {-0.0161657367f, 0.0429096138f, -0.0752896400f, 0.1065626393f, -0.1420889944f, 0.1999355085f,
                          -0.3333314528f, 1.0f}) {
      acc = _mm256_fmadd_ps(acc, t2, _mm256_set1_ps(c));
    }
    const __m256 a = _mm256_mul_ps(t, acc);
    const __m256 q = select(swap, _mm256_sub_ps(v_half_pi, a), a);
    const __m256 phi_upper = select(lt(vx, v_zero), _mm256_sub_ps(v_pi, q), q);
    const __m256 phi = select(lt(vy, v_zero), _mm256_sub_ps(v_two_pi, phi_upper), phi_upper);
    const __m256 c = _mm256_max_ps(_mm256_min_ps(_mm256_mul_ps(phi, v_cpr), v_cols_hi), v_zero);
    const __m256 row = _mm256_cvtepi32_ps(_mm256_cvttps_epi32(r)), col = _mm256_cvtepi32_ps(_mm256_cvttps_epi32(c));
    const __m256 row_frac = _mm256_sub_ps(r, row), col_frac = _mm256_sub_ps(c, col);
    const __m256 regular = _mm256_and_ps(_mm256_and_ps(gt(len2, v_len_lo), lt(len2, v_len_hi)), gt(hi, v_hi_lo));
    const __m256 inside =
        _mm256_and_ps(_mm256_and_ps(_mm256_and_ps(gt(row_frac, v_rg), lt(row_frac, v_rg_hi)),
                                    _mm256_and_ps(gt(col_frac, v_cg), lt(col_frac, v_cg_hi))),
                      _mm256_and_ps(lt(row, v_last_row), lt(col, v_last_col)));
    const __m256 outside = _mm256_or_ps(lt(r, v_out_lo), gt(r, v_out_hi));
    // row * cols + col is an integer below 2^24: exact in float. Integer results are selected as bits.
    const __m256 bin = _mm256_castsi256_ps(_mm256_cvttps_epi32(_mm256_fmadd_ps(row, v_cols, col)));
    const __m256 certain = select(inside, bin, select(outside, v_outside_bin, v_needs_exact));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(bins + i), _mm256_castps_si256(select(regular, certain, v_needs_exact)));
  }
  return i;
}
#endif
}  // namespace

void FastDirectionBinner::bin_floats(const float* __restrict x, const float* __restrict y, const float* __restrict z,
                                     int n, int* __restrict bins) const {
  if (float_exact_only_) {
    for (int i = 0; i < n; ++i) bins[i] = exact(Vec3<double>(x[i], y[i], z[i]));
    return;
  }
  const float sx = float(inv_ax_), sy = float(inv_ay_), z_max = float(z_max_), inv_dz = float(inv_dz_);
  const float cols_per_radian = float(cols_per_radian_), rows = float(rows_);
  const float row_guard = row_guard_, col_guard = col_guard_;
  const float half_pi = float(kPi<double> / 2), pi = float(kPi<double>), two_pi = float(2 * kPi<double>);
  const int cols = cols_, last_row = rows_ - 1, last_col = cols_ - 1;
  int i = 0;
#if defined(MICROSIM_HAVE_AVX2_BINNING)
  if (cpu_has_avx2_fma()) {
    const FloatBinParams params{sx, sy, z_max, inv_dz, cols_per_radian, rows, row_guard, col_guard,
                                half_pi, pi, two_pi, cols, last_row, last_col};
    i = bin_floats_avx2(params, x, y, z, n, bins);
  }
#endif
  // Pass 1, branch-free: the bin where it is certain, -1 where the direction is certainly outside the
  // parameter space, kNeedsExact elsewhere. Eight directions at a time with AVX2 where the CPU has it,
  // then four at a time with SSE2 (the same operations as the scalar loop below, which does the rest;
  // the compiler does not vectorise that loop by itself).
#if defined(__SSE2__)
  {
    const __m128 v_sx = _mm_set1_ps(sx), v_sy = _mm_set1_ps(sy), v_z_max = _mm_set1_ps(z_max);
    const __m128 v_inv_dz = _mm_set1_ps(inv_dz), v_cpr = _mm_set1_ps(cols_per_radian);
    const __m128 v_rows_hi = _mm_set1_ps(rows + 1.0f), v_minus_one = _mm_set1_ps(-1.0f);
    const __m128 v_cols_hi = _mm_set1_ps(float(cols + 1)), v_zero = _mm_setzero_ps();
    const __m128 v_half_pi = _mm_set1_ps(half_pi), v_pi = _mm_set1_ps(pi), v_two_pi = _mm_set1_ps(two_pi);
    const __m128 v_abs = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
    const __m128 v_rg = _mm_set1_ps(row_guard), v_rg_hi = _mm_set1_ps(1.0f - row_guard);
    const __m128 v_cg = _mm_set1_ps(col_guard), v_cg_hi = _mm_set1_ps(1.0f - col_guard);
    const __m128 v_out_lo = _mm_set1_ps(-row_guard), v_out_hi = _mm_set1_ps(rows + row_guard);
    const __m128 v_len_lo = _mm_set1_ps(1e-30f), v_len_hi = _mm_set1_ps(1e30f), v_hi_lo = _mm_set1_ps(1e-15f);
    const __m128 v_last_row = _mm_set1_ps(float(last_row) + 0.5f), v_last_col = _mm_set1_ps(float(last_col) + 0.5f);
    const __m128 v_cols = _mm_set1_ps(float(cols));
    const __m128i v_needs_exact = _mm_set1_epi32(kNeedsExact), v_outside_bin = _mm_set1_epi32(-1);
    const auto select = [](__m128 mask, __m128 a, __m128 b) { return _mm_or_ps(_mm_and_ps(mask, a), _mm_andnot_ps(mask, b)); };
    const auto select_i = [](__m128 mask, __m128i a, __m128i b) {
      const __m128i m = _mm_castps_si128(mask);
      return _mm_or_si128(_mm_and_si128(m, a), _mm_andnot_si128(m, b));
    };
    const auto poly = [](__m128 acc, __m128 t2, float c) { return _mm_add_ps(_mm_set1_ps(c), _mm_mul_ps(t2, acc)); };
    for (; i + 4 <= n; i += 4) {
      const __m128 vx = _mm_mul_ps(_mm_loadu_ps(x + i), v_sx), vy = _mm_mul_ps(_mm_loadu_ps(y + i), v_sy);
      const __m128 vz = _mm_loadu_ps(z + i);
      const __m128 len2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(vx, vx), _mm_mul_ps(vy, vy)), _mm_mul_ps(vz, vz));
      const __m128 r_raw = _mm_mul_ps(_mm_sub_ps(v_z_max, _mm_div_ps(vz, _mm_sqrt_ps(len2))), v_inv_dz);
      // _mm_min_ps(a, b) returns b when a is NaN: NaN goes to the upper end, as in the scalar loop.
      const __m128 r = _mm_max_ps(_mm_min_ps(r_raw, v_rows_hi), v_minus_one);
      const __m128 ax = _mm_and_ps(vx, v_abs), ay = _mm_and_ps(vy, v_abs);
      const __m128 swap = _mm_cmpgt_ps(ay, ax);
      const __m128 hi = select(swap, ay, ax), lo = select(swap, ax, ay);
      const __m128 t = _mm_div_ps(lo, hi), t2 = _mm_mul_ps(t, t);
      __m128 acc = _mm_set1_ps(0.0028662257f);
      acc = poly(acc, t2, -0.0161657367f);
      acc = poly(acc, t2, 0.0429096138f);
      acc = poly(acc, t2, -0.0752896400f);
      acc = poly(acc, t2, 0.1065626393f);
      acc = poly(acc, t2, -0.1420889944f);
      acc = poly(acc, t2, 0.1999355085f);
      acc = poly(acc, t2, -0.3333314528f);
      acc = poly(acc, t2, 1.0f);
      const __m128 a = _mm_mul_ps(t, acc);
      const __m128 q = select(swap, _mm_sub_ps(v_half_pi, a), a);
      const __m128 phi_upper = select(_mm_cmplt_ps(vx, v_zero), _mm_sub_ps(v_pi, q), q);
      const __m128 phi = select(_mm_cmplt_ps(vy, v_zero), _mm_sub_ps(v_two_pi, phi_upper), phi_upper);
      const __m128 c = _mm_max_ps(_mm_min_ps(_mm_mul_ps(phi, v_cpr), v_cols_hi), v_zero);
      const __m128 row = _mm_cvtepi32_ps(_mm_cvttps_epi32(r)), col = _mm_cvtepi32_ps(_mm_cvttps_epi32(c));
      const __m128 row_frac = _mm_sub_ps(r, row), col_frac = _mm_sub_ps(c, col);
      const __m128 regular = _mm_and_ps(_mm_and_ps(_mm_cmpgt_ps(len2, v_len_lo), _mm_cmplt_ps(len2, v_len_hi)),
                                        _mm_cmpgt_ps(hi, v_hi_lo));
      const __m128 inside = _mm_and_ps(
          _mm_and_ps(_mm_and_ps(_mm_cmpgt_ps(row_frac, v_rg), _mm_cmplt_ps(row_frac, v_rg_hi)),
                     _mm_and_ps(_mm_cmpgt_ps(col_frac, v_cg), _mm_cmplt_ps(col_frac, v_cg_hi))),
          _mm_and_ps(_mm_cmplt_ps(row, v_last_row), _mm_cmplt_ps(col, v_last_col)));
      const __m128 outside = _mm_or_ps(_mm_cmplt_ps(r, v_out_lo), _mm_cmpgt_ps(r, v_out_hi));
      // row * cols + col is an integer below 2^24: exact in float.
      const __m128i bin = _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(row, v_cols), col));
      const __m128i certain = select_i(inside, bin, select_i(outside, v_outside_bin, v_needs_exact));
      _mm_storeu_si128(reinterpret_cast<__m128i*>(bins + i), select_i(regular, certain, v_needs_exact));
    }
  }
#endif
  for (; i < n; ++i) {
    // A point along the parameter-space direction (lobe: (x / ax, y / ay, z); sphere: sx = sy = 1).
    const float vx = x[i] * sx, vy = y[i] * sy, vz = z[i];
    const float len2 = vx * vx + vy * vy + vz * vz;
    // Fractional row and column indices, clamped (NaN to the upper end) so the conversions to int are
    // defined; a clamped value is never `inside`.
    const float r_raw = (z_max - vz / std::sqrt(len2)) * inv_dz;
    const float r_top = r_raw < rows + 1.0f ? r_raw : rows + 1.0f;
    const float r = r_top > -1.0f ? r_top : -1.0f;
    const float ax = __builtin_fabsf(vx), ay = __builtin_fabsf(vy);
    const float hi = ay > ax ? ay : ax, lo = ay > ax ? ax : ay;
    const float a = atan_unit_float(lo / hi);
    // phi in [0, 2 pi) by octant: first quadrant q, then pi - q (x < 0), and 2 pi - that (y < 0).
    const float q = ay > ax ? half_pi - a : a;
    const float phi_upper = vx < 0.0f ? pi - q : q;
    const float phi = vy < 0.0f ? two_pi - phi_upper : phi_upper;
    const float c_raw = phi * cols_per_radian, c_top = c_raw < float(cols + 1) ? c_raw : float(cols + 1);
    const float c = c_top > 0.0f ? c_top : 0.0f;
    const int row = int(r), col = int(c);  // truncation; r in (-1, 0) is caught by the guard below
    const float row_frac = r - float(row), col_frac = c - float(col);
    // Normal magnitudes only (NaN, zero, denormal or huge inputs fail these and go to bin_of).
    const bool regular = (len2 > 1e-30f) & (len2 < 1e30f) & (hi > 1e-15f);
    const bool inside = (row_frac > row_guard) & (row_frac < 1.0f - row_guard) & (col_frac > col_guard) &
                        (col_frac < 1.0f - col_guard) & (row <= last_row) & (col <= last_col);
    // Certainly beyond z_max or below z_min (lobe bins: the far side of the parameter space).
    const bool outside = (r < -row_guard) | (r > rows + row_guard);
    const int certain = inside ? row * cols + col : (outside ? -1 : kNeedsExact);
    bins[i] = regular ? certain : kNeedsExact;
  }
  // Pass 2: the rare directions near an edge, degenerate or extreme.
  for (i = 0; i < n; ++i) {
    if (bins[i] == kNeedsExact) bins[i] = exact(Vec3<double>(x[i], y[i], z[i]));
  }
}

// ---- the target ------------------------------------------------------------------------------------------

EllipsoidTarget::EllipsoidTarget(double alpha_x, double alpha_y, int mesh_level, embree::BuildQuality quality)
    : ellipsoid_{alpha_x, alpha_y}, mesh_level_(mesh_level < 0 ? -1 : mesh_level) {
  if (!(alpha_x > 0.0) || !(alpha_y > 0.0) || !std::isfinite(alpha_x) || !std::isfinite(alpha_y)) {
    throw std::invalid_argument(fmt::format("ellipsoid roughness ({}, {}) must be positive and finite", alpha_x, alpha_y));
  }
  if (!is_mesh()) check_quadric_roughness(alpha_x, alpha_y);  // before any Embree work (QuadricEllipsoid checks too)
  device_ = std::make_unique<embree::Device>();
  scene_ = std::make_unique<embree::Scene>(*device_, quality, /*robust=*/true);
  if (is_mesh()) {
    mesh_ = std::make_unique<microgeom::EllipsoidTriMesh>(microgeom::build_ellipsoid_mesh(ellipsoid_, mesh_level_));
    auto buffers = microgeom::triangle_buffers(*mesh_);
    scene_->add_triangles(buffers.vertices, buffers.indices);
    face_normals_.assign(buffers.face_normals.begin(), buffers.face_normals.end());
  } else {
    quadric_ = std::make_unique<QuadricEllipsoid>(ellipsoid_);
    quadric_->attach(*scene_);
  }
  scene_->commit();
}

std::string EllipsoidTarget::describe() const {
  if (!is_mesh()) return "quadric";
  return fmt::format("mesh level {} ({} triangles)", mesh_level_, triangle_count());
}

// ---- the beam ----------------------------------------------------------------------------------------------

ParallelBeam::ParallelBeam(const microgeom::Ellipsoid& ellipsoid, const Vec3<double>& wi) : ellipsoid_(ellipsoid) {
  if (!(wi.z() > 0.0) || !wi.allFinite()) {
    throw std::invalid_argument(fmt::format("beam direction ({}, {}, {}) must point above the horizon", wi.x(), wi.y(), wi.z()));
  }
  wi_ = wi.normalized();
  orthonormal_basis(wi_, b1_, b2_);
  // Silhouette: the ellipsoid {x : x^T A x <= 1}, A = diag(ax^2, ay^2, 1), projected on span(b1, b2) is
  // the ellipse {y : y^T S^-1 y <= 1} with S = P A^-1 P^T, P = [b1 b2]^T (the image of the unit ball
  // under P A^-1/2). Uniform points: y = L w, L L^T = S, w uniform in the unit disk.
  const Vec3<double> inv_a(1.0 / sqr(ellipsoid.ax), 1.0 / sqr(ellipsoid.ay), 1.0);
  const double s11 = b1_.cwiseProduct(inv_a).dot(b1_);
  const double s12 = b1_.cwiseProduct(inv_a).dot(b2_);
  const double s22 = b2_.cwiseProduct(inv_a).dot(b2_);
  l11_ = std::sqrt(s11);
  l21_ = s12 / l11_;
  l22_ = safe_sqrt(s22 - l21_ * l21_);
  l11_ *= kBeamMargin;
  l21_ *= kBeamMargin;
  l22_ *= kBeamMargin;
  // Start beyond the support plane along wi (1% and a unit of slack): every origin is outside.
  start_ = 1.01 * ellipsoid.support(wi_) + 1.0;
}

double ParallelBeam::area() const { return kPi<double> * l11_ * l22_; }

double ParallelBeam::expected_hit_fraction() const {
  const GGX<double> ggx(ellipsoid_.ax, ellipsoid_.ay);
  return ellipsoid_.footprint_area() * ggx.projected_area(wi_) / area();
}

namespace {

// n uniform points of the unit disk by rejection from the square (no trigonometry; 4/pi pairs on
// average), without a data-dependent branch: every candidate is written, and the write position advances
// only when it is accepted. xs and ys hold n + 1 values. The sequence is that of a loop drawing pairs
// (x first) until one falls inside, repeated n times.
inline void disk_points(CounterRng& rng, int n, double* xs, double* ys) {
  int k = 0;
  while (k < n) {
    const double x = 2.0 * rng.uniform() - 1.0;
    const double y = 2.0 * rng.uniform() - 1.0;
    xs[k] = x;
    ys[k] = y;
    k += int(x * x + y * y < 1.0);
  }
}

// Rays are generated, traced and binned in batches of this many (a block is 16 batches): each stage
// runs as a tight loop over the batch, so the binning is vectorised and independent of Embree's code.
constexpr int kBatch = 256;
static_assert(kRaysPerBlock % kBatch == 0);

struct BatchBuffers {
  double disk_x[kBatch + 1], disk_y[kBatch + 1];
  float org_x[kBatch], org_y[kBatch], org_z[kBatch];
  float nx[kBatch], ny[kBatch], nz[kBatch];  // counted normals
  int bins[kBatch];
};

// Origins of a batch: disk points mapped to the beam, rounded to float.
inline void beam_origins(const ParallelBeam& beam, BatchBuffers& b, int n) {
  for (int i = 0; i < n; ++i) {
    const Vec3<double> o = beam.origin(b.disk_x[i], b.disk_y[i]);
    b.org_x[i] = float(o.x());
    b.org_y[i] = float(o.y());
    b.org_z[i] = float(o.z());
  }
}

double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

constexpr std::size_t kMaxBinnings = 8;
constexpr int kUnknownBin = std::numeric_limits<int>::min();
constexpr int kNotCounted = -2;

// One block's tally: per binning its bins, then one for unbinned hits.
struct BlockTally {
  std::vector<std::vector<std::uint64_t>> counts;
  std::uint64_t rays = 0, hits = 0;
  void count(std::size_t binning, int bin) {
    std::vector<std::uint64_t>& c = counts[binning];
    ++c[bin >= 0 ? std::size_t(bin) : c.size() - 1];
  }
};


// Mesh targets: per-triangle cache of its bins (kUnknownBin until first hit, kNotCounted for faces whose
// hits do not count), `stride` ints per triangle. A triangle has one normal, so its bins are computed on
// its first hit; racing threads store the same values. Slot 0 is published last (release) and read first
// (acquire): a thread that sees it set sees the whole entry. (Storing slot 0 first let another thread
// read a lobe bin still unknown, about one run in eight at mesh level 4: a hit counted as unbinned.)
class FaceBinCache {
public:
  FaceBinCache(const EllipsoidTarget& target, const Vec3<double>& wi, std::span<const FastDirectionBinner> binners)
      : target_(target), wi_(wi), binners_(binners), stride_(std::max<std::size_t>(binners.size(), 1)),
        slots_(new std::atomic<int>[target.triangle_count() * stride_]) {
    const std::size_t n = target.triangle_count() * stride_;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, std::size_t(1) << 16), [&](const auto& r) {
      for (std::size_t i = r.begin(); i != r.end(); ++i) slots_[i].store(kUnknownBin, std::memory_order_relaxed);
    });
  }
  void prefetch(unsigned int face) const { __builtin_prefetch(&slots_[std::size_t(face) * stride_]); }
  void count(BlockTally& tally, unsigned int face) const {
    std::atomic<int>* slot = &slots_[std::size_t(face) * stride_];
    int first_value = slot[0].load(std::memory_order_acquire);
    if (first_value == kUnknownBin) first_value = fill(slot, face);
    if (first_value == kNotCounted) return;
    ++tally.hits;
    for (std::size_t k = 0; k < binners_.size(); ++k) tally.count(k, slot[k].load(std::memory_order_relaxed));
  }

private:
  int fill(std::atomic<int>* slot, unsigned int face) const {
    Vec3<double> n;
    const embree::Hit hit{0.0f, face, 0, Vec3<float>::Zero(), 0.0f, 0.0f};
    const bool counted = target_.counted_normal(hit, wi_, n);
    auto value = [&](std::size_t k) { return !counted ? kNotCounted : (k < binners_.size() ? binners_[k](n) : 0); };
    for (std::size_t k = stride_; k-- > 1;) slot[k].store(value(k), std::memory_order_relaxed);
    const int first_value = value(0);
    slot[0].store(first_value, std::memory_order_release);
    return first_value;
  }
  const EllipsoidTarget& target_;
  Vec3<double> wi_;
  std::span<const FastDirectionBinner> binners_;
  std::size_t stride_;
  std::unique_ptr<std::atomic<int>[]> slots_;
};

// Traces one block of the beam: disk points from CounterRng(seed, block), in batches of kBatch.
class BeamBlockTracer {
public:
  BeamBlockTracer(const EllipsoidTarget& target, const ParallelBeam& beam, const Vec3<double>& wi,
                  std::span<const DirectionBinning> binnings, std::span<const FastDirectionBinner> binners,
                  const FaceBinCache* faces)
      : target_(target), beam_(beam), wi_(wi), dir_(beam.direction().cast<float>()), binnings_(binnings),
        binners_(binners), faces_(faces) {}

  BlockTally trace(const BlockPlan& plan, std::uint64_t seed, std::uint64_t block, BatchBuffers& b) const {
    embree::FlushDenormalsScope ftz;  // Embree wants FTZ/DAZ in every tracing thread
    BlockTally tally;
    tally.counts.resize(binnings_.size());
    for (std::size_t k = 0; k < binnings_.size(); ++k) tally.counts[k].assign(std::size_t(binnings_[k].size()) + 1, 0);
    const std::uint64_t count = plan.units_in(block);
    CounterRng rng(seed, block);
    for (std::uint64_t batch_first = 0; batch_first < count; batch_first += kBatch) {
      const int n = int(std::min<std::uint64_t>(kBatch, count - batch_first));
      disk_points(rng, n, b.disk_x, b.disk_y);
      beam_origins(beam_, b, n);
      if (faces_) trace_mesh_batch(b, n, tally);
      else trace_quadric_batch(b, n, tally);
    }
    tally.rays = count;
    return tally;
  }

private:
  RTCRayHit intersect(const BatchBuffers& b, int i, RTCIntersectContext& context) const {
    constexpr float kInf = std::numeric_limits<float>::infinity();
    RTCRayHit rh = embree::make_ray_hit(b.org_x[i], b.org_y[i], b.org_z[i], dir_.x(), dir_.y(), dir_.z(), 0.0f, kInf);
    rtcIntersect1(target_.scene().handle(), &context, &rh);
    return rh;
  }
  // Mesh: software pipelining: fetch a hit triangle's cache line, bin the previous hit while it arrives
  // (the order of integer increments does not matter).
  void trace_mesh_batch(BatchBuffers& b, int n, BlockTally& tally) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    unsigned int pending = RTC_INVALID_GEOMETRY_ID;
    for (int i = 0; i < n; ++i) {
      const RTCRayHit rh = intersect(b, i, context);
      if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
      faces_->prefetch(rh.hit.primID);
      if (pending != RTC_INVALID_GEOMETRY_ID) faces_->count(tally, pending);
      pending = rh.hit.primID;
    }
    if (pending != RTC_INVALID_GEOMETRY_ID) faces_->count(tally, pending);
  }
  // Quadric: a lean loop of rtcIntersect1 calls, as the raw benchmark's; normals (zero for a miss, which
  // does not count) go to b.nx/ny/nz, then the counted ones (EllipsoidTarget::counted_normal's rule, in
  // double) are compacted in place without a data-dependent branch and binned.
  void trace_quadric_batch(BatchBuffers& b, int n, BlockTally& tally) const {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    for (int i = 0; i < n; ++i) {
      const RTCRayHit rh = intersect(b, i, context);
      const bool hit = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
      b.nx[i] = hit ? rh.hit.Ng_x : 0.0f;
      b.ny[i] = hit ? rh.hit.Ng_y : 0.0f;
      b.nz[i] = hit ? rh.hit.Ng_z : 0.0f;
    }
    int counted = 0;
    for (int i = 0; i < n; ++i) {
      const float x = b.nx[i], y = b.ny[i], z = b.nz[i];
      b.nx[counted] = x;
      b.ny[counted] = y;
      b.nz[counted] = z;
      counted += int(EllipsoidTarget::counts(Vec3<double>(x, y, z), wi_));
    }
    tally.hits += std::uint64_t(counted);
    for (std::size_t k = 0; k < binners_.size(); ++k) {
      binners_[k].bin_floats(b.nx, b.ny, b.nz, counted, b.bins);
      for (int i = 0; i < counted; ++i) tally.count(k, b.bins[i]);
    }
  }

  const EllipsoidTarget& target_;
  const ParallelBeam& beam_;
  Vec3<double> wi_;
  Vec3<float> dir_;
  std::span<const DirectionBinning> binnings_;
  std::span<const FastDirectionBinner> binners_;
  const FaceBinCache* faces_;
};

void add_tally(TraceResult& result, const BlockTally& tally) {
  result.rays += tally.rays;
  result.hits += tally.hits;
  for (std::size_t k = 0; k < result.counts.size(); ++k) {
    for (std::size_t b = 0; b < result.counts[k].size(); ++b) result.counts[k][b] += tally.counts[k][b];
    result.unbinned[k] += tally.counts[k].back();
  }
}

}  // namespace

TraceResult empty_trace_result(std::span<const DirectionBinning> binnings, std::uint64_t total_blocks) {
  TraceResult result;
  result.counts.resize(binnings.size());
  for (std::size_t k = 0; k < binnings.size(); ++k) result.counts[k].assign(std::size_t(binnings[k].size()), 0);
  result.unbinned.assign(binnings.size(), 0);
  result.total_blocks = total_blocks;
  return result;
}

TraceResult trace_vndf(const EllipsoidTarget& target, const Vec3<double>& wi_in,
                       std::span<const DirectionBinning> binnings, const TraceOptions& options) {
  if (options.rays == 0) throw std::invalid_argument("trace_vndf: the number of rays must be positive");
  if (binnings.size() > kMaxBinnings) throw std::invalid_argument(fmt::format("trace_vndf: at most {} binnings", kMaxBinnings));
  const ParallelBeam beam(target.ellipsoid(), wi_in);
  const Vec3<double> wi = wi_in.normalized();
  std::vector<FastDirectionBinner> binners;
  for (const DirectionBinning& b : binnings) binners.emplace_back(b);
  std::optional<FaceBinCache> faces;
  if (target.is_mesh()) faces.emplace(target, wi, binners);
  const BeamBlockTracer tracer(target, beam, wi, binnings, binners, faces ? &*faces : nullptr);

  const BlockPlan plan{options.rays, kRaysPerBlock};
  TraceResult result = empty_trace_result(binnings, plan.blocks());
  tbb::enumerable_thread_specific<std::unique_ptr<BatchBuffers>> buffers([] { return std::make_unique<BatchBuffers>(); });
  const auto start = std::chrono::steady_clock::now();
  const double cpu_start = process_cpu_seconds();
  const BlockRunStatus status = for_each_block(
      selected_blocks(plan, options.blocks), options.run, {"trace vndf", plan},
      [&](std::uint64_t block) { return tracer.trace(plan, options.seed, block, *buffers.local()); },
      [&](BlockTally&& tally, std::uint64_t) { add_tally(result, tally); });
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.cpu_seconds = process_cpu_seconds() - cpu_start;
  target.scene().device().check("rtcIntersect1");
  result.blocks = status.done;
  result.partial = status.cancelled;
  return result;
}

std::vector<BeamRay> generate_beam_rays(const ParallelBeam& beam, std::uint64_t count, std::uint64_t seed) {
  std::vector<BeamRay> rays(count);
  const Vec3<float> dir = beam.direction().cast<float>();
  const BlockPlan plan{count, kRaysPerBlock};
  // The same disk points, origins and order as trace_vndf's batches; each block writes its own rays.
  for_each_block(
      BlockRange{0, plan.blocks()}, RunControl{}, {"beam rays", plan},
      [&](std::uint64_t block) {
        CounterRng rng(seed, block);
        auto b = std::make_unique<BatchBuffers>();
        const std::uint64_t first = plan.first_unit(block), n = plan.units_in(block);
        for (std::uint64_t batch_first = 0; batch_first < n; batch_first += kBatch) {
          const int m = int(std::min<std::uint64_t>(kBatch, n - batch_first));
          disk_points(rng, m, b->disk_x, b->disk_y);
          beam_origins(beam, *b, m);
          for (int i = 0; i < m; ++i)
            rays[first + batch_first + std::size_t(i)] = {Vec3<float>(b->org_x[i], b->org_y[i], b->org_z[i]), dir};
        }
        return n;
      },
      [](std::uint64_t, std::uint64_t) {});
  return rays;
}

}  // namespace microsim
