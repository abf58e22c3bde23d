// Bad-input table: usage mistakes that are not numbers, files or output paths. Each must exit 2
// with a message that names the word at fault, writing nothing.
#include "cli_helpers.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_bad_inputs_usage {

namespace {

using microsim::test::BadInputCase;
namespace fs = std::filesystem;

class BadUsage : public ::testing::TestWithParam<BadInputCase> {};

std::vector<BadInputCase> usage_cases() {
  const auto one_line = [](const fs::path& dir) { std::ofstream(dir / "one.txt") << "0 0 1\n"; };
  return {
      {"unknown_command", "nosuch", 2, "unknown command 'nosuch'"},
      {"unknown_subcommand", "trace nosuch", 2, "unknown command 'nosuch' (commands here: vndf, masking)"},
      {"unknown_surface_subcommand", "surface nosuch", 2, "unknown command 'nosuch'"},
      // An unknown or misspelt option: named with its command, and the nearest valid option of that command.
      {"misspelt_option", "validate --sampel heitz2018 --alpha 0.3 --theta 30", 2,
       "unknown option '--sampel' for `microsim validate`; did you mean '--sampler'?"},
      {"swapped_letters", "trace vndf --alpah 0.3 --theta 30 --out o.exr", 2,
       "unknown option '--alpah' for `microsim trace vndf`; did you mean '--alpha'?"},
      {"misspelt_option_with_value", "validate --sampler=heitz2018 --alpha 0.3 --theta 30 --sedd=3", 2,
       "unknown option '--sedd' for `microsim validate`; did you mean '--seed'?"},
      {"misspelt_required_option", "plot h.exr --outt f.svg", 2,
       "unknown option '--outt' for `microsim plot`; did you mean '--out'?"},
      {"unknown_option_far_from_any", "validate --sampler heitz2018 --alpha 0.3 --theta 30 --zzzzzzzz", 2,
       "unknown option '--zzzzzzzz' for `microsim validate` (its options: microsim validate --help)"},
      {"short_option_is_no_slip", "validate --sampler heitz2018 --alpha 0.3 --theta 30 -q", 2,
       "unknown option '-q' for `microsim validate` (its options"},
      {"very_long_unknown_option", "validate --sampler heitz2018 --alpha 0.3 --theta 30 --" + std::string(5000, 'x'), 2,
       "unknown option '--xxxxxxxx"},
      {"unexpected_argument", "validate heitz2018 --alpha 0.3 --theta 30", 2,
       "unexpected argument 'heitz2018' for `microsim validate`"},
      // An empty value would write or read nothing, silently: refused, the option named.
      {"empty_json_path", "validate --sampler heitz2018 --alpha 0.3 --theta 30 --samples 20000 --json ''", 2,
       "microsim: error: --json: an empty value"},
      {"empty_out_path", "scatter --model analytic --alpha 0.3 --theta 30 --out ''", 2, "--out: an empty value"},
      // A parse error carries the command's prefix, as every other error does.
      {"not_a_number_prefixed", "validate --sampler heitz2018 --alpha 0.3 --theta nan", 2,
       "microsim: error: --theta 'nan'"},
      // A traced histogram has its own binnings: --rows would be ignored.
      {"rows_with_a_traced_histogram", "validate --sampler heitz2018 --alpha 0.3 --theta 30 --against h.exr --rows 15", 2,
       "--rows 15: a traced histogram (h.exr) is compared in its own binnings"},
      // Too few samples in a file: the message names the file as well as the number needed.
      {"from_too_few_names_file", "validate --from one.txt --alpha 0.3 --theta 30", 2, "--from 'one.txt': 1 sample",
       one_line},
  };
}

TEST_P(BadUsage, ExitTwoNamingTheWordAndWritingNothing) { microsim::test::expect_bad_input(GetParam(), "bad_usage"); }

INSTANTIATE_TEST_SUITE_P(Usage, BadUsage, ::testing::ValuesIn(usage_cases()), [](const auto& info) { return info.param.name; });

}  // namespace

}  // namespace test_bad_inputs_usage
