// microsim: the command-line entry point. Each apps/cmd_*.cpp registers one subcommand
// (see apps/command.h); this file only builds the CLI11 app and runs it.
#include "command.h"

#include "core/parse.h"

#include <CLI/CLI.hpp>
#include <fmt/core.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <string_view>
#include <vector>

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

// Optimal string alignment distance between a and b: the fewest insertions, deletions, substitutions and
// swaps of two neighbours ("--alpah" is one edit from "--alpha") from one to the other.
std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] != b[j - 1] ? 1 : 0)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

// The command as typed: "microsim trace vndf".
std::string command_line_of(const CLI::App* app) {
  std::string words;
  for (; app->get_parent(); app = app->get_parent()) words = " " + app->get_name() + words;
  return "microsim" + words;
}

// The option of `app` spelled nearest to `word` (--long or -s), if near enough to be a slip of the keyboard:
// a third of the name's length (without its dashes) in edits, 1 to 3, and none for a name of 1 or 2
// characters (-q is no slip of -h), nor for a word far longer than any option. Empty when none is.
std::string nearest_option(const CLI::App* app, std::string_view word) {
  if (word.size() > 64) return {};  // the distance's table is word.size() by the option's length
  const std::size_t name = word.size() - std::min(word.find_first_not_of('-'), word.size());
  std::size_t best_distance = (name < 3 ? 0 : std::clamp<std::size_t>(name / 3, 1, 3)) + 1;
  std::string best;
  for (const CLI::Option* option : app->get_options()) {
    std::vector<std::string> spellings;
    for (const std::string& n : option->get_lnames()) spellings.push_back("--" + n);
    for (const std::string& n : option->get_snames()) spellings.push_back("-" + n);
    for (const std::string& spelling : spellings)
      if (const std::size_t d = edit_distance(word, spelling); d < best_distance) {
        best = spelling;
        best_distance = d;
      }
  }
  return best;
}

// The first parsed command, from the top, with words left over (as CLI11 checks them); nullptr if none has.
CLI::App* command_with_leftovers(CLI::App& app) {
  CLI::App* command = &app;
  while (command->remaining(false).empty()) {
    CLI::App* next = nullptr;
    for (CLI::App* sub : command->get_subcommands())
      if (sub->parsed()) next = sub;
    if (!next) return nullptr;
    command = next;
  }
  return command;
}

// CLI11 answers an unknown option with "The following arguments were not expected: heitz2018 --sampel": say
// which option, of which command, and the valid option nearest it; or which argument was not expected.
// `options_only`: only an unknown option of a command without subcommands (after another parse error: a
// misspelt required option is then reported missing). False when nothing was printed.
bool explain_unexpected_arguments(CLI::App& app, bool options_only) {
  const CLI::App* command = command_with_leftovers(app);
  if (!command) return false;
  const std::vector<std::string> left = command->remaining(false);
  const auto option = std::find_if(left.begin(), left.end(), [](const std::string& w) { return w.starts_with("-"); });
  const bool group = !command->get_subcommands([](const CLI::App*) { return true; }).empty();
  if (options_only && (option == left.end() || group)) return false;
  const std::string where = "`" + command_line_of(command) + "`";
  if (option == left.end()) {
    fmt::print(stderr, "microsim: unexpected argument {} for {} (see {} --help)\n", microsim::quote_excerpt(left.front()),
               where, command_line_of(command));
    return true;
  }
  const std::string word = option->substr(0, option->find('='));  // --name=value
  const std::string nearest = nearest_option(command, word);
  if (nearest.empty())
    fmt::print(stderr, "microsim: unknown option {} for {} (its options: {} --help)\n", microsim::quote_excerpt(word),
               where, command_line_of(command));
  else
    fmt::print(stderr, "microsim: unknown option {} for {}; did you mean '{}'?\n", microsim::quote_excerpt(word), where,
               nearest);
  return true;
}

// An option given an empty value ("--json ''"): nothing would be written or read, and nothing would say so. Every
// option with a value wants a path, a name or a number. False (and the option named) when one is empty.
bool no_empty_values(const CLI::App& app) {
  for (const CLI::Option* option : app.get_options())
    if (option->get_type_size_max() > 0 && option->count() > 0)
      for (const std::string& value : option->results())
        if (value.empty()) {
          fmt::print(stderr, "microsim: error: {}: an empty value (give a path, a name or a number)\n",
                     option->get_name());
          return false;
        }
  for (const CLI::App* sub : app.get_subcommands())
    if (sub->parsed() && !no_empty_values(*sub)) return false;
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"microsim: a microsurface ray-tracing oracle for Smith-GGX samplers and BSDFs"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "microsim 0.1");
  auto& commands = microsim::app::command_registry();
  std::sort(commands.begin(), commands.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  for (auto& c : commands) c.setup(app);
  app.failure_message([](const CLI::App*, const CLI::Error& e) {
    return fmt::format("microsim: error: {}\nRun with --help for more information.\n", e.what());
  });
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ExtrasError& e) {
    if (!explain_unexpected_arguments(app, false)) app.exit(e);
    return microsim::app::kExitUsage;
  } catch (const CLI::ParseError& e) {
    // An unknown option is named first: it is often the required one misspelt ("--outt": "--out is required").
    if (!explain_unexpected_arguments(app, true)) explain_unknown_subcommand(app);
    app.exit(e);
    return microsim::app::kExitUsage;
  }
  if (!no_empty_values(app)) return microsim::app::kExitUsage;
  return microsim::app::run_selected();
}
