// microsim: counter-based random numbers, so that results depend on (seed, stream, index) only and not
// on thread count or scheduling. Every parallel loop in microsim derives the variates of work item i
// from CounterRng(seed, stream = i): reproducible whatever the number of threads.
//
// The generator hashes a 64-bit counter with the SplitMix64 finalizer (Steele, Lea, Flood 2014,
// "Fast Splittable Pseudorandom Number Generators", OOPSLA), keyed by seed and stream through a second
// round of mixing. Statistical quality: each output is a bijective avalanche of a distinct 64-bit input.
#pragma once

#include <cstdint>

namespace microsim {

// SplitMix64's output mixing function: a bijection on 64-bit integers with full avalanche.
constexpr std::uint64_t mix64(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

class CounterRng {
public:
  constexpr CounterRng(std::uint64_t seed, std::uint64_t stream)
      : key_(mix64(mix64(seed + 0x9e3779b97f4a7c15ULL) ^ (stream * 0xd1b54a32d192ed03ULL + 0x632be59bd9b4e019ULL))) {}

  constexpr std::uint64_t next_u64() { return mix64(key_ + 0x9e3779b97f4a7c15ULL * (++counter_)); }

  // Uniform double in [0, 1) with 53 random bits.
  constexpr double uniform() { return double(next_u64() >> 11) * 0x1.0p-53; }
  // Uniform float in [0, 1) with 24 random bits.
  constexpr float uniform_float() { return float(next_u64() >> 40) * 0x1.0p-24f; }

  // Skips ahead: the i-th draw of this stream, independent of how many were drawn before.
  constexpr void seek(std::uint64_t index) { counter_ = index; }

private:
  std::uint64_t key_;
  std::uint64_t counter_ = 0;
};

}  // namespace microsim
