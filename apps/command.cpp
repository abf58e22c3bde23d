#include "command.h"

#include "core/errors.h"
#include "core/run_control.h"

#include <fmt/core.h>

#include <cstdio>
#include <exception>
#include <new>

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

void on_selected(CLI::App* sub, std::function<int()> action) { actions().push_back({sub, std::move(action)}); }

int run_selected() {
  for (auto& s : actions()) {
    if (!s.sub->parsed()) continue;
    try {
      return s.action();
    } catch (const UsageError& e) {
      fmt::print(stderr, "microsim: error: {}\n", e.what());
      return kExitUsage;
    } catch (const microsim::Cancelled& e) {  // a step with no partial result to keep
      fmt::print(stderr, "microsim: interrupted ({}): nothing written\n", e.what());
      return kExitInterrupted;
    } catch (const std::bad_alloc&) {
      fmt::print(stderr, "microsim: internal error: out of memory\n");
      return kExitInternal;
    } catch (const microsim::InternalError& e) {
      fmt::print(stderr, "microsim: internal error: {}\n", e.what());
      return kExitInternal;
    } catch (const std::exception& e) {
      fmt::print(stderr, "microsim: error: {}\n", e.what());
      return kExitUsage;
    }
  }
  fmt::print(stderr, "microsim: no subcommand given (see --help)\n");
  return kExitUsage;
}

}  // namespace microsim::app
