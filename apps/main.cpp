// microsim: the command-line entry point. Each apps/cmd_*.cpp registers one subcommand
// (see apps/command.h); this file only builds the CLI11 app and runs it.
#include "command.h"

#include "core/parse.h"

#include <CLI/CLI.hpp>
#include <fmt/core.h>

#include <algorithm>
#include <cstdio>

namespace {

// CLI11 answers an unknown subcommand with "A subcommand is required", which names nothing. When the
// deepest command that was parsed has a subcommand and a word is left over, say which word and what the
// choices are.
void explain_unknown_subcommand(CLI::App& app) {
  CLI::App* deepest = &app;
  for (bool deeper = true; deeper;) {
    deeper = false;
    for (CLI::App* sub : deepest->get_subcommands())
      if (sub->parsed()) {
        deepest = sub;
        deeper = true;
        break;
      }
  }
  const auto left = deepest->remaining();
  const auto subs = deepest->get_subcommands([](CLI::App*) { return true; });
  if (left.empty() || subs.empty()) return;
  std::string names;
  for (const CLI::App* sub : subs) names += (names.empty() ? "" : ", ") + sub->get_name();
  fmt::print(stderr, "microsim: unknown command {} (commands here: {})\n", microsim::quote_excerpt(left.front()), names);
}

}  // namespace

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
    explain_unknown_subcommand(app);
    app.exit(e);
    return microsim::app::kExitUsage;
  }
  return microsim::app::run_selected();
}
