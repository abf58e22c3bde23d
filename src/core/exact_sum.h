// core: an exactly associative sum of non-negative reals, for accumulators that must merge bit for bit
// in any grouping (a run split into shards and merged equals the single run).
//
// Each term is rounded once to a multiple of 2^-64 (fixed point in a 128-bit integer) and the integers
// are summed exactly, so the sum does not depend on the order or grouping of the additions. Terms must
// be finite and in [0, 2^40] (a weight or a squared weight); the total stays exact up to 2^63. A term
// below 2^-65 rounds to zero: the resolution is absolute, 5.4e-20, far below any weight that matters
// next to a count (a histogram of Fresnel-weighted paths, a masking estimate).
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>
#include <stdexcept>

namespace microsim {

class ExactSum {
public:
  static constexpr double kMaxTerm = 1099511627776.0;  // 2^40

  void add(double term) {
    if (!(term >= 0.0 && term <= kMaxTerm)) throw std::domain_error("ExactSum: a term outside [0, 2^40]");
    fixed_ += to_fixed(term);
  }
  // A term in [0, 2^40] as the nearest multiple of 2^-64 (ties to even), in units of 2^-64: the value of
  // nearbyint(ldexp(term, 64)) under the default rounding, from the double's bits (an order of magnitude
  // faster than that and its conversion to __int128; tests/core/test_block_runner.cpp compares the two).
  static __int128 to_fixed(double term) {
    const std::uint64_t bits = std::bit_cast<std::uint64_t>(term);
    const int biased_exponent = int(bits >> 52);
    if (biased_exponent == 0) return 0;  // zero or subnormal: far below 2^-65
    const std::uint64_t mantissa = (bits & ((std::uint64_t(1) << 52) - 1)) | (std::uint64_t(1) << 52);
    const int shift = biased_exponent - 1075 + kFractionBits;  // term = mantissa 2^(biased_exponent - 1075)
    if (shift >= 0) return static_cast<__int128>(mantissa) << shift;
    if (shift < -54) return 0;  // below 2^-65: under half a unit
    const int s = -shift;
    const std::uint64_t quotient = mantissa >> s, rest = mantissa & ((std::uint64_t(1) << s) - 1);
    const std::uint64_t half = std::uint64_t(1) << (s - 1);
    return static_cast<__int128>(quotient + std::uint64_t(rest > half || (rest == half && (quotient & 1))));
  }
  void add_count(std::uint64_t n) { fixed_ += static_cast<__int128>(n) << kFractionBits; }
  ExactSum& operator+=(const ExactSum& other) {
    fixed_ += other.fixed_;
    return *this;
  }
  // The sum, rounded once to the nearest double.
  double value() const { return std::ldexp(static_cast<double>(fixed_), -kFractionBits); }
  bool operator==(const ExactSum&) const = default;

  // The raw fixed-point value as two 64-bit halves (for files that must round-trip it exactly).
  std::uint64_t high_bits() const { return static_cast<std::uint64_t>(static_cast<unsigned __int128>(fixed_) >> 64); }
  std::uint64_t low_bits() const { return static_cast<std::uint64_t>(static_cast<unsigned __int128>(fixed_)); }
  static ExactSum from_bits(std::uint64_t high, std::uint64_t low) {
    ExactSum s;
    s.fixed_ = static_cast<__int128>((static_cast<unsigned __int128>(high) << 64) | low);
    return s;
  }

private:
  static constexpr int kFractionBits = 64;
  __int128 fixed_ = 0;
};

}  // namespace microsim
