// core: the one deterministic block loop behind every Monte Carlo measurement.
//
// Work is cut into blocks of a fixed number of units (rays, samples); block b draws its variates from
// CounterRng(seed, b) and nothing else, and the per-block results are reduced one at a time in block
// order. A result therefore depends only on (seed, block range), never on the thread count or the
// scheduling; a range [0, n) split into shards and merged in order is the unsharded run, bit for bit.
//
// Cancellation keeps what is exact: blocks not yet started are skipped, and only the completed prefix of
// the range is reduced, so a cancelled run is the run of a shorter range (a shard), reported as such.
#pragma once

#include "core/run_control.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>
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
// how many blocks may be computed before their results are reduced (0: a default from the thread count),
// and whether blocks run in chunks of in_flight with a barrier between chunks (for a caller whose
// compute writes per-slot buffers, slot = block % in_flight, consumed when a chunk's last block is
// reduced). None of these changes a result, only memory, speed and progress.
struct BlockSchedule {
  std::string_view stage;
  BlockPlan plan;
  std::uint64_t in_flight = 0;
  bool chunk_barrier = false;
};

namespace detail {
// Blocks computed concurrently before their results are reduced: bounds memory, not the result.
std::uint64_t blocks_in_flight(int threads);
}  // namespace detail

// For each block of `range`: result = compute(block) on worker threads (run_control.threads of them),
// then reduce(std::move(result), block), one block at a time and in increasing block order (on whichever
// thread holds the pipeline's last stage). At most `schedule.in_flight` blocks are computed ahead of the
// reduction (a tbb::parallel_pipeline with a serial in-order last stage: no barrier between chunks, and
// the per-block results in flight stay few, so they stay in cache). With schedule.chunk_barrier: chunks
// of in_flight blocks, each chunk finished before its results are reduced.
template <class Compute, class Reduce>
BlockRunStatus for_each_block(BlockRange range, const RunControl& run, const BlockSchedule& schedule,
                              Compute&& compute, Reduce&& reduce);

namespace detail {

template <class Compute, class Reduce>
BlockRunStatus pipelined_blocks(BlockRange range, const RunControl& run, const BlockSchedule& schedule,
                                std::uint64_t tokens, Compute& compute, Reduce& reduce) {
  using Result = decltype(compute(std::uint64_t{}));
  struct Computed {
    std::uint64_t block = 0;
    std::optional<Result> result;  // empty: skipped after a cancel
  };
  std::atomic<std::uint64_t> units_done{0};
  const std::uint64_t total_units = schedule.plan.units_in(range);
  BlockRunStatus status{{range.begin, range.begin}, false};
  std::uint64_t next = range.begin;
  const auto issue = [&](tbb::flow_control& flow) -> std::uint64_t {
    if (next >= range.end || run.cancelled()) {
      flow.stop();
      return 0;
    }
    return next++;
  };
  const auto compute_block = [&](std::uint64_t block) {
    Computed c{block, std::nullopt};
    if (run.cancelled()) return c;
    c.result.emplace(compute(block));
    const std::uint64_t n = schedule.plan.units_in(block);
    run.report(schedule.stage, units_done.fetch_add(n, std::memory_order_relaxed) + n, total_units);
    return c;
  };
  const auto reduce_block = [&](Computed c) {
    if (!c.result || status.cancelled) {  // a gap: what follows is discarded, the prefix is kept
      status.cancelled = true;
      return;
    }
    reduce(std::move(*c.result), c.block);
    status.done.end = c.block + 1;
  };
  tbb::task_arena arena(run.threads > 0 ? run.threads : tbb::task_arena::automatic);
  if (!range.empty()) {
    arena.execute([&] {
      tbb::parallel_pipeline(std::size_t(tokens),
                             tbb::make_filter<void, std::uint64_t>(tbb::filter_mode::serial_in_order, issue) &
                                 tbb::make_filter<std::uint64_t, Computed>(tbb::filter_mode::parallel, compute_block) &
                                 tbb::make_filter<Computed, void>(tbb::filter_mode::serial_in_order, reduce_block));
    });
  }
  status.cancelled = status.done.end < range.end;  // only a cancel stops the pipeline early
  return status;
}

// Chunks of `chunk` blocks computed in parallel, each finished before its results are reduced in order.
template <class Compute, class Reduce>
BlockRunStatus chunked_blocks(BlockRange range, const RunControl& run, const BlockSchedule& schedule,
                              std::uint64_t chunk, Compute& compute, Reduce& reduce) {
  using Result = decltype(compute(std::uint64_t{}));
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
    for (std::uint64_t block = first; block < last && !status.cancelled; ++block) {
      std::optional<Result>& r = results[std::size_t(block - first)];
      status.cancelled = !r;
      if (r) reduce(std::move(*r), block);
      if (r) status.done.end = block + 1;
    }
    for (auto& r : results) r.reset();  // results after a gap are discarded
  }
  return status;
}

}  // namespace detail

template <class Compute, class Reduce>
BlockRunStatus for_each_block(BlockRange range, const RunControl& run, const BlockSchedule& schedule,
                              Compute&& compute, Reduce&& reduce) {
  const std::uint64_t in_flight = schedule.in_flight > 0 ? schedule.in_flight : detail::blocks_in_flight(run.threads);
  if (schedule.chunk_barrier) return detail::chunked_blocks(range, run, schedule, in_flight, compute, reduce);
  return detail::pipelined_blocks(range, run, schedule, in_flight, compute, reduce);
}

}  // namespace microsim
