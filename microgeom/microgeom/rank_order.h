// microgeom: the rank order of n 32-bit values in bounded memory. The slope matchings (assembly.cpp,
// ndf_match.cpp) and the statistics (surface_stats.cpp) need, for every element, its rank in the order of
// (value, index): the order of the keys (value << 32 | index). Sorting all n keys needs two 64-bit arrays
// of n (16 bytes per element); here the keys are collected and sorted one block of value range at a time
// in a buffer the caller gives (a histogram of the top 16 value bits chooses the blocks so that each
// fits), and handed to the caller block by block, in rank order. The order of (value, index) is total, so
// the result is the same permutation as any sort of all keys, whatever the buffer and the thread count.
#pragma once

#include "microgeom/assembly.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

namespace microgeom::detail {

// Fixed chunks of [0, n) for the parallel passes (a fixed count: the collected order is the index order).
inline constexpr int kRankChunks = 32;
inline constexpr int kRankBuckets = 1 << 16;  // the top 16 value bits

// Per (chunk, bucket) counts of the values; also the last non-empty bucket + 1.
template <class Value>
std::vector<std::uint32_t> rank_histogram(std::size_t n, const Value& value_of, int& bucket_end) {
  std::vector<std::uint32_t> hist(std::size_t(kRankChunks) * kRankBuckets, 0);
  tbb::parallel_for(0, kRankChunks, [&](int c) {
    std::uint32_t* h = hist.data() + std::size_t(c) * kRankBuckets;
    for (std::size_t k = n * std::size_t(c) / kRankChunks; k < n * std::size_t(c + 1) / kRankChunks; ++k)
      ++h[std::uint32_t(value_of(k)) >> 16];
  });
  bucket_end = 0;
  for (int c = 0; c < kRankChunks; ++c)
    for (int b = kRankBuckets - 1; b >= bucket_end; --b)
      if (hist[std::size_t(c) * kRankBuckets + std::size_t(b)] != 0) {
        bucket_end = b + 1;
        break;
      }
  return hist;
}

// Calls visit(first_rank, sorted_keys, count) for consecutive blocks of the keys (value_of(k) << 32 | k),
// k in [0, n), in ascending order; every key once. `buffer` holds `capacity` keys (half for the keys of a
// block, half for the sort's scratch); a block that cannot fit (one top-16-bit bucket holding more than
// capacity / 2 values) gets a buffer of its own. value_of(k) is evaluated once for the histogram and once
// per block pass, and must return the same value each time for every k not yet handed to `visit`; after
// a key was visited, value_of(k) may return anything whose top 16 bits exceed those of every value (e.g.
// a result with the top bit set, when no value has it), as collected values are tested against the
// block's bucket range.
template <class Value, class Visit>
void visit_in_rank_order(std::size_t n, const Value& value_of, std::uint64_t* buffer, std::size_t capacity,
                         const Visit& visit) {
  if (n == 0) return;
  int bucket_end = 0;
  const std::vector<std::uint32_t> hist = rank_histogram(n, value_of, bucket_end);
  std::vector<std::size_t> bucket_total(std::size_t(bucket_end), 0);
  for (int c = 0; c < kRankChunks; ++c)
    for (int b = 0; b < bucket_end; ++b) bucket_total[std::size_t(b)] += hist[std::size_t(c) * kRankBuckets + std::size_t(b)];
  const std::size_t half = std::max<std::size_t>(1, capacity / 2);
  std::vector<std::uint64_t> own;
  std::size_t first_rank = 0;
  for (int lo = 0; lo < bucket_end;) {
    int hi = lo;
    std::size_t count = 0;
    while (hi < bucket_end && (hi == lo || count + bucket_total[std::size_t(hi)] <= half)) count += bucket_total[std::size_t(hi++)];
    std::uint64_t* keys = buffer;
    std::uint64_t* scratch = buffer + half;
    if (count > half) {
      own.assign(2 * count, 0);
      keys = own.data();
      scratch = own.data() + count;
    }
    std::array<std::size_t, kRankChunks> offset{};
    std::size_t running = 0;
    for (int c = 0; c < kRankChunks; ++c) {
      offset[std::size_t(c)] = running;
      for (int b = lo; b < hi; ++b) running += hist[std::size_t(c) * kRankBuckets + std::size_t(b)];
    }
    const auto ulo = std::uint32_t(lo), uhi = std::uint32_t(hi);
    tbb::parallel_for(0, kRankChunks, [&](int c) {
      std::size_t next = offset[std::size_t(c)];
      for (std::size_t k = n * std::size_t(c) / kRankChunks; k < n * std::size_t(c + 1) / kRankChunks; ++k) {
        const std::uint32_t v = std::uint32_t(value_of(k)), bucket = v >> 16;
        if (bucket >= ulo && bucket < uhi) keys[next++] = (std::uint64_t(v) << 32) | std::uint32_t(k);
      }
    });
    radix_sort_by_high32(keys, scratch, count);
    visit(first_rank, static_cast<const std::uint64_t*>(keys), count);
    if (!own.empty()) std::vector<std::uint64_t>().swap(own);
    first_rank += count;
    lo = hi;
  }
}

}  // namespace microgeom::detail
