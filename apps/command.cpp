#include "command.h"

#include "core/errors.h"
#include "core/run_control.h"
#include "stats/histogram_io.h"

#include <fmt/core.h>

#include <cstdio>
#include <exception>
#include <new>

#include <sys/resource.h>

namespace microsim::app {
namespace {
struct Selected {
  CLI::App* sub = nullptr;
  std::function<int()> action;
};
std::vector<Selected>& actions() {
  static std::vector<Selected> a;
  return a;
}
}  // namespace

std::vector<Command>& command_registry() {
  static std::vector<Command> commands;
  return commands;
}

void check_distinct_outputs(const std::vector<microsim::PathOption>& inputs,
                            const std::vector<microsim::PathOption>& outputs) {
  try {
    microsim::check_output_paths(inputs, outputs);
  } catch (const microsim::OutputPathError& e) {
    throw UsageError(e.what());
  }
}

void check_output(const std::string& option, const std::string& path) {
  if (path.empty()) return;
  try {
    microsim::check_writable(path);
  } catch (const microsim::OutputPathError& e) {
    throw UsageError(fmt::format("{}: {}", option, e.what()));
  }
}

int interrupted_nothing_written(std::string_view command, std::string_view when, std::string_view lost) {
  fmt::print(stderr, "{}: interrupted{}{}: {}{}nothing written\n", command, when.empty() ? "" : " ", when, lost,
             lost.empty() ? "" : ", ");
  return kExitInterrupted;
}

double peak_rss_mib() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return double(usage.ru_maxrss) / 1024.0;  // Linux: kilobytes
}

void on_selected(CLI::App* sub, std::function<int()> action) { actions().push_back({sub, std::move(action)}); }

int report_error(const std::exception_ptr& error, std::string_view who) {
  try {
    std::rethrow_exception(error);
  } catch (const UsageError& e) {
    fmt::print(stderr, "{}: error: {}\n", who, e.what());
    return kExitUsage;
  } catch (const microsim::Cancelled& e) {  // a step with no partial result to keep
    return interrupted_nothing_written(who, fmt::format("({})", e.what()));
  } catch (const std::bad_alloc&) {
    fmt::print(stderr, "{}: internal error: out of memory\n", who);
    return kExitInternal;
  } catch (const microsim::InternalError& e) {
    fmt::print(stderr, "{}: internal error: {}\n", who, e.what());
    return kExitInternal;
  } catch (const std::exception& e) {
    fmt::print(stderr, "{}: error: {}\n", who, e.what());
    return kExitUsage;
  }
}

int run_selected() {
  for (auto& s : actions()) {
    if (!s.sub->parsed()) continue;
    try {
      return s.action();
    } catch (...) {
      return report_error(std::current_exception());
    }
  }
  fmt::print(stderr, "microsim: no subcommand given (see --help)\n");
  return kExitUsage;
}

}  // namespace microsim::app
