// Bad-input table: an output that cannot be created (a directory, or in a directory that does
// not exist) is refused before any work by the one check of core/output_paths.h (check_writable), with the
// option and the path named, by every command alike: plot and validate had a check of their own that saw
// only a missing directory, so a validation ran to its end before its --json or --plot failed to be written.
#include "cli_helpers.h"

#include "stats/histogram_io.h"
#include "validate/compare.h"

#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_bad_inputs_output_dirs {

namespace {

using microsim::test::BadInputCase;
namespace fs = std::filesystem;

// A small traced histogram with its expected counts (what `plot` draws), and a directory named like an output.
void histogram_and_directory(const fs::path& dir) {
  const microsim::GGX<double> ggx(0.5);
  const microsim::Vec3<double> wi = microsim::direction_from_degrees(30.0, 0.0);
  microsim::OracleTraceOptions t;
  t.rays = 20000;
  t.rows = 9;
  microsim::TraceResult raw;
  microsim::TracedHistogram h = microsim::trace_vndf_histogram(ggx, wi, t, &raw);
  microsim::analyse_against_vndf(h, ggx, wi, raw.unbinned);
  microsim::write_histogram_exr(dir / "h.exr", h);
  fs::create_directory(dir / "out.json");
  fs::create_directory(dir / "fig.svg");
  fs::create_directory(dir / "m.ply");
}

const std::string kValidateRows9 = "validate --sampler heitz2018 --alpha 0.3 --theta 30 --samples 20000 --rows 9 ";

std::vector<BadInputCase> output_dirs_cases() {
  return {
      {"PlotOutIsADirectory", "plot h.exr --out fig.svg", 2, "--out: output 'fig.svg' is a directory",
       histogram_and_directory},
      {"PlotOutInAMissingDirectory", "plot h.exr --out nodir/f.svg", 2,
       "--out: cannot write 'nodir/f.svg': directory 'nodir' does not exist", histogram_and_directory},
      {"ValidateJsonIsADirectory", kValidateRows9 + "--json out.json", 2, "--json: output 'out.json' is a directory",
       histogram_and_directory},
      {"ValidatePlotIsADirectory", kValidateRows9 + "--plot fig.svg", 2, "--plot: output 'fig.svg' is a directory",
       histogram_and_directory},
      {"ValidatePlotInAMissingDirectory", kValidateRows9 + "--plot nodir/f.svg", 2,
       "--plot: cannot write 'nodir/f.svg': directory 'nodir' does not exist", histogram_and_directory},
      {"TraceMeshOutIsADirectory", "trace vndf --alpha 0.3 --theta 30 --rays 1000 --mesh-level 1 --out o.exr --mesh-out m.ply",
       2, "--mesh-out: output 'm.ply' is a directory", histogram_and_directory},
  };
}

class OutputThatCannotBeCreated : public ::testing::TestWithParam<BadInputCase> {};

TEST_P(OutputThatCannotBeCreated, IsRefusedBeforeAnyWork) { microsim::test::expect_bad_input(GetParam(), "output_dirs"); }

INSTANTIATE_TEST_SUITE_P(Cases, OutputThatCannotBeCreated, ::testing::ValuesIn(output_dirs_cases()),
                         [](const auto& info) { return info.param.name; });

}  // namespace

}  // namespace test_bad_inputs_output_dirs
