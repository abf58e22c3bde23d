// Data loss: an output that is the same file as an input, or two outputs of one command
// on the same file, are refused before any work (exit 2, both options and the path named, nothing
// written, the input unchanged). "The same file" by filesystem identity: the same spelling, another
// spelling (./sub/../in.txt, an absolute path), a hard link, a symbolic link. Plus the same-file rules
// themselves (src/core/output_paths.h) and the atomic writer's temporaries (microgeom/atomic_file.h).
#include "cli_helpers.h"

#include "microgeom/assembly.h"
#include "core/atomic_file.h"
#include "microgeom/heightfield.h"
#include "validate/compare.h"
#include "stats/histogram_io.h"
#include "core/output_paths.h"
#include "core/random.h"
#include "validate/sample_io.h"
#include "microfacet/samplers.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_bad_inputs_outputs {

namespace {

namespace fs = std::filesystem;
using microsim::test::BadInputCase;

void write_file(const fs::path& path, const std::string& text) { std::ofstream(path) << text; }

// ---- inputs, made once per build of the tests with the library and copied into each case's directory -----

fs::path input_cache() {
  static const fs::path dir = microsim::test::shared_fixture_dir("outputs", [](const fs::path& d) {
    // Directions of a correct sampler: `validate --from` passes on them (so it would write its JSON).
    const microsim::SamplerInfo* s = microsim::find_sampler("heitz2018");
    const microsim::GGX<double> ggx(0.3);
    const microsim::Vec3<double> wi = microsim::direction_from_degrees(30.0, 0.0);
    std::vector<microsim::Vec3<double>> samples;
    for (int i = 0; samples.size() < 20000; ++i) {
      microsim::CounterRng rng(7, std::uint64_t(i));
      if (const auto r = s->sample_double(ggx, wi, microsim::Vec2<double>(rng.uniform(), rng.uniform())))
        samples.push_back(r->direction);
    }
    microsim::write_text_samples(d / "in.txt", samples);
    // A small heightmap (64^2 Beckmann surface).
    microgeom::AssemblyParams p;
    p.assembly = "beckmann";
    p.resolution = 64;
    p.corr_cells = 4;
    microgeom::save_heightmap_exr(d / "in.exr", microgeom::build_assembly(p));
    // A traced histogram of the ellipsoid at alpha 0.5, theta 30 deg (with its expected counts).
    const microsim::GGX<double> g5(0.5);
    const microsim::Vec3<double> w30 = microsim::direction_from_degrees(30.0, 0.0);
    microsim::OracleTraceOptions t;
    t.rays = 200000;
    microsim::TraceResult raw;
    microsim::TracedHistogram h = microsim::trace_vndf_histogram(g5, w30, t, &raw);
    microsim::analyse_against_vndf(h, g5, w30, raw.unbinned);
    microsim::write_histogram_exr(d / "hist.exr", h);
  });
  return dir;
}

// Copies the named inputs into `dir`, adds a subdirectory `sub` (for ./sub/../ spellings), a hard link
// `hard.EXT` and a symbolic link `sym.EXT` to the first input.
std::function<void(const fs::path&)> with_inputs(std::vector<std::string> names) {
  return [names](const fs::path& dir) {
    for (const auto& n : names) fs::copy_file(input_cache() / n, dir / n);
    fs::create_directory(dir / "sub");
    const std::string ext = fs::path(names.front()).extension().string();
    fs::create_hard_link(dir / names.front(), dir / ("hard" + ext));
    fs::create_symlink(names.front(), dir / ("sym" + ext));
  };
}

const auto kSamples = with_inputs({"in.txt"});
const auto kHeightmap = with_inputs({"in.exr"});
const auto kHistogram = with_inputs({"hist.exr"});
const auto kNothing = [](const fs::path& dir) { fs::create_directory(dir / "sub"); };

const std::string kValidateFrom = "validate --from in.txt --alpha 0.3 --theta 30";
const std::string kValidateAgainst = "validate --sampler heitz2018 --alpha 0.5 --theta 30 --samples 20000 --against hist.exr";
const std::string kTraceEllipsoid = "trace vndf --alpha 0.5 --theta 30 --rays 20000";
const std::string kTraceSurface = "trace vndf --surface in.exr --theta 30 --rays 20000";
const std::string kMasking = "trace masking --surface in.exr --theta 30 --samples 20000";
const std::string kTable =
    "trace masking --table --assemblies beckmann --alphas 0.5 --thetas 30 --res 64 --samples 2000 --vndf-rays 2000";
const std::string kBuild = "surface build --assembly beckmann --alpha 0.5 --res 64 --quiet";

// The messages: an output on an input, two outputs on one file.
std::string on_input(const std::string& out_option, const std::string& out, const std::string& in_option,
                     const std::string& in) {
  return out_option + " '" + out + "' is the same file as the input " + in_option + " '" + in + "'";
}
std::string same_outputs(const std::string& option1, const std::string& path1, const std::string& option2,
                         const std::string& path2) {
  return option1 + " '" + path1 + "' and " + option2 + " '" + path2 + "' are the same file";
}

std::vector<BadInputCase> outputs_cases() {
  const auto in_txt = [](const std::string& out_option, const std::string& spelling) {
    return on_input(out_option, spelling, "--from", "in.txt");
  };
  return {
      // an output on an input: every command with an input
      {"ValidateJsonOnFrom", kValidateFrom + " --json in.txt", 2, in_txt("--json", "in.txt"), kSamples},
      {"ValidateJsonOnFromSpelledDotDot", kValidateFrom + " --json ./sub/../in.txt", 2,
       in_txt("--json", "./sub/../in.txt"), kSamples},
      {"ValidateJsonOnFromAbsolute", kValidateFrom + " --json \"$PWD/in.txt\"", 2, "is the same file as the input --from 'in.txt'",
       kSamples},
      {"ValidateJsonOnFromHardLink", kValidateFrom + " --json hard.txt", 2, in_txt("--json", "hard.txt"), kSamples},
      {"ValidateJsonOnFromSymlink", kValidateFrom + " --json sym.txt", 2, in_txt("--json", "sym.txt"), kSamples},
      {"ValidateFromOnSymlinkedJson", "validate --from sym.txt --alpha 0.3 --theta 30 --json in.txt", 2,
       on_input("--json", "in.txt", "--from", "sym.txt"), kSamples},
      {"ValidatePlotOnFrom", kValidateFrom + " --plot in.txt", 2, in_txt("--plot", "in.txt"), kSamples},
      {"ValidateJsonOnAgainst", kValidateAgainst + " --json hist.exr", 2,
       on_input("--json", "hist.exr", "--against", "hist.exr"), kHistogram},
      {"ValidateJsonOnAgainstHardLink", kValidateAgainst + " --json hard.exr", 2,
       on_input("--json", "hard.exr", "--against", "hist.exr"), kHistogram},
      {"TraceVndfOutOnSurface", kTraceSurface + " --out in.exr", 2,
       on_input("--out", "in.exr", "--surface", "in.exr"), kHeightmap},
      {"TraceVndfOutOnSurfaceSymlink", kTraceSurface + " --out sym.exr", 2,
       on_input("--out", "sym.exr", "--surface", "in.exr"), kHeightmap},
      {"TraceVndfJsonOnSurface", kTraceSurface + " --out h.exr --json in.exr", 2,
       on_input("--json", "in.exr", "--surface", "in.exr"), kHeightmap},
      {"TraceMaskingJsonOnSurface", kMasking + " --json in.exr", 2,
       on_input("--json", "in.exr", "--surface", "in.exr"), kHeightmap},
      {"TraceMaskingJsonOnSurfaceHardLink", kMasking + " --json hard.exr", 2,
       on_input("--json", "hard.exr", "--surface", "in.exr"), kHeightmap},
      {"SurfaceStatsJsonOnInput", "surface stats in.exr --json in.exr", 2,
       on_input("--json", "in.exr", "heightmap", "in.exr"), kHeightmap},
      {"SurfaceStatsNormalsOnInputDotDot", "surface stats in.exr --normals sub/../in.exr", 2,
       on_input("--normals", "sub/../in.exr", "heightmap", "in.exr"), kHeightmap},
      {"SurfaceStatsMeshOnInputSymlink", "surface stats in.exr --mesh sym.exr", 2,
       on_input("--mesh", "sym.exr", "heightmap", "in.exr"), kHeightmap},
      {"SurfaceImportOutOnInput", "surface import in.exr --tile-size 1 --out in.exr", 2,
       on_input("--out", "in.exr", "heightmap", "in.exr"), kHeightmap},
      {"SurfaceImportOutOnInputHardLink", "surface import in.exr --tile-size 1 --out hard.exr", 2,
       on_input("--out", "hard.exr", "heightmap", "in.exr"), kHeightmap},
      {"PlotOutOnHistogram", "plot hist.exr --out hist.exr", 2,
       on_input("--out", "hist.exr", "histogram", "hist.exr"), kHistogram},
      {"PlotOutOnHistogramSymlink", "plot hist.exr --out sym.exr", 2,
       on_input("--out", "sym.exr", "histogram", "hist.exr"), kHistogram},
      // two outputs of one command on one file (existing or not yet)
      {"ValidateJsonAndPlot", kValidateFrom + " --json fig.svg --plot fig.svg", 2,
       same_outputs("--json", "fig.svg", "--plot", "fig.svg"), kSamples},
      {"ValidateJsonAndPlotSpelled", kValidateFrom + " --json fig.svg --plot ./sub/../fig.svg", 2,
       same_outputs("--json", "fig.svg", "--plot", "./sub/../fig.svg"), kSamples},
      {"TraceVndfOutAndJson", kTraceEllipsoid + " --out o.exr --json o.exr", 2,
       same_outputs("--out", "o.exr", "--json", "o.exr"), kNothing},
      {"TraceVndfOutAndJsonExistingHardLink", kTraceEllipsoid + " --out in.exr --json hard.exr", 2,
       same_outputs("--out", "in.exr", "--json", "hard.exr"), kHeightmap},
      {"TraceVndfOutAndMeshOut", kTraceEllipsoid + " --mesh-level 1 --out o.exr --mesh-out ./o.exr", 2,
       same_outputs("--out", "o.exr", "--mesh-out", "./o.exr"), kNothing},
      {"TraceVndfSurfaceOutAndJson", kTraceSurface + " --out o.exr --json sub/../o.exr", 2,
       same_outputs("--out", "o.exr", "--json", "sub/../o.exr"), kHeightmap},
      {"TraceMaskingTableJsonAndMarkdown", kTable + " --json t.md --markdown t.md", 2,
       same_outputs("--json", "t.md", "--markdown", "t.md"), kNothing},
      {"SurfaceBuildOutAndNormals", kBuild + " --out o.exr --normals o.exr", 2,
       same_outputs("--out", "o.exr", "--normals", "o.exr"), kNothing},
      {"SurfaceBuildOutAndJsonSymlink", kBuild + " --out in.exr --json sym.exr", 2,
       same_outputs("--out", "in.exr", "--json", "sym.exr"), kHeightmap},
      {"SurfaceBuildMeshAndJson", kBuild + " --out o.exr --mesh m.ply --json ./m.ply", 2,
       same_outputs("--mesh", "m.ply", "--json", "./m.ply"), kNothing},
      {"SurfaceStatsMeshAndJson", "surface stats in.exr --json m.ply --mesh m.ply", 2,
       same_outputs("--json", "m.ply", "--mesh", "m.ply"), kHeightmap},
      {"SurfaceStatsNormalsAndJson", "surface stats in.exr --json n.exr --normals sub/../n.exr", 2,
       same_outputs("--json", "n.exr", "--normals", "sub/../n.exr"), kHeightmap},
  };
}

class OutputPathTable : public ::testing::TestWithParam<BadInputCase> {};

TEST_P(OutputPathTable, RefusedBeforeAnyWork) { microsim::test::expect_bad_input(GetParam(), "outputs"); }

INSTANTIATE_TEST_SUITE_P(SamePath, OutputPathTable, ::testing::ValuesIn(outputs_cases()),
                         [](const auto& info) { return info.param.name; });

// ---- what is still allowed -----------------------------------------------------------------------------

// Distinct outputs next to the inputs, and replacing an existing output that is no input, still work.
TEST(OutputPaths, DistinctOutputsAreWritten) {
  const fs::path dir = microsim::test::scratch_dir("outputs", "distinct");
  kHeightmap(dir);
  write_file(dir / "old.json", "{}\n");
  const auto r = microsim::test::run_cli(dir, "surface stats in.exr --json old.json --normals n.exr");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(microsim::test::slurp(dir / "old.json"), "{}\n");
  EXPECT_TRUE(fs::exists(dir / "n.exr"));
  fs::remove_all(dir);
}

// The old writers staged JSON in PATH.partial: `--json s.txt` with the input s.txt.partial truncated the
// input. A temporary is now always a new file.
TEST(OutputPaths, TemporaryNeverTruncatesAnInput) {
  const fs::path dir = microsim::test::scratch_dir("outputs", "partial_name");
  fs::copy_file(input_cache() / "in.txt", dir / "s.txt.partial");
  const std::string before = microsim::test::slurp(dir / "s.txt.partial");
  const auto r = microsim::test::run_cli(dir, "validate --from s.txt.partial --alpha 0.3 --theta 30 --json s.txt");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(microsim::test::slurp(dir / "s.txt.partial"), before) << "the input was overwritten";
  EXPECT_NE(microsim::test::slurp(dir / "s.txt").find("\"verdict\""), std::string::npos);
  EXPECT_EQ(microsim::test::file_count(dir), 2u) << "a temporary was left behind";
  fs::remove_all(dir);
}

// ---- the rules, directly ---------------------------------------------------------------------------------

TEST(OutputPaths, SameFileByIdentityNotSpelling) {
  const fs::path dir = microsim::test::scratch_dir("outputs", "same_file");
  write_file(dir / "a.txt", "a");
  write_file(dir / "b.txt", "a");  // same contents, another file
  fs::create_directory(dir / "sub");
  fs::create_hard_link(dir / "a.txt", dir / "hard.txt");
  fs::create_symlink("a.txt", dir / "sym.txt");
  fs::create_symlink("missing.txt", dir / "dangling.txt");
  using microsim::same_file;
  EXPECT_TRUE(same_file(dir / "a.txt", dir / "sub/../a.txt"));
  EXPECT_TRUE(same_file(dir / "a.txt", dir / "hard.txt"));
  EXPECT_TRUE(same_file(dir / "sym.txt", dir / "a.txt"));
  EXPECT_FALSE(same_file(dir / "a.txt", dir / "b.txt"));
  EXPECT_TRUE(same_file(dir / "new.txt", dir / "./sub/../new.txt"));  // neither exists yet
  EXPECT_FALSE(same_file(dir / "new.txt", dir / "a.txt"));
  EXPECT_FALSE(same_file(dir / "new.txt", dir / "other.txt"));
  EXPECT_FALSE(same_file(dir / "dangling.txt", dir / "a.txt"));
  EXPECT_THROW(microsim::check_output_paths({{"--in", dir / "a.txt"}}, {{"--out", dir / "hard.txt"}}),
               microsim::OutputPathError);
  EXPECT_THROW(microsim::check_output_paths({}, {{"--one", dir / "x"}, {"--two", dir / "sub/../x"}}),
               microsim::OutputPathError);
  EXPECT_NO_THROW(microsim::check_output_paths({{"--in", dir / "a.txt"}, {"--unused", ""}},
                                               {{"--out", dir / "b.txt"}, {"--none", ""}, {"--also-none", ""}}));
  fs::remove_all(dir);
}

TEST(AtomicFile, TemporariesAreNewSiblingsAndLeaveNothing) {
  const fs::path dir = microsim::test::scratch_dir("outputs", "atomic");
  write_file(dir / "out.exr", "old");
  {
    const microsim::TemporaryFile a(dir / "out.exr"), b(dir / "out.exr");
    EXPECT_NE(a.path(), b.path());
    EXPECT_EQ(a.path().parent_path(), dir);
    EXPECT_EQ(a.path().extension(), ".exr");
    EXPECT_TRUE(fs::exists(a.path()));
    EXPECT_EQ(fs::file_size(a.path()), 0u);
  }
  EXPECT_EQ(microsim::test::file_count(dir), 1u);  // both removed, the destination untouched
  EXPECT_EQ(microsim::test::slurp(dir / "out.exr"), "old");
  microsim::write_file_atomically(dir / "out.exr", std::string_view("new"));
  EXPECT_EQ(microsim::test::slurp(dir / "out.exr"), "new");
  EXPECT_THROW(microsim::write_file_atomically(dir / "out.exr",
                                                [](const fs::path&) { throw std::runtime_error("writer failed"); }),
               std::runtime_error);
  EXPECT_EQ(microsim::test::slurp(dir / "out.exr"), "new");
  EXPECT_EQ(microsim::test::file_count(dir), 1u);
  EXPECT_THROW(microsim::TemporaryFile(dir / "no_such_dir" / "x.json"), microsim::FileWriteError);
  fs::remove_all(dir);
}

}  // namespace

}  // namespace test_bad_inputs_outputs
