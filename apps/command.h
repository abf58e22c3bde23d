// microsim: subcommand registration for the thin command-line front ends.
//
// Each apps/cmd_NAME.cpp defines a static CommandRegistration that adds a CLI11 subcommand in its setup
// function and stores the action to run when that subcommand was selected. Exit codes follow the
// project's convention.
#pragma once

#include "core/output_paths.h"

#include <CLI/CLI.hpp>

#include <exception>

#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace microsim::app {

// The exit codes of every command (README, "Exit codes"). One place: no command returns a bare number.
// The exit codes, in one enum (README, "Exit codes"; core/errors.h says which error gives which).
enum ExitCode : int {
  kExitOk = 0,            // ok / the statistical test passed
  kExitRejected = 1,      // a statistical test rejected
  kExitUsage = 2,         // bad usage or bad input
  kExitInternal = 3,      // internal error: out of memory, an Embree failure, a bug
  kExitInterrupted = 130  // interrupted (Ctrl-C): what was done is kept, marked partial
};

struct Command {
  std::string name;
  std::function<void(CLI::App&)> setup;  // adds the subcommand and its options to the app
};

std::vector<Command>& command_registry();

// Returns the subcommand `name` of `parent`, adding it (with `description`) if no registration has yet.
// Lets several apps/cmd_*.cpp files add leaves under one group (`trace vndf`, `trace masking`).
inline CLI::App* get_or_add_subcommand(CLI::App& parent, const std::string& name, const std::string& description) {
  for (CLI::App* sub : parent.get_subcommands([](CLI::App*) { return true; }))
    if (sub->get_name() == name) return sub;
  CLI::App* sub = parent.add_subcommand(name, description);
  sub->require_subcommand(1);
  return sub;
}

// Called from a setup function: runs `action` if `sub` was the parsed subcommand.
void on_selected(CLI::App* sub, std::function<int()> action);

// Runs the action of the selected subcommand; returns its exit code.
int run_selected();

// The exit code of an error a command threw (UsageError and std::exception: 2; Cancelled: 130; bad_alloc and
// InternalError: 3), its message printed on stderr as "WHO: error: ..." (run_selected's, for a command that
// must act on the code itself: `run` under MPI).
int report_error(const std::exception_ptr& error, std::string_view who = "microsim");

struct CommandRegistration {
  CommandRegistration(std::string name, std::function<void(CLI::App&)> setup) {
    command_registry().push_back({std::move(name), std::move(setup)});
  }
};

// Thrown by front ends for bad input (exit 2); the message names the bad value.
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Called by every command before any work: refuses (UsageError, exit 2, nothing written) an output that is
// the same file as an input or as another output (src/core/output_paths.h). Empty paths are not given.
void check_distinct_outputs(const std::vector<microsim::PathOption>& inputs,
                            const std::vector<microsim::PathOption>& outputs);

// An output that can be created (its directory exists and is writable, it is not a directory), else
// UsageError naming the option; "" is no output.
void check_output(const std::string& option, const std::string& path);

// Ctrl-C in a command that has no partial result to keep: says so on stderr, "COMMAND: interrupted[ WHEN]:
// [LOST, ]nothing written" (e.g. "validate: interrupted while validating: no verdict, nothing written").
// Returns kExitInterrupted.
int interrupted_nothing_written(std::string_view command, std::string_view when = {}, std::string_view lost = {});

// The process's peak resident memory so far, in MiB.
double peak_rss_mib();

}  // namespace microsim::app
