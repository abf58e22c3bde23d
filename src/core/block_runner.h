// core: the one deterministic block loop behind every Monte Carlo measurement.
//
// Work is cut into blocks of a fixed number of units (rays, samples); block b draws its variates from
// CounterRng(seed, b) and nothing else, and the per-block results are reduced on the calling thread in
// block order. A result therefore depends only on (seed, block range), never on the thread count or the
// scheduling; a range [0, n) split into shards and merged in order is the unsharded run, bit for bit.
//
// Cancellation keeps what is exact: blocks not yet started are skipped, and only the completed prefix of
// the range is reduced, so a cancelled run is the run of a shorter range (a shard), reported as such.
#pragma once

#include "core/run_control.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace microsim {

// A half-open range of block indices [begin, end).
struct BlockRange {
  std::uint64_t begin = 0, end = 0;
  std::uint64_t size() const { return end > begin ? end - begin : 0; }
  bool empty() const { return size() == 0; }
  bool operator==(const BlockRange&) const = default;
  std::string to_string() const;  // "[begin, end)"
};

// `units` units (rays, samples) in blocks of `block_size`: block b holds units [b size, min(units, (b+1) size)).
struct BlockPlan {
  std::uint64_t units = 0, block_size = 1;
  std::uint64_t blocks() const { return units / block_size + (units % block_size != 0); }
  std::uint64_t first_unit(std::uint64_t block) const { return block * block_size; }
  std::uint64_t units_in(std::uint64_t block) const {
    return std::min(block_size, units - std::min(units, first_unit(block)));
  }
  // Units in the blocks of `range`.
  std::uint64_t units_in(const BlockRange& range) const {
    return std::min(units, range.end * block_size) - std::min(units, range.begin * block_size);
  }
};

// The blocks a call runs: `selection` (a shard), or all of the plan's. Throws std::invalid_argument when
// the selection is not inside [0, plan.blocks()).
BlockRange selected_blocks(const BlockPlan& plan, const std::optional<BlockRange>& selection);

// Shard k of n (1-based) of the blocks [0, blocks): contiguous ranges in order, sizes differing by at most
// one, together exactly [0, blocks). Throws std::invalid_argument unless 1 <= k <= n.
BlockRange shard_range(std::uint64_t blocks, std::uint64_t k, std::uint64_t n);

// What for_each_block did: the blocks whose results were reduced (a prefix of the requested range) and
// whether it stopped early because the RunControl was cancelled.
struct BlockRunStatus {
  BlockRange done;
  bool cancelled = false;
};

// How for_each_block reports and schedules: the stage name and the plan (units per block, for progress),
// and how many blocks may be computed before their results are reduced (0: a default from the thread
// count). Neither changes a result, only memory and progress.
struct BlockSchedule {
  std::string_view stage;
  BlockPlan plan;
  std::uint64_t in_flight = 0;
};

namespace detail {
// Blocks computed concurrently before their results are reduced: bounds memory, not the result.
std::uint64_t blocks_in_flight(int threads);
}  // namespace detail

// For each block of `range`: result = compute(block) on worker threads (run_control.threads of them),
// then reduce(std::move(result), block) on the calling thread, in increasing block order.
template <class Compute, class Reduce>
BlockRunStatus for_each_block(BlockRange range, const RunControl& run, const BlockSchedule& schedule,
                              Compute&& compute, Reduce&& reduce) {
  using Result = decltype(compute(std::uint64_t{}));
  const std::uint64_t chunk = schedule.in_flight > 0 ? schedule.in_flight : detail::blocks_in_flight(run.threads);
  std::vector<std::optional<Result>> results(std::size_t(std::min(chunk, std::max<std::uint64_t>(range.size(), 1))));
  std::atomic<std::uint64_t> units_done{0};
  const std::uint64_t total_units = schedule.plan.units_in(range);
  tbb::task_arena arena(run.threads > 0 ? run.threads : tbb::task_arena::automatic);
  BlockRunStatus status{{range.begin, range.begin}, false};
  for (std::uint64_t first = range.begin; first < range.end && !status.cancelled; first += chunk) {
    const std::uint64_t last = std::min(range.end, first + chunk);
    arena.execute([&] {
      tbb::parallel_for(first, last, [&](std::uint64_t block) {
        if (run.cancelled()) return;
        results[std::size_t(block - first)].emplace(compute(block));
        const std::uint64_t n = schedule.plan.units_in(block);
        run.report(schedule.stage, units_done.fetch_add(n, std::memory_order_relaxed) + n, total_units);
      });
    });
    for (std::uint64_t block = first; block < last; ++block) {
      std::optional<Result>& r = results[std::size_t(block - first)];
      if (!r) {
        status.cancelled = true;
        break;
      }
      reduce(std::move(*r), block);
      r.reset();
      status.done.end = block + 1;
    }
    for (auto& r : results) r.reset();  // results after a gap are discarded
  }
  return status;
}

}  // namespace microsim
