#include "progress_bar.h"

#include <fmt/core.h>

#include <csignal>
#include <cstdio>
#include <unistd.h>

namespace microsim {
namespace {
// The process's cancel token: the one global of the command line (a signal handler has no other way in).
CancelToken g_interrupt;
std::atomic<bool> g_seen_sigint{false};
// The first Ctrl-C cancels; a second one, for work that has no check (or is slow to reach it), kills the
// process as if no handler were installed.
extern "C" void on_sigint(int) {
  if (g_seen_sigint.exchange(true)) {
    std::signal(SIGINT, SIG_DFL);
    std::raise(SIGINT);
  }
  g_interrupt.cancel();
}
}  // namespace

void install_interrupt_handler() { std::signal(SIGINT, on_sigint); }
void install_termination_handler() { std::signal(SIGTERM, on_sigint); }
bool interrupted() { return g_interrupt.cancelled(); }
const CancelToken& interrupt_token() { return g_interrupt; }

void CliProgress::report(std::string_view stage, std::uint64_t done, std::uint64_t total) {
  if (!enabled_) return;
  ProgressBar* bar = nullptr;
  {
    std::lock_guard lock(mutex_);
    auto it = bars_.find(stage);
    if (it == bars_.end()) it = bars_.emplace(std::string(stage), std::make_unique<ProgressBar>(std::string(stage), total)).first;
    bar = it->second.get();
  }
  bar->update(done);
}

void CliProgress::finish() {
  std::lock_guard lock(mutex_);
  for (auto& [stage, bar] : bars_) bar->finish();
}

RunControl cli_run_control(int threads, const std::shared_ptr<CliProgress>& progress) {
  RunControl run;
  run.threads = threads;
  run.cancel = &g_interrupt;
  if (progress) run.progress = [progress](std::string_view stage, std::uint64_t done, std::uint64_t total) {
    progress->report(stage, done, total);
  };
  return run;
}

ProgressBar::ProgressBar(std::string label, std::uint64_t total, bool enabled)
    : label_(std::move(label)), total_(total), enabled_(enabled), tty_(isatty(fileno(stderr)) != 0),
      start_(std::chrono::steady_clock::now()), last_draw_(start_) {}

ProgressBar::~ProgressBar() { finish(); }

double ProgressBar::elapsed_seconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void ProgressBar::add(std::uint64_t n) {
  const std::uint64_t done = done_.fetch_add(n, std::memory_order_relaxed) + n;
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - start_ < std::chrono::seconds(1)) return;
  std::unique_lock lock(mutex_, std::try_to_lock);
  if (!lock.owns_lock() || now - last_draw_ < std::chrono::milliseconds(200)) return;
  last_draw_ = now;
  draw(done, false);
}

void ProgressBar::update(std::uint64_t done) {
  std::uint64_t seen = done_.load(std::memory_order_relaxed);
  while (done > seen && !done_.compare_exchange_weak(seen, done, std::memory_order_relaxed)) {
  }
  if (done > seen) add(0);
}

void ProgressBar::finish() {
  if (finished_.exchange(true)) return;
  if (!enabled_ || !drawn_.load()) return;
  std::lock_guard lock(mutex_);
  draw(done_.load(), true);
}

void ProgressBar::draw(std::uint64_t done, bool final) {
  const double frac = total_ ? std::min(1.0, double(done) / double(total_)) : 1.0;
  const double t = elapsed_seconds();
  const double rate = t > 0 ? double(done) / t : 0.0;
  const double eta = rate > 0 && total_ > done ? double(total_ - done) / rate : 0.0;
  if (tty_) {
    constexpr int width = 30;
    const int filled = int(frac * width);
    fmt::print(stderr, "\r{} [{}{}] {:5.1f}%  {:.3g}/s  ETA {:.0f}s   {}", label_, std::string(filled, '#'),
               std::string(width - filled, '.'), 100.0 * frac, rate, eta, final ? "\n" : "");
  } else {
    const int decile = int(frac * 10);
    if (decile == last_decile_ && !final) return;
    last_decile_ = decile;
    fmt::print(stderr, "{}: {:5.1f}% ({:.3g}/s, {:.1f}s)\n", label_, 100.0 * frac, rate, t);
  }
  std::fflush(stderr);
  drawn_.store(true);
}

}  // namespace microsim
