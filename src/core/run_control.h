// core: how a caller drives a long library call. The library never reads globals, never writes to a
// terminal and never exits: it takes a RunControl (threads, a cancel token, a progress callback) and
// returns what it measured, marked partial when cancelled. The command line sets the token on Ctrl-C
// and draws the progress bar; a Python caller or a cluster job does what suits it.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string_view>

namespace microsim {

// Set once (from any thread, or a signal handler: a lock-free atomic store), polled by the workers.
class CancelToken {
public:
  void cancel() noexcept { cancelled_.store(true, std::memory_order_relaxed); }
  void reset() noexcept { cancelled_.store(false, std::memory_order_relaxed); }
  bool cancelled() const noexcept { return cancelled_.load(std::memory_order_relaxed); }

private:
  std::atomic<bool> cancelled_{false};
  static_assert(std::atomic<bool>::is_always_lock_free);
};

// Progress of one stage of a call ("trace vndf", "build surface"): `done` of `total` units. Called from
// worker threads, possibly concurrently, with `done` not necessarily increasing between threads.
using ProgressCallback = std::function<void(std::string_view stage, std::uint64_t done, std::uint64_t total)>;

struct RunControl {
  int threads = 0;                      // worker threads; 0: all cores
  const CancelToken* cancel = nullptr;  // nullptr: the call is never cancelled
  ProgressCallback progress;            // empty: no progress reports

  bool cancelled() const { return cancel != nullptr && cancel->cancelled(); }
  void report(std::string_view stage, std::uint64_t done, std::uint64_t total) const {
    if (progress) progress(stage, done, total);
  }
};

// Thrown by a step that has no partial result to return when its RunControl is cancelled.
struct Cancelled : std::runtime_error {
  using std::runtime_error::runtime_error;
};

}  // namespace microsim
