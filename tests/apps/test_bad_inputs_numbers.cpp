// The numbers given on the command line: every numeric option of every
// command that takes numbers (validate, trace vndf, trace masking, surface build/stats/import, stability,
// albedo)
// goes through the one parser (src/core/parse.h). Each row: exit 2, stderr names the bad value (a
// short, escaped excerpt of it), and no file in the scratch directory is created or changed. `plot`
// takes no numbers on its command line.
#include "cli_helpers.h"
#include "microgeom/exr_io.h"
#include "stats/binning.h"
#include "core/parse.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_bad_inputs_numbers {

namespace {

namespace fs = std::filesystem;
using microsim::test::BadInputCase;

// A 16 x 16 flat heightmap (tile size from --tile-size) for the commands that read a surface.
void flat_surface(const fs::path& dir) {
  microgeom::ExrImage image;
  image.width = image.height = 16;
  image.add_channel("height");
  microgeom::write_exr(dir / "s.exr", image);
}

// A command line: the command and its options; with(option, value) replaces or adds one option, so that
// no option is given twice.
struct CommandLine {
  std::string command;
  std::vector<std::pair<std::string, std::string>> options;
  std::string with(const std::string& option, const std::string& value) const {
    std::string out = command;
    bool replaced = false;
    for (const auto& [o, v] : options) {
      const bool mine = o == option;
      replaced = replaced || mine;
      out += " " + o + (mine ? (value.empty() ? "" : " " + value) : (v.empty() ? "" : " " + v));
    }
    if (!replaced) out += " " + option + " " + value;
    return out;
  }
};

const CommandLine kValidateLine{
    "validate",
    {{"--sampler", "heitz2018"}, {"--alpha", "0.3"}, {"--theta", "30"}, {"--samples", "1000"}, {"--json", "v.json"}}};
const CommandLine kTraceLine{"trace vndf", {{"--alpha", "0.3"}, {"--theta", "30"}, {"--rays", "1000"}, {"--out", "o.exr"}}};
const CommandLine kTraceSurfaceLine{
    "trace vndf",
    {{"--surface", "s.exr"}, {"--tile-size", "1"}, {"--theta", "30"}, {"--rays", "10"}, {"--out", "h.exr"}}};
const CommandLine kMaskingLine{
    "trace masking",
    {{"--surface", "s.exr"}, {"--tile-size", "1"}, {"--theta", "30"}, {"--samples", "1000"}, {"--json", "m.json"}}};
const CommandLine kTableLine{"trace masking --table",
                         {{"--assemblies", "smith"},
                          {"--alphas", "0.5"},
                          {"--thetas", "30"},
                          {"--res", "64"},
                          {"--samples", "1000"},
                          {"--vndf-rays", "1000"},
                          {"--markdown", "t.md"}}};
const CommandLine kBuildLine{"surface build --quiet",
                         {{"--assembly", "smith"}, {"--alpha", "0.5"}, {"--res", "64"}, {"--out", "x.exr"}}};
const CommandLine kStatsLine{"surface stats s.exr", {{"--tile-size", "1"}, {"--json", "st.json"}}};
const CommandLine kImportLine{"surface import s.exr", {{"--tile-size", "1"}, {"--out", "y.exr"}}};
const CommandLine kStabilityLine{"stability", {{"--random-u", "0"}, {"--failures-only", ""}, {"--json", "sb.json"}}};
const CommandLine kAlbedoLine{"albedo --model smith-walk", {{"--alphas", "0.5"}, {"--mus", "2"}, {"--rays", "1000"}, {"--out", "a.exr"}}};
const CommandLine kAlbedoSurfaceLine{"albedo --model surface", {{"--alphas", "0.5"}, {"--mus", "2"}, {"--rays", "10"}, {"--out", "a.exr"}}};
const CommandLine kAlbedoAnalyticLine{"albedo --model analytic", {{"--alphas", "0.5"}, {"--mus", "2"}, {"--out", "a.exr"}}};

std::vector<BadInputCase> numbers_cases() {
  const auto surface = [](const fs::path& dir) { flat_surface(dir); };
  const std::string max_rays = "an integer in [1, 1000000000000 (1e12)]";
  return {
      // ---- --rows, one bound (kMaxBinningRows = 501) for validate and trace ----
      {"ValidateRows46341", kValidateLine.with("--rows", "46341"), 2, "--rows '46341': too large: an integer in [3, 501]"},
      {"ValidateRows1048577", kValidateLine.with("--rows", "1048577"), 2, "'1048577': too large: an integer in [3, 501]"},
      {"ValidateRows2147483647", kValidateLine.with("--rows", "2147483647"), 2, "'2147483647': too large"},
      {"ValidateRows16383", kValidateLine.with("--rows", "16383"), 2, "'16383': too large: an integer in [3, 501]"},
      {"ValidateRows4095", kValidateLine.with("--rows", "4095"), 2, "'4095': too large: an integer in [3, 501]"},
      {"ValidateRows503", kValidateLine.with("--rows", "503"), 2, "'503': too large"},
      {"ValidateRowsEven", kValidateLine.with("--rows", "30"), 2, "--rows '30': must be odd"},
      {"ValidateRowsOne", kValidateLine.with("--rows", "1"), 2, "'1': too small: an integer in [3, 501]"},
      {"ValidateRowsHuge", kValidateLine.with("--rows", "99999999999999999999"), 2, "'99999999999999999999': too large"},
      {"ValidateRowsFraction", kValidateLine.with("--rows", "31.5"), 2, "'31.5': not an integer"},
      {"TraceRows46341", kTraceLine.with("--rows", "46341"), 2, "--rows '46341': too large: an integer in [1, 501]"},
      {"TraceRowsEven", kTraceLine.with("--rows", "2"), 2, "'2': must be odd"},
      {"TraceHeightfieldRows", kTraceSurfaceLine.with("--rows", "2147483647"), 2, "'2147483647': too large", surface},
      // ---- counts have documented maxima (1e12), no clamping, no hang ----
      {"TraceRaysHuge", kTraceLine.with("--rays", "99999999999999999999"), 2,
       "--rays '99999999999999999999': too large: " + max_rays},
      {"TraceRaysAboveMax", kTraceLine.with("--rays", "1000000000001"), 2, "'1000000000001': too large"},
      {"TraceRaysNegative", kTraceLine.with("--rays", "-1"), 2, "--rays '-1': negative"},
      {"TraceRaysZero", kTraceLine.with("--rays", "0"), 2, "'0': too small"},
      {"TraceRaysFraction", kTraceLine.with("--rays", "1.5"), 2, "--rays '1.5': not an integer"},
      {"ValidateRaysHuge", kValidateLine.with("--against", "ellipsoid --rays 99999999999999999999"), 2,
       "--rays '99999999999999999999': too large: " + max_rays},
      {"ValidateSamplesHuge", kValidateLine.with("--samples", "99999999999999999999"), 2,
       "--samples '99999999999999999999': too large: " + max_rays},
      {"ValidateSamples1e13", kValidateLine.with("--samples", "1e13"), 2, "'1e13': too large"},
      {"ValidateSamplesZero", kValidateLine.with("--samples", "0"), 2, "'0': too small"},
      {"ValidateSamplesNegative", kValidateLine.with("--samples", "-5"), 2, "'-5': negative"},
      {"MaskingSamplesHuge", kMaskingLine.with("--samples", "99999999999999999999"), 2, "'99999999999999999999': too large",
       surface},
      {"MaskingVndfRaysHuge", kMaskingLine.with("--vndf-rays", "1e13"), 2, "--vndf-rays '1e13': too large", surface},
      {"MaskingVndfRaysNegative", kMaskingLine.with("--vndf-rays", "-1"), 2, "--vndf-rays '-1': negative", surface},
      {"TableVndfRaysHuge", kTableLine.with("--vndf-rays", "18446744073709551616"), 2, "'18446744073709551616': too large"},
      // ---- seeds, lists, the supported alpha ----
      {"ValidateSeedMinusOne", kValidateLine.with("--seed", "-1"), 2, "--seed '-1': negative"},
      {"ValidateSeedNegativeZero", kValidateLine.with("--seed", "-0"), 2, "--seed '-0': negative"},
      {"ValidateSeed2To64", kValidateLine.with("--seed", "18446744073709551616"), 2,
       "--seed '18446744073709551616': too large: an integer in [0, 18446744073709551615]"},
      {"ValidateSeedFraction", kValidateLine.with("--seed", "1.5"), 2, "--seed '1.5': not an integer"},
      {"TraceSeedMinusOne", kTraceLine.with("--seed", "-1"), 2, "--seed '-1': negative"},
      {"TraceSeed2To64", kTraceLine.with("--seed", "18446744073709551616"), 2, "'18446744073709551616': too large"},
      {"MaskingSeedMinusOne", kMaskingLine.with("--seed", "-1"), 2, "--seed '-1': negative", surface},
      {"TableSeedsMinusOne", kTableLine.with("--seeds", "1,-1"), 2, "--seeds '1,-1' item 2: '-1': negative"},
      {"TableSeedsHuge", kTableLine.with("--seeds", "18446744073709551616"), 2, "'18446744073709551616': too large"},
      {"TableSeedsTrailingComma", kTableLine.with("--seeds", "1,"), 2, "--seeds '1,': empty item after '1'"},
      {"BuildSeedMinusOne", kBuildLine.with("--seed", "-1"), 2, "--seed '-1': negative"},
      {"BuildSeed2To64", kBuildLine.with("--seed", "18446744073709551616"), 2, "'18446744073709551616': too large"},
      {"StabilitySeedMinusOne", kStabilityLine.with("--seed", "-1"), 2, "--seed '-1': negative"},
      {"StabilitySeed2To64", kStabilityLine.with("--seed", "18446744073709551616"), 2, "'18446744073709551616': too large"},
      {"TraceAlphaTrailingComma", kTraceLine.with("--alpha", "0.3,"), 2, "--alpha '0.3,': empty item after '0.3'"},
      {"ValidateAlphaTrailingComma", kValidateLine.with("--alpha", "0.3,"), 2, "--alpha '0.3,': empty item after '0.3'"},
      {"ValidateAlphaLeadingComma", kValidateLine.with("--alpha", ",0.3"), 2, "--alpha ',0.3': empty item before '0.3'"},
      {"ValidateAlphaEmptyMiddle", kValidateLine.with("--alpha", "0.3,,0.5"), 2, "empty item between '0.3' and '0.5'"},
      {"ValidateAlphaThreeItems", kValidateLine.with("--alpha", "0.3,0.3,0.3"), 2,
       "'0.3,0.3,0.3': 3 items, 1 to 2 expected"},
      {"ValidateAlpha1e30", kValidateLine.with("--alpha", "1e30"), 2,
       "--alpha '1e30': outside the supported roughness range [0.0001, 10]"},
      {"ValidateAlphaTooSmall", kValidateLine.with("--alpha", "1e-5"), 2, "'1e-5': outside the supported roughness range"},
      {"ValidateAlphaNegativeZero", kValidateLine.with("--alpha", "-0"), 2, "'-0': outside the supported roughness range"},
      {"ValidateAnisotropy", kValidateLine.with("--alpha", "1e-4,1"), 2,
       "--alpha 0.0001,1: anisotropy 1:1e+04 beyond the supported 1:1000"},
      {"ValidateAlphaHexFloat", kValidateLine.with("--alpha", "0x1p-2"), 2, "--alpha '0x1p-2': not a number"},
      {"ValidateAlphaLeadingSpace", kValidateLine.with("--alpha", "' 0.3'"), 2,
       "--alpha ' 0.3': leading or trailing white space"},
      {"TraceAlpha1e30", kTraceLine.with("--alpha", "1e30"), 2,
       "--alpha '1e30': outside the supported roughness range [0.0001, 10]"},
      {"TraceAnisotropy", kTraceLine.with("--alpha", "1e-4,1"), 2, "anisotropy 1:1e+04 beyond the supported 1:1000"},
      {"TraceAlphaNan", kTraceLine.with("--alpha", "0.3,nan"), 2, "--alpha '0.3,nan' item 2: 'nan': not finite"},
      {"BuildAlphaTrailingComma", kBuildLine.with("--alpha", "0.5,"), 2, "--alpha '0.5,': empty item after '0.5'"},
      {"BuildAlpha1e30", kBuildLine.with("--alpha", "1e30"), 2, "'1e30': outside the supported roughness range"},
      {"StatsAlphaTrailingComma", kStatsLine.with("--alpha", "0.3,"), 2, "--alpha '0.3,': empty item after '0.3'", surface},
      {"StatsAlpha1e30", kStatsLine.with("--alpha", "1e30"), 2, "'1e30': outside the supported roughness range", surface},
      {"TableAlphasEmptyItem", kTableLine.with("--alphas", "0.1,,0.5"), 2,
       "--alphas '0.1,,0.5': empty item between '0.1' and '0.5'"},
      {"TableAssembliesTrailingComma", kTableLine.with("--assemblies", "smith,"), 2,
       "--assemblies 'smith,': empty item after 'smith'"},
      {"TableThetasTrailingComma", kTableLine.with("--thetas", "30,"), 2, "--thetas '30,': empty item after '30'"},
      // ---- reals: NaN, inf, hex floats, white space, empty, huge exponents ----
      {"ValidateThetaNan", kValidateLine.with("--theta", "nan"), 2, "--theta 'nan': not finite"},
      {"ValidateThetaInf", kValidateLine.with("--theta", "inf"), 2, "--theta 'inf': not finite"},
      {"ValidateThetaHugeExponent", kValidateLine.with("--theta", "1e999999"), 2,
       "--theta '1e999999': out of the range of a double"},
      {"ValidateThetaHex", kValidateLine.with("--theta", "0x1E"), 2, "--theta '0x1E': not a number"},
      {"ValidateThetaTrailingSpace", kValidateLine.with("--theta", "'30 '"), 2,
       "--theta '30 ': leading or trailing white space"},
      {"ValidateThetaEmpty", kValidateLine.with("--theta", "''"), 2, "--theta '': empty"},
      {"ValidatePhiUnderflow", kValidateLine.with("--phi", "1e-400"), 2, "--phi '1e-400': out of the range of a double"},
      {"ValidatePhiComma", kValidateLine.with("--phi", "1,5"), 2, "--phi '1,5': not a number"},
      {"ValidateSignificanceNan", kValidateLine.with("--significance", "nan"), 2, "--significance 'nan': not finite"},
      {"ValidateBinaryBytes", kValidateLine.with("--phi", "\"$(printf '1\\001\\033[2J')\""), 2,
       "--phi '1\\x01\\x1B[2J': not a number"},
      {"TraceThetaNan", kTraceLine.with("--theta", "nan"), 2, "--theta 'nan': not finite"},
      {"TracePhiInf", kTraceLine.with("--phi", "-inf"), 2, "--phi '-inf': not finite"},
      {"TraceThreadsNegative", kTraceLine.with("--threads", "-1"), 2, "--threads '-1': too small: an integer in [0, 4096]"},
      {"TraceThreadsHuge", kTraceLine.with("--threads", "99999999999"), 2, "--threads '99999999999': too large"},
      {"TraceMeshLevelTen", kTraceLine.with("--mesh-level", "10"), 2, "--mesh-level '10': too large: an integer in [0, 9]"},
      {"TraceTileSizeNan", kTraceSurfaceLine.with("--tile-size", "nan"), 2, "--tile-size 'nan': not finite", surface},
      {"MaskingThetaLightNan", kMaskingLine.with("--theta-l", "nan"), 2, "--theta-l 'nan': not finite", surface},
      {"MaskingConeInf", kMaskingLine.with("--cone", "inf"), 2, "--cone 'inf': not finite", surface},
      {"MaskingGrazingShareHex", kMaskingLine.with("--grazing-share", "0x0.1p0"), 2,
       "--grazing-share '0x0.1p0': not a number", surface},
      {"MaskingTileSizeUnderflow", kMaskingLine.with("--tile-size", "1e-400"), 2, "--tile-size '1e-400': out of the range",
       surface},
      {"MaskingBinsZero", kMaskingLine.with("--bins", "0"), 2, "--bins '0': too small: an integer in [1, 1000]", surface},
      {"MaskingBinsHuge", kMaskingLine.with("--bins", "1e9"), 2, "--bins '1e9': too large", surface},
      {"MaskingThreadsNegative", kMaskingLine.with("--threads", "-1"), 2, "--threads '-1': too small", surface},
      {"TableResHuge", kTableLine.with("--res", "1e9"), 2, "--res '1e9': too large: an integer in [16, 8192]"},
      {"TableResHex", kTableLine.with("--res", "0x400"), 2, "--res '0x400': not an integer"},
      {"TablePhiNan", kTableLine.with("--table-phi", "nan"), 2, "--table-phi 'nan': not finite"},
      {"BuildResHuge", kBuildLine.with("--res", "99999999999"), 2,
       "--res '99999999999': too large: an integer in [16, 8192]"},
      {"BuildResNotPowerOfTwo", kBuildLine.with("--res", "100"), 2, "--res '100': not a power of two (one in [16, 8192]"},
      {"TableResNotPowerOfTwo", kTableLine.with("--res", "17"), 2, "--res '17': not a power of two"},
      {"StatsAlphaEmpty", kStatsLine.with("--alpha", "''"), 2, "--alpha: an empty value", surface},
      {"BuildTileSizeZero", kBuildLine.with("--tile-size", "0"), 2, "--tile-size '0': outside (0, inf]"},
      {"BuildCorrCellsNegative", kBuildLine.with("--corr-cells", "-1"), 2, "--corr-cells '-1': outside [0, inf]"},
      {"BuildIterationsHuge", kBuildLine.with("--iterations", "1e3"), 2,
       "--iterations '1e3': too large: an integer in [0, 100]"},
      {"BuildMeshCropNegative", kBuildLine.with("--mesh-crop", "-1"), 2, "--mesh-crop '-1': too small"},
      {"BuildTileSizeNan", kBuildLine.with("--tile-size", "nan"), 2, "--tile-size 'nan': not finite"},
      {"BuildCorrCellsInf", kBuildLine.with("--corr-cells", "inf"), 2, "--corr-cells 'inf': not finite"},
      {"StatsTileSizeNan", kStatsLine.with("--tile-size", "nan"), 2, "--tile-size 'nan': not finite", surface},
      {"StatsCorrCellsHugeExponent", kStatsLine.with("--corr-cells", "1e999"), 2, "--corr-cells '1e999': out of the range",
       surface},
      {"StatsMeshCropHuge", kStatsLine.with("--mesh-crop", "99999999999"), 2, "--mesh-crop '99999999999': too large",
       surface},
      {"ImportTileSizeHex", kImportLine.with("--tile-size", "0x1p0"), 2, "--tile-size '0x1p0': not a number", surface},
      {"ImportTileSizeEmpty", kImportLine.with("--tile-size", "''"), 2, "--tile-size '': empty", surface},
      {"ImportTileSizeInf", kImportLine.with("--tile-size", "inf"), 2, "--tile-size 'inf': not finite", surface},
      {"StabilityRandomUHuge", kStabilityLine.with("--random-u", "1e7"), 2,
       "--random-u '1e7': too large: an integer in [0, 1000000 (1e6)]"},
      {"StabilityRandomUNegative", kStabilityLine.with("--random-u", "-1"), 2, "--random-u '-1': too small"},
      {"StabilityRandomUFraction", kStabilityLine.with("--random-u", "2.5"), 2, "--random-u '2.5': not an integer"},
      // ---- albedo: the same rules ----
      {"AlbedoRaysHuge", kAlbedoLine.with("--rays", "1e13"), 2, "--rays '1e13': too large: " + max_rays},
      {"AlbedoSeed2To64", kAlbedoLine.with("--seed", "18446744073709551616"), 2, "'18446744073709551616': too large"},
      {"AlbedoThreadsHuge", kAlbedoLine.with("--threads", "99999999999"), 2, "--threads '99999999999': too large"},
      {"AlbedoMusHex", kAlbedoLine.with("--mus", "0x10"), 2, "--mus '0x10': not an integer"},
      {"AlbedoMaxOrderHuge", kAlbedoLine.with("--max-order", "1e9"), 2, "--max-order '1e9': too large"},
      {"AlbedoAlphasTrailingComma", kAlbedoLine.with("--alphas", "0.5,"), 2, "--alphas '0.5,': empty item after '0.5'"},
      {"AlbedoAlphasHexFloat", kAlbedoLine.with("--alphas", "0x1p-1"), 2, "'0x1p-1': not a number"},
      {"AlbedoResHex", kAlbedoSurfaceLine.with("--res", "0x400"), 2, "--res '0x400': not an integer"},
      {"AlbedoToleranceNan", kAlbedoAnalyticLine.with("--tolerance", "nan"), 2, "--tolerance 'nan': not finite"},
      {"AlbedoToleranceTooLarge", kAlbedoAnalyticLine.with("--tolerance", "0.1"), 2, "--tolerance '0.1': outside"},
  };
}

class BadNumbers : public ::testing::TestWithParam<BadInputCase> {};

TEST_P(BadNumbers, ExitTwoNamingTheValueNothingWritten) { microsim::test::expect_bad_input(GetParam(), "bad_numbers"); }

INSTANTIATE_TEST_SUITE_P(Cli, BadNumbers, ::testing::ValuesIn(numbers_cases()),
                         [](const ::testing::TestParamInfo<BadInputCase>& info) { return info.param.name; });

// A long token is quoted as a short excerpt with its length: a command line takes at most
// 128 KiB per argument, so 100000 digits stand for the 10 MB token of the issue (the parser's own test
// quotes 10 MB).
TEST(BadNumbersCli, LongTokenIsQuotedAsAShortExcerpt) {
  const fs::path dir = microsim::test::scratch_dir("bad_numbers", "long_token");
  const microsim::test::CliRun r = microsim::test::run_cli(dir, kTraceLine.with("--rays", std::string(100000, '9')));
  EXPECT_EQ(r.exit_code, 2) << r.err.substr(0, 500);
  EXPECT_NE(r.err.find("--rays '" + std::string(microsim::kExcerptBytes, '9') + "...' (100000 bytes): too large"),
            std::string::npos)
      << r.err.substr(0, 500);
  EXPECT_LT(r.err.size(), 400u) << r.err.substr(0, 500);
  EXPECT_EQ(microsim::test::file_count(dir), 0u);
  fs::remove_all(dir);
}

// The maxima are documented where the options are: each command's --help states them.
TEST(BadNumbersCli, HelpStatesTheMaxima) {
  const fs::path dir = microsim::test::scratch_dir("bad_numbers", "help");
  struct Help {
    std::string command;
    std::vector<std::string> needles;
  };
  for (const Help& h : {Help{"validate --help", {"--samples INT", "(at most 1e12)", "odd, 3..501", "[1e-4, 10]"}},
                        Help{"trace vndf --help", {"rays to trace (at most 1e12)", "odd, 1..501", "(at most 4096)"}},
                        Help{"trace masking --help", {"surface points per view (at most 1e12)", "1..1000"}}}) {
    const microsim::test::CliRun r = microsim::test::run_cli(dir, h.command);
    EXPECT_EQ(r.exit_code, 0) << h.command;
    for (const std::string& n : h.needles) EXPECT_NE(r.out.find(n), std::string::npos) << h.command << ": " << n;
  }
  fs::remove_all(dir);
}

// Defect 2 at its root: no binning has more rows than kMaxBinningRows, so its 2 rows^2 bin indices fit
// an int (rows 46341 overflowed them).
TEST(BadNumbersBinning, RowsBeyondTheMaximumAreRejected) {
  using microsim::DirectionBinning;
  EXPECT_EQ(DirectionBinning::sphere(microsim::kMaxBinningRows).size(), 2 * 501 * 501);
  for (int rows : {503, 4095, 16383, 46341, 1048577, 2147483647}) {
    EXPECT_THROW(DirectionBinning::sphere(rows), std::invalid_argument) << rows;
    EXPECT_THROW(DirectionBinning::lobe(microsim::GGX<double>(0.3, 0.3), microsim::Vec3<double>(0, 0, 1),
                                        microsim::SampleDomain::microfacet_normal, rows),
                 std::invalid_argument)
        << rows;
  }
  const auto description = [](const nlohmann::json& rows) {
    nlohmann::json d;
    d["kind"] = "sphere";
    d["rows"] = rows;
    return d;
  };
  EXPECT_NO_THROW(DirectionBinning::from_description(description(31)));
  for (const nlohmann::json& rows : {nlohmann::json(46341), nlohmann::json(4294967297LL), nlohmann::json(31.5),
                                     nlohmann::json(-1), nlohmann::json(18446744073709551615ULL)})
    EXPECT_THROW(DirectionBinning::from_description(description(rows)), std::invalid_argument) << rows.dump();
}

}  // namespace

}  // namespace test_bad_inputs_numbers
