// microsim: a progress bar on stderr for long work, and cooperative cancellation on Ctrl-C.
//
// ProgressBar is thread-safe (workers call add() from TBB tasks). It stays silent for the first second,
// then redraws at most five times a second: a bar with the fraction, rate and ETA on a terminal, or one
// line per 10% when stderr is not a terminal (CI logs). Nothing is printed on stdout.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <string>

namespace microsim {

class ProgressBar {
public:
  ProgressBar(std::string label, std::uint64_t total, bool enabled = true);
  ~ProgressBar();  // finishes the line if anything was drawn
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  void add(std::uint64_t n);
  void finish();
  double elapsed_seconds() const;

private:
  void draw(std::uint64_t done, bool final);
  std::string label_;
  std::uint64_t total_;
  bool enabled_;
  bool tty_;
  std::atomic<std::uint64_t> done_{0};
  std::atomic<bool> drawn_{false};
  std::atomic<bool> finished_{false};
  std::mutex mutex_;
  std::chrono::steady_clock::time_point start_, last_draw_;
  int last_decile_ = -1;
};

// Ctrl-C (SIGINT) handling: install once at the start of a long command; workers poll
// interrupted() and stop early; the command then writes what it measured, marked as partial (exit 130).
// A second Ctrl-C kills the process (the default action).
void install_interrupt_handler();
bool interrupted();
// For tests: set or clear the flag as if Ctrl-C had been pressed.
void set_interrupted(bool value);

}  // namespace microsim
