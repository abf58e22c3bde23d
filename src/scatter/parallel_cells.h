// scatter: the cells of a table computed in parallel on the run's threads, with progress and cancellation.
#pragma once

#include "core/run_control.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <cstddef>
#include <cstdint>

namespace microsim {

// Evaluates f(k) for k in [0, count) in parallel (run.threads, or TBB's default), reporting `stage` as
// done of total after each cell; false when cancelled (cells not reached are left as they were).
template <class F>
bool parallel_cells(std::size_t count, const RunControl& run, const char* stage, std::atomic<std::uint64_t>& done,
                    std::uint64_t total, const F& f) {
  std::atomic<bool> cancelled{false};
  tbb::task_arena arena(run.threads > 0 ? run.threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(std::size_t(0), count, [&](std::size_t k) {
      if (cancelled || run.cancelled()) {
        cancelled = true;
        return;
      }
      f(k);
      run.report(stage, done.fetch_add(1) + 1, total);
    });
  });
  return !(cancelled || run.cancelled());
}

}  // namespace microsim
