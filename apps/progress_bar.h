// microsim CLI: a progress bar on stderr for long work, and Ctrl-C as the library's cancel token.
//
// ProgressBar is thread-safe (workers call add() from TBB tasks). It stays silent for the first second,
// then redraws at most five times a second: a bar with the fraction, rate and ETA on a terminal, or one
// line per 10% when stderr is not a terminal (CI logs). Nothing is printed on stdout.
#pragma once

#include "core/run_control.h"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
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
  void update(std::uint64_t done);  // the total done so far (never moves the bar back)
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

// Ctrl-C (SIGINT) handling: install once at the start of a long command. The first Ctrl-C cancels the
// process's CancelToken (passed to the library in every RunControl the CLI makes); the library stops at
// its next block and returns what it measured, which the command writes marked as partial (exit 130).
// A second Ctrl-C kills the process (the default action).
void install_interrupt_handler();
// SIGTERM handled as Ctrl-C (the first cancels, a second kills): what mpirun sends every rank on Ctrl-C, and
// what Slurm's scancel sends. Installed by `microsim run` under an MPI launcher.
void install_termination_handler();
bool interrupted();
const CancelToken& interrupt_token();

// The progress callback of a RunControl: one bar per stage, drawn on stderr (thread-safe).
class CliProgress {
public:
  explicit CliProgress(bool enabled) : enabled_(enabled) {}
  void report(std::string_view stage, std::uint64_t done, std::uint64_t total);
  void finish();  // ends every bar's line; call before printing results

private:
  bool enabled_;
  std::mutex mutex_;
  std::map<std::string, std::unique_ptr<ProgressBar>, std::less<>> bars_;
};

// A RunControl for the library: `threads` (0: all cores), the Ctrl-C token, and `progress` (may be null).
RunControl cli_run_control(int threads, const std::shared_ptr<CliProgress>& progress);

}  // namespace microsim
