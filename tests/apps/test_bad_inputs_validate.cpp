// Bad-input table of `microsim validate`: too few samples for any test is not a pass (defect
// 7). Each case must exit 2, say on stderr how many samples were given and that more are needed, and
// write nothing (no --json, no --plot).
#include "cli_helpers.h"
#include "validate/sample_io.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_bad_inputs_validate {

using microsim::test::BadInputCase;
using microsim::test::expect_bad_input;
namespace fs = std::filesystem;

namespace {

void write_lines(const fs::path& path, int n) {
  std::ofstream out(path);
  for (int i = 0; i < n; ++i) out << "0 0 1\n";
}

const std::string kOut = " --json out.json --plot out.svg";

std::vector<BadInputCase> too_few_samples_cases() {
  return {
      {"Samples1", "validate --sampler heitz2018 --alpha 0.3 --theta 60 --samples 1" + kOut, 2,
       "1 sample(s) are too few: a chi-square test needs at least 10 samples"},
      {"Samples2", "validate --sampler heitz2018 --alpha 0.3 --theta 60 --samples 2" + kOut, 2,
       "2 sample(s) are too few: a chi-square test needs at least 10 samples"},
      {"Samples9Float", "validate --sampler dupuy2023 --alpha 0.3 --theta 30 --samples 9 --float" + kOut, 2,
       "9 sample(s) are too few"},
      // Above the bound of any binning, below this one's: the lobe bins (31 rows) need thousands.
      {"Samples100", "validate --sampler heitz2018 --alpha 0.3 --theta 60 --samples 100" + kOut, 2,
       "100 sample(s) are too few: the chi-square tests need at least"},
      {"Samples1Reflected", "validate --sampler bounded2023 --alpha 0.3 --theta 60 --samples 1" + kOut, 2,
       "1 sample(s) are too few"},
      {"AllSamples1", "validate --all --samples 1 --json out.json", 2,
       "1 sample(s) are too few: a chi-square test needs at least 10 samples"},
      {"AllSamples5", "validate --all --samples 5 --json out.json", 2, "5 sample(s) are too few"},
      {"FromOneLine", "validate --from one.txt --alpha 0.3 --theta 60" + kOut, 2, "1 sample(s) are too few",
       [](const fs::path& d) { write_lines(d / "one.txt", 1); }},
      {"FromOneLineReflected", "validate --from one.txt --reflected --alpha 0.3 --theta 60" + kOut, 2,
       "1 sample(s) are too few", [](const fs::path& d) { write_lines(d / "one.txt", 1); }},
      {"FromFiftyLines", "validate --from fifty.txt --alpha 0.3 --theta 60" + kOut, 2,
       "50 sample(s) are too few: the chi-square tests need at least",
       [](const fs::path& d) { write_lines(d / "fifty.txt", 50); }},
      {"FromFiveRowNpy", "validate --from five.npy --alpha 0.3 --theta 60" + kOut, 2, "5 sample(s) are too few",
       [](const fs::path& d) {
         const std::vector<microsim::Vec3<double>> rows(5, microsim::Vec3<double>(0, 0, 1));
         microsim::write_npy(d / "five.npy", rows, false);
       }},
      {"AgainstSamples5", "validate --sampler heitz2018 --alpha 0.3 --theta 60 --samples 5 --against ellipsoid --rays 100000" + kOut,
       2, "5 sample(s) are too few"},
      {"AgainstSamples500", "validate --sampler heitz2018 --alpha 0.3 --theta 60 --samples 500 --against ellipsoid --rays 100000" + kOut,
       2, "500 sample(s) are too few: the comparison with the traced histogram needs at least"},
      {"AgainstFromOneLine", "validate --from one.txt --alpha 0.3 --theta 60 --against ellipsoid --rays 100000" + kOut, 2,
       "1 sample(s) are too few", [](const fs::path& d) { write_lines(d / "one.txt", 1); }},
      {"AgainstTooFewRays", "validate --sampler heitz2018 --alpha 0.3 --theta 60 --samples 100000 --against ellipsoid --rays 5" + kOut,
       2, "hits, too few: the comparison needs at least"},
  };
}

class BadInputsValidate : public ::testing::TestWithParam<BadInputCase> {};

TEST_P(BadInputsValidate, ExitsTwoSaysHowManyAreNeededWritesNothing) { expect_bad_input(GetParam(), "bad_validate"); }

INSTANTIATE_TEST_SUITE_P(TooFewSamples, BadInputsValidate, ::testing::ValuesIn(too_few_samples_cases()),
                         [](const ::testing::TestParamInfo<BadInputCase>& i) { return i.param.name; });

}  // namespace

}  // namespace test_bad_inputs_validate
