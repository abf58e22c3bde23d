// Shard and merge for trace masking: a run split with --shard K/N and joined by `microsim merge`
// is the single run, bit for bit (every non-timing JSON number, and the table), for 3 and 5 shards in any
// order and thread count on two assemblies; in the library, the exact sums of any grouping of blocks are
// the single run's, with both samplings. Parts with a gap, an overlap, another seed, another view or
// surface, or of another kind (a VNDF histogram) are refused (exit 2) with the ranges or the difference
// named, and nothing is written.
#include "cli_helpers.h"
#include "merge_errors_suite.h"
#include "output_digest.h"

#include "measure/masking.h"
#include "microgeom/assembly.h"

#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

namespace microsim::test {
namespace {

// ---- library: exact sums in any grouping -------------------------------------------------------------------

struct SmallSurface {
  microgeom::Heightfield field;
  std::unique_ptr<HeightfieldScene> scene;
  std::unique_ptr<EmpiricalSmith> empirical;
  std::unique_ptr<AnalyticSmith> analytic;
};

const SmallSurface& small_masking_surface() {
  static const std::unique_ptr<SmallSurface> s = [] {
    microgeom::AssemblyParams p;
    p.assembly = "sorted";
    p.alpha_x = p.alpha_y = 0.5;
    p.resolution = 128;
    p.seed = 4;
    auto out = std::make_unique<SmallSurface>(SmallSurface{microgeom::build_assembly(p), nullptr, nullptr, nullptr});
    out->scene = std::make_unique<HeightfieldScene>(out->field);
    out->empirical = std::make_unique<EmpiricalSmith>(out->field);
    out->analytic = std::make_unique<AnalyticSmith>(analytic_reference(out->field));
    return out;
  }();
  return *s;
}

MaskingResult run_blocks(const MaskingOptions& base, std::optional<BlockRange> blocks, int threads) {
  const SmallSurface& s = small_masking_surface();
  MaskingOptions o = base;
  o.blocks = blocks;
  o.run.threads = threads;
  return estimate_masking(*s.scene, *s.analytic, *s.empirical, direction_from_degrees(70.0, 25.0), o);
}

class ExactMaskingSums : public ::testing::TestWithParam<PointSampling> {};

TEST_P(ExactMaskingSums, AnyGroupingOfBlocksIsTheSingleRun) {
  MaskingOptions o;
  o.samples = 30 * kSamplesPerBlock + 123;  // 31 blocks, the last one short
  o.seed = 9;
  o.sampling = GetParam();
  o.light = direction_from_degrees(50.0, 200.0);
  const MaskingResult whole = run_blocks(o, std::nullopt, 2);
  ASSERT_EQ(whole.total_blocks, 31u);
  const std::vector<BlockRange> parts = {{17, 31}, {0, 5}, {5, 17}};
  MaskingSums sum = MaskingSums::empty(o.normal_bins, o.height_bins);
  for (std::size_t k = 0; k < parts.size(); ++k) sum += run_blocks(o, parts[k], 1 + int(k % 2)).sums;
  EXPECT_TRUE(sum == whole.sums);
  const SmallSurface& s = small_masking_surface();
  const MaskingResult merged = masking_result_from_sums(s.field, *s.analytic, *s.empirical, direction_from_degrees(70.0, 25.0),
                                                        o, sum, {0, 31});
  expect_contains(pinned_part(to_json(whole)), pinned_part(to_json(merged)), "merged");
  expect_contains(pinned_part(to_json(merged)), pinned_part(to_json(whole)), "whole");
  // The real-valued sums are not integers (the test would pass trivially with counts alone).
  EXPECT_NE(whole.sums.mirror.pred_analytic.value(), std::floor(whole.sums.mirror.pred_analytic.value()));
}

INSTANTIATE_TEST_SUITE_P(Samplings, ExactMaskingSums, ::testing::Values(PointSampling::projected, PointSampling::uniform),
                         [](const auto& info) { return info.param == PointSampling::projected ? "projected" : "uniform"; });

TEST(ExactMaskingSums, SumsOfOtherBinsAreRefused) {
  MaskingSums a = MaskingSums::empty(10, 10), b = MaskingSums::empty(10, 8);
  EXPECT_THROW(a += b, std::invalid_argument);
}

// ---- the command line: merge of shards == single run ---------------------------------------------------------

struct MaskingShardCase {
  std::string name;
  std::string build;  // surface build arguments (writes s.exr)
  std::string trace;  // trace masking arguments without --shard/--json/--threads
  int shards;
};

void PrintTo(const MaskingShardCase& c, std::ostream* os) { *os << c.name; }

// The table rows and the leak test line of a report (the lines without timings).
std::string masking_table_of(const std::string& out) {
  std::istringstream in(out);
  std::string line, table;
  while (std::getline(in, line))
    if (line.starts_with("|") || line.starts_with("leak test")) table += line + "\n";
  return table;
}

class MaskingShardMerge : public ::testing::TestWithParam<MaskingShardCase> {};

TEST_P(MaskingShardMerge, MergedShardsAreTheSingleRunBitForBit) {
  const MaskingShardCase& c = GetParam();
  const fs::path dir = scratch_dir("masking_shard", c.name);
  ASSERT_EQ(run_cli(dir, c.build + " --out s.exr --quiet").exit_code, 0);
  const CliRun whole = run_cli(dir, c.trace + " --threads 2 --json whole.json");
  ASSERT_EQ(whole.exit_code, 0) << whole.err;
  std::string parts;
  for (int k = c.shards; k >= 1; --k) {  // any order
    const std::string part = "part" + std::to_string(k) + ".json";
    const CliRun r = run_cli(dir, c.trace + " --threads " + std::to_string(1 + k % 2) + " --shard " + std::to_string(k) +
                                      "/" + std::to_string(c.shards) + " --json " + part);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    parts += " " + part;
  }
  const CliRun merged = run_cli(dir, "merge" + parts + " --json merged.json");
  ASSERT_EQ(merged.exit_code, 0) << merged.err;
  const json want = pinned_part(json::parse(slurp(dir / "whole.json")));
  const json got = pinned_part(json::parse(slurp(dir / "merged.json")));
  ASSERT_TRUE(want.contains("sums") && want["provenance"]["blocks"] == json::array({0, want["provenance"]["total_blocks"]}));
  expect_contains(want, got, c.name + " (whole in merged)");
  expect_contains(got, want, c.name + " (merged in whole)");
  EXPECT_EQ(masking_table_of(merged.out), masking_table_of(whole.out));
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(
    Runs, MaskingShardMerge,
    ::testing::Values(
        MaskingShardCase{"sorted_3", "surface build --assembly sorted --res 256 --alpha 0.5 --seed 2",
                         "trace masking --surface s.exr --theta 60 --phi 20 --theta-l 40 --samples 120000 --seed 2", 3},
        MaskingShardCase{"sorted_5", "surface build --assembly sorted --res 256 --alpha 0.5 --seed 2",
                         "trace masking --surface s.exr --theta 75 --phi 30 --samples 100000 --seed 5 --bins 7", 5},
        MaskingShardCase{"smith_3", "surface build --assembly smith --res 256 --alpha 0.3 --seed 1",
                         "trace masking --surface s.exr --theta 80 --theta-l 60 --phi-l 150 --samples 90000 --seed 3", 3},
        MaskingShardCase{"smith_5", "surface build --assembly smith --res 256 --alpha 0.3 --seed 1",
                         "trace masking --surface s.exr --theta 45 --phi 10 --theta-l 30 --samples 110000 --seed 4 "
                         "--grazing-share 0.05 --cone 8",
                         5}),
    [](const auto& info) { return info.param.name; });

// ---- merge errors ----------------------------------------------------------------------------------------------

// The parts of a run of 25 blocks (100000 samples) in three shards: [0, 8), [8, 16), [16, 25); and parts of
// other runs: another seed, another view, another surface, a VNDF histogram of the same surface.
class MaskingMergeErrors : public MergeErrorsSuite<MaskingMergeErrors> {
protected:
  static void SetUpTestSuite() {
    dir() = scratch_dir("masking_merge", "errors");
    // The surfaces and parts, made once per build of the tests (shared_fixture_dir) and copied here.
    copy_fixture_files(shared_fixture_dir("masking_merge_errors", [](const fs::path& d) {
      ASSERT_EQ(run_cli(d, "surface build --assembly sorted --res 256 --alpha 0.5 --seed 2 --out s.exr --quiet").exit_code, 0);
      ASSERT_EQ(run_cli(d, "surface build --assembly sorted --res 256 --alpha 0.5 --seed 3 --out t.exr --quiet").exit_code, 0);
      const std::string run = "trace masking --surface s.exr --theta 60 --theta-l 40 --samples 100000";
      for (int k = 1; k <= 3; ++k)
        ASSERT_EQ(run_cli(d, run + " --seed 7 --shard " + std::to_string(k) + "/3 --json p" + std::to_string(k) + ".json").exit_code, 0);
      ASSERT_EQ(run_cli(d, run + " --seed 8 --shard 2/3 --json seed8.json").exit_code, 0);
      ASSERT_EQ(run_cli(d, "trace masking --surface s.exr --theta 50 --theta-l 40 --samples 100000 --seed 7 --shard 2/3 "
                               "--json theta50.json").exit_code, 0);
      ASSERT_EQ(run_cli(d, "trace masking --surface t.exr --theta 60 --theta-l 40 --samples 100000 --seed 7 --shard 2/3 "
                               "--json other_surface.json").exit_code, 0);
      ASSERT_EQ(run_cli(d, "trace vndf --surface s.exr --theta 60 --rays 30000 --seed 7 --shard 2/3 --out vpart.json --json v.json").exit_code, 0);
    }), dir());
  }
};

TEST_F(MaskingMergeErrors, TheShardsMerge) {
  const CliRun r = run_cli(dir(), "merge p3.json p1.json p2.json --json merged.json");
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(dir() / "merged.json"));
  fs::remove(dir() / "merged.json");
}
TEST_F(MaskingMergeErrors, AGapIsNamed) { expect_refused("p1.json p3.json --json m.json", "blocks [8, 16) of [0, 25) are missing"); }
TEST_F(MaskingMergeErrors, AMissingEndIsNamed) { expect_refused("p1.json p2.json --json m.json", "blocks [16, 25) of [0, 25) are missing"); }
TEST_F(MaskingMergeErrors, AnOverlapIsNamed) {
  expect_refused("p1.json p2.json p2.json p3.json --json m.json", "blocks [8, 16) are in more than one part");
}
TEST_F(MaskingMergeErrors, AnotherSeedIsRefused) { expect_refused("p1.json seed8.json p3.json --json m.json", "seed '7' vs '8'"); }
TEST_F(MaskingMergeErrors, AnotherViewIsRefused) {
  expect_refused("p1.json theta50.json p3.json --json m.json", "part 2 is not part of the same run: theta is '50.0' there");
}
TEST_F(MaskingMergeErrors, AnotherSurfaceIsRefused) {
  expect_refused("p1.json other_surface.json p3.json --json m.json", "part 2 is not part of the same run: surface is 't.exr'");
}
TEST_F(MaskingMergeErrors, ASurfaceOtherThanTheTracedOneIsRefused) {
  expect_refused("p1.json p2.json p3.json --surface t.exr --json m.json", "is not the one the parts were traced on");
}
TEST_F(MaskingMergeErrors, AVndfHistogramIsAnotherKind) {
  expect_refused("p1.json vpart.json p3.json --json m.json", "parts of one run are of one kind");
  expect_refused("vpart.json p1.json --out m.exr", "parts of one run are of one kind");
}
TEST_F(MaskingMergeErrors, AVndfReportIsNotAMaskingPart) {
  expect_refused("p1.json v.json p3.json --json m.json", "part 'v.json': not a trace masking report");
}
TEST_F(MaskingMergeErrors, AnOutputThatIsAPartIsRefused) { expect_refused("p1.json p2.json p3.json --json p2.json", "p2.json"); }
TEST_F(MaskingMergeErrors, AnExrOutputIsRefused) { expect_refused("p1.json p2.json p3.json --out m.exr", "--out 'm.exr'"); }

}  // namespace
}  // namespace microsim::test
