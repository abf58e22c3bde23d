// microsim: the command-line entry point. Each apps/cmd_*.cpp registers one subcommand
// (see apps/command.h); this file only builds the CLI11 app and runs it.
#include "command.h"

#include <CLI/CLI.hpp>
#include <fmt/core.h>

#include <algorithm>
#include <cstdio>

int main(int argc, char** argv) {
  CLI::App app{"microsim: a microsurface ray-tracing oracle for Smith-GGX samplers and BSDFs"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "microsim 0.1");
  auto& commands = microsim::app::command_registry();
  std::sort(commands.begin(), commands.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  for (auto& c : commands) c.setup(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return microsim::app::kExitUsage;
  }
  return microsim::app::run_selected();
}
