// Bad-input table for the file readers, end to end: broken histogram EXRs given to `plot` and
// `validate --against`, an EXR whose header claims 46340 x 46340 pixels given to `surface stats`,
// `trace vndf --surface` and `trace masking --surface`, heightmap attributes that are not numbers, an .npy
// header without its newline, a text file with a 10 MB token or binary bytes to `validate --from`. Each
// must exit 2 naming the attribute and the bad value in a short message, and write nothing.
#include "cli_helpers.h"

#include "microgeom/exr_io.h"
#include "microgeom/heightfield.h"

#include <cstring>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_bad_inputs_files {

namespace {

using microsim::test::BadInputCase;
namespace fs = std::filesystem;

constexpr std::size_t kShortMessage = 500;  // bytes of stderr

// A small valid histogram written by `trace vndf` once per build of the tests (3 rows: 2 binnings of 18 bins).
const fs::path& histogram_fixture() {
  static const fs::path path = microsim::test::shared_fixture_dir("bad_files", [](const fs::path& dir) {
    const auto r = microsim::test::run_cli(dir, "trace vndf --alpha 0.3 --theta 30 --rays 5000 --rows 3 --out h.exr");
    EXPECT_EQ(r.exit_code, 0) << r.err;
  }) / "h.exr";
  return path;
}

// Writes the fixture histogram into DIR/h.exr with one string attribute replaced by `value`, or by
// `repeat` copies of it (made only when the case runs: the table itself stays small in memory).
std::function<void(const fs::path&)> histogram_with(const std::string& key, const std::string& value,
                                                    std::size_t repeat = 1) {
  return [=](const fs::path& dir) {
    microgeom::ExrImage img = microgeom::read_exr(histogram_fixture());
    std::string& v = img.attributes[key] = "";
    for (std::size_t i = 0; i < repeat; ++i) v += value;
    microgeom::write_exr(dir / "h.exr", img);
  };
}

// Writes an 8 x 8 heightmap DIR/hf.exr with the given string attributes (microsim.tile_size = 1 unless
// given), its header claiming width x height pixels when those are non-zero.
std::function<void(const fs::path&)> heightmap_with(std::map<std::string, std::string> attributes, int width = 0,
                                                    int height = 0) {
  return [=](const fs::path& dir) {
    microgeom::ExrImage img;
    img.width = img.height = 8;
    auto& h = img.add_channel("height");
    for (std::size_t i = 0; i < h.data.size(); ++i) h.data[i] = 0.01f * float(i % 5);
    img.attributes = attributes;
    img.attributes.emplace("microsim.tile_size", "1");
    microgeom::write_exr(dir / "hf.exr", img);
    if (width == 0) return;
    std::string bytes = microsim::test::slurp(dir / "hf.exr");
    for (const char* name : {"dataWindow", "displayWindow"}) {
      const std::string key = std::string(name) + '\0' + "box2i" + '\0';
      const std::int32_t box[4] = {0, 0, width - 1, height - 1};
      std::memcpy(bytes.data() + bytes.find(key) + key.size() + 4, box, sizeof box);
    }
    std::ofstream(dir / "hf.exr", std::ios::binary) << bytes;
  };
}

// Writes DIR/NAME = head, `repeat` copies of `body`, tail (made only when the case runs).
std::function<void(const fs::path&)> file_with(const std::string& name, std::string head, std::string body = "",
                                               std::size_t repeat = 0, std::string tail = "") {
  return [=](const fs::path& dir) {
    std::ofstream out(dir / name, std::ios::binary);
    out << head;
    for (std::size_t i = 0; i < repeat; ++i) out << body;
    out << tail;
  };
}

std::string npy_without_newline() {
  std::string dict = "{'descr': '<f8', 'fortran_order': False, 'shape': (1, 3), }";
  dict.append(128 - 10 - dict.size(), ' ');  // padding, but the last byte is a blank, not '\n'
  std::string bytes = std::string("\x93NUMPY\x01", 7) + '\0' + char(dict.size()) + '\0' + dict;
  const double row[3] = {0, 0, 1};
  return bytes.append(reinterpret_cast<const char*>(row), sizeof row);
}

std::string binary_text() {
  std::string s = "0 0 1\n0 0 ";
  for (int i = 0; i < 256; ++i) s += char(i == '\n' ? 1 : i);
  return s + "\n";
}

const std::string kValidateSampler = "validate --sampler heitz2018 --alpha 0.3 --theta 30 --samples 20000 ";
const std::string kFrom = "validate --alpha 0.3 --theta 30 --from ";

std::vector<BadInputCase> files_cases() {
  const std::string huge_claim = "46340 x 46340 pixels x 1 channel = 8.0 GiB of float data, over the limit of 2.0 GiB";
  return {
      {"plot_hits_negative", "plot h.exr --out f.svg", 2, "attribute hits = '-1' is not a count",
       histogram_with("hits", "-1")},
      {"plot_hits_over_rays", "plot h.exr --out f.svg", 2, "attribute hits = 5001 is more than rays = 5000",
       histogram_with("hits", "5001")},
      {"plot_rays_overflow", "plot h.exr --out f.svg", 2, "attribute rays = '18446744073709551616'",
       histogram_with("rays", "18446744073709551616")},
      {"plot_binnings_twice", "plot h.exr --out f.svg", 2,
       "attribute binnings = 'sphere,sphere' names binning 'sphere' twice", histogram_with("binnings", "sphere,sphere")},
      {"plot_binnings_unknown", "plot h.exr --out f.svg", 2, "unknown binning 'cube'",
       histogram_with("binnings", "sphere,cube")},
      {"plot_binning_rows", "plot h.exr --out f.svg", 2, "attribute binning.sphere",
       histogram_with("binning.sphere", R"({"kind":"sphere","rows":-3})")},
      {"plot_huge_value", "plot h.exr --out f.svg", 2, "attribute partial = 'yyyy",
       histogram_with("partial", "y", 10 << 20)},
      {"against_hits_negative", kValidateSampler + "--against h.exr", 2, "attribute hits = '-1'",
       histogram_with("hits", "-1")},
      {"against_binnings_twice", kValidateSampler + "--against h.exr", 2, "names binning 'sphere' twice",
       histogram_with("binnings", "sphere,sphere")},
      {"against_alpha_trailing_comma", kValidateSampler + "--against h.exr", 2, "attribute alpha = '0.3,'",
       histogram_with("alpha", "0.3,")},
      {"stats_huge_header", "surface stats hf.exr", 2, huge_claim, heightmap_with({}, 46340, 46340)},
      {"trace_vndf_huge_header", "trace vndf --surface hf.exr --theta 30 --rays 1000 --out o.exr", 2, huge_claim,
       heightmap_with({}, 46340, 46340)},
      {"trace_masking_huge_header", "trace masking --surface hf.exr --theta 30 --samples 1000", 2, huge_claim,
       heightmap_with({}, 46340, 46340)},
      {"stats_tile_size_nan", "surface stats hf.exr", 2, "attribute microsim.tile_size = 'nan'",
       heightmap_with({{"microsim.tile_size", "nan"}})},
      {"stats_tile_size_junk", "surface stats hf.exr", 2, "attribute microsim.tile_size = '1x'",
       heightmap_with({{"microsim.tile_size", "1x"}})},
      // A malformed roughness in the metadata was silently replaced by a fitted one.
      {"stats_alpha_junk", "surface stats hf.exr", 2, "attribute microsim.alpha_x = '0.5x'",
       heightmap_with({{"microsim.alpha_x", "0.5x"}, {"microsim.alpha_y", "0.5"}})},
      {"masking_alpha_trailing_comma", "trace masking --surface hf.exr --theta 30 --samples 1000", 2,
       "attribute microsim.alpha_x = '0.5,'", heightmap_with({{"microsim.alpha_x", "0.5,"}, {"microsim.alpha_y", "0.5"}})},
      {"from_npy_without_newline", kFrom + "n.npy", 2, "NPY header does not end with a newline",
       file_with("n.npy", npy_without_newline())},
      {"from_text_huge_token", kFrom + "t.txt", 2, "line 1: value '" + std::string(40, '1') + "...' (",
       file_with("t.txt", "0 0 ", "1", 10 << 20, "\n")},
      {"from_text_binary", kFrom + "b.txt", 2, "line 2: malformed line: '\\x00\\x01\\x02", file_with("b.txt", binary_text())},
  };
}

class BadInputsFiles : public ::testing::TestWithParam<BadInputCase> {};

TEST_P(BadInputsFiles, ExitTwoNamingTheValueInAShortMessageAndWritingNothing) {
  const BadInputCase& c = GetParam();
  microsim::test::expect_bad_input(c, "bad_files");
  // The same run once more, for the length of its message (expect_bad_input checks the rest).
  const fs::path dir = microsim::test::scratch_dir("bad_files_len", c.name);
  if (c.prepare) c.prepare(dir);
  const microsim::test::CliRun r = microsim::test::run_cli(dir, c.args);
  EXPECT_LT(r.err.size(), kShortMessage) << r.err.substr(0, 600);
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Readers, BadInputsFiles, ::testing::ValuesIn(files_cases()),
                         [](const auto& info) { return info.param.name; });

}  // namespace

}  // namespace test_bad_inputs_files
