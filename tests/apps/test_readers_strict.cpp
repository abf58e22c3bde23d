// Strict readers: attribute parsing (src/core/strict_parse.h), the histogram EXR reader's
// validation of every attribute and channel, the EXR reader's size checks before allocating, heightmap
// and analytic-reference attributes, and short escaped excerpts of bad input in every message.
#include "microgeom/exr_io.h"
#include "microgeom/heightfield.h"
#include "validate/compare.h"
#include "stats/histogram_io.h"
#include "validate/sample_io.h"
#include "trace/smith_prediction.h"
#include "core/strict_parse.h"

#include "cli_helpers.h"
#include "error_message.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <string>

#include <unistd.h>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_readers_strict {

using namespace microsim;
namespace fs = std::filesystem;

namespace {

constexpr std::size_t kShortMessage = 500;  // bytes: a message that quotes an excerpt, not the input

fs::path scratch(const std::string& name) { return microsim::test::scratch_dir("strict", name); }

using microsim::test::message_of;

std::string read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void write_bytes(const fs::path& p, const std::string& bytes) { std::ofstream(p, std::ios::binary) << bytes; }

// Overwrites the dataWindow and displayWindow of an EXR file with (0, 0) - (w - 1, h - 1): the header
// then claims w x h pixels whatever the file holds.
std::string with_window(std::string exr, int w, int h) {
  for (const char* name : {"dataWindow", "displayWindow"}) {
    const std::string key = std::string(name) + '\0' + "box2i" + '\0';
    const std::size_t at = exr.find(key);
    EXPECT_NE(at, std::string::npos);
    const std::int32_t box[4] = {0, 0, w - 1, h - 1};
    std::memcpy(exr.data() + at + key.size() + 4, box, sizeof box);  // little-endian host
  }
  return exr;
}

// An 8 x 8 single-channel EXR, as write_exr writes it (ZIP: 16 scan lines per chunk).
void write_small_exr(const fs::path& path) {
  microgeom::ExrImage img;
  img.width = img.height = 8;
  img.add_channel("height");
  microgeom::write_exr(path, img);
}

}  // namespace

// ---- strict_parse.h ------------------------------------------------------------------------------------

TEST(StrictParse, CountsAreDigitsOnlyAndNeverWrap) {
  EXPECT_EQ(reader::parse_uint64("0"), 0u);
  EXPECT_EQ(reader::parse_uint64("18446744073709551615"), std::numeric_limits<std::uint64_t>::max());
  for (const char* bad : {"", "-1", "+1", " 1", "1 ", "1x", "1e3", "0x10", "18446744073709551616", "1.0"})
    EXPECT_FALSE(reader::parse_uint64(bad)) << bad;
}

TEST(StrictParse, RealsAreWholeFiniteDecimalTokens) {
  EXPECT_EQ(reader::parse_finite_double("0.3"), 0.3);
  EXPECT_EQ(reader::parse_finite_double("-2.5e-3"), -2.5e-3);
  EXPECT_EQ(reader::parse_finite_double(".5"), 0.5);
  for (const char* bad : {"", "nan", "inf", "-inf", "1e999", "0x1p3", " 1", "1 ", "+1", "1,", "0.3abc", "-"})
    EXPECT_FALSE(reader::parse_finite_double(bad)) << bad;
}

TEST(StrictParse, ExcerptsAreShortAndEscaped) {
  EXPECT_EQ(reader::quote_excerpt("abc"), "'abc'");
  EXPECT_EQ(reader::quote_excerpt(std::string("a\x01\xff'\\", 5)), "'a\\x01\\xFF\\'\\\\'");
  const std::string q = reader::quote_excerpt(std::string(10 << 20, '7'));
  EXPECT_EQ(q, "'" + std::string(reader::kExcerptBytes, '7') + "...' (10485760 bytes)");
  EXPECT_EQ(reader::split_commas("a,,b").size(), 3u);
  EXPECT_EQ(reader::split_commas("").size(), 1u);
}

// ---- the EXR reader's size checks ----------------------------------------------------------------------

TEST(ExrLimits, AHeaderClaimingMorePixelsThanTheLimitIsRejectedBeforeDecoding) {
  const fs::path dir = scratch("exr_huge");
  write_small_exr(dir / "small.exr");
  write_bytes(dir / "huge.exr", with_window(read_bytes(dir / "small.exr"), 46340, 46340));
  const auto start = std::chrono::steady_clock::now();
  const std::string m = message_of([&] { microgeom::read_exr(dir / "huge.exr"); });
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 5.0);
  EXPECT_NE(m.find("46340 x 46340 pixels x 1 channel = 8.0 GiB"), std::string::npos) << m;
  EXPECT_NE(m.find("over the limit of 2.0 GiB"), std::string::npos) << m;
  EXPECT_NE(m.find("huge.exr"), std::string::npos) << m;
  // A limit of the caller's: the same 8 x 8 file is over 100 bytes of float data.
  EXPECT_NE(message_of([&] { microgeom::read_exr(dir / "small.exr", 100); }).find("over the limit"), std::string::npos);
  // Within the limit but more chunks than the file can hold offsets for (a 2 MiB image in a tiny file).
  write_bytes(dir / "tall.exr", with_window(read_bytes(dir / "small.exr"), 1, 1 << 19));
  EXPECT_NE(message_of([&] { microgeom::read_exr(dir / "tall.exr"); }).find("chunk offsets"), std::string::npos);
  fs::remove_all(dir);
}

TEST(ExrLimits, AChunkOfScanLinesOverTheLimitIsRejectedHoweverFewLinesTheImageHas) {
  // OpenEXR decodes ZIP files 16 lines at a time, and allocates for 16 lines even in a one-line image.
  const fs::path dir = scratch("exr_wide");
  write_small_exr(dir / "small.exr");
  write_bytes(dir / "wide.exr", with_window(read_bytes(dir / "small.exr"), 4096, 1));
  const std::string m = message_of([&] { microgeom::read_exr(dir / "wide.exr", 32768); });  // 16 KiB of pixels
  EXPECT_NE(m.find("scan lines of 4096 pixels x 1 channel, which its compression decodes 16 lines at a time: "
                   "262144 bytes of float data, over the limit of 32768 bytes"), std::string::npos) << m;
  EXPECT_NE(m.find("wide.exr"), std::string::npos) << m;
  fs::remove_all(dir);
}

TEST(ExrLimits, AnAttributeDeclaringMoreBytesThanTheFileIsRejected) {
  const fs::path dir = scratch("exr_attr");
  microgeom::ExrImage img;
  img.width = img.height = 4;
  img.add_channel("height");
  img.attributes["note"] = "abcd";
  microgeom::write_exr(dir / "a.exr", img);
  std::string bytes = read_bytes(dir / "a.exr");
  const std::string key = std::string("note") + '\0' + "string" + '\0';
  const std::size_t at = bytes.find(key);
  ASSERT_NE(at, std::string::npos);
  const std::int32_t huge = 0x7ffffff0;
  std::memcpy(bytes.data() + at + key.size(), &huge, 4);
  write_bytes(dir / "b.exr", bytes);
  const std::string m = message_of([&] { microgeom::read_exr(dir / "b.exr"); });
  EXPECT_NE(m.find("attribute 'note' declares 2147483632 bytes, beyond the end of the file"), std::string::npos) << m;
  fs::remove_all(dir);
}

TEST(ExrLimits, TheMemoryReaderReadsWhatTheFileReaderReads) {
  const fs::path dir = scratch("exr_memory");
  microgeom::ExrImage img;
  img.width = 5;
  img.height = 3;
  auto& c = img.add_channel("height");
  for (std::size_t i = 0; i < c.data.size(); ++i) c.data[i] = float(i) * 0.5f;
  img.attributes["microsim.tile_size"] = "2";
  microgeom::write_exr(dir / "m.exr", img);
  const std::string bytes = read_bytes(dir / "m.exr");
  const microgeom::ExrImage a = microgeom::read_exr(dir / "m.exr");
  const microgeom::ExrImage b = microgeom::read_exr_memory(bytes, "m.exr");
  EXPECT_EQ(a.channels[0].data, b.channels[0].data);
  EXPECT_EQ(a.attributes, b.attributes);
  EXPECT_NE(message_of([&] { microgeom::read_exr_memory(std::string_view(bytes).substr(0, 100), "cut.exr"); })
                .find("cannot read EXR 'cut.exr'"),
            std::string::npos);
  fs::remove_all(dir);
}

// ---- histogram attributes ------------------------------------------------------------------------------

namespace {

// A small valid histogram as an EXR image (written and read back: what a file holds).
const microgeom::ExrImage& histogram_image() {
  static const microgeom::ExrImage image = [] {
    OracleTraceOptions o;
    o.rays = 5000;
    o.rows = 3;
    TracedHistogram h = trace_vndf_histogram(GGX<double>(0.3, 0.3), direction_from_degrees(30.0, 0.0), o);
    analyse_against_vndf(h, GGX<double>(0.3, 0.3), direction_from_degrees(30.0, 0.0));
    const fs::path dir = scratch("hist_image");
    write_histogram_exr(dir / "h.exr", h);
    microgeom::ExrImage img = microgeom::read_exr(dir / "h.exr");
    fs::remove_all(dir);
    return img;
  }();
  return image;
}

struct HistogramCase {
  std::string name;
  std::function<void(microgeom::ExrImage&)> edit;
  std::string message;
};

}  // namespace

TEST(HistogramAttributes, TheUneditedImageIsAccepted) {
  const TracedHistogram h = histogram_from_exr(histogram_image(), "h.exr");
  EXPECT_EQ(h.rays, 5000u);
  EXPECT_EQ(h.binnings.size(), 2u);
}

TEST(HistogramAttributes, EveryBadAttributeIsNamedWithItsValue) {
  const auto set = [](const std::string& key, const std::string& value) {
    return [=](microgeom::ExrImage& img) { img.attributes[key] = value; };
  };
  const std::vector<HistogramCase> cases = {
      {"hits negative", set("hits", "-1"), "attribute hits = '-1' is not a count"},
      {"hits with junk", set("hits", "12abc"), "attribute hits = '12abc'"},
      {"hits with blank", set("hits", " 12"), "attribute hits = ' 12'"},
      {"rays overflow", set("rays", "99999999999999999999999"), "attribute rays = '99999999999999999999999'"},
      {"hits over rays", set("hits", "5001"), "attribute hits = 5001 is more than rays = 5000"},
      {"partial", set("partial", "yes"), "attribute partial = 'yes'"},
      {"format", set("format", "microsim-histogram-9"), "unsupported histogram format 'microsim-histogram-9'"},
      {"binnings twice", set("binnings", "sphere,sphere"), "attribute binnings = 'sphere,sphere' names binning 'sphere' twice"},
      {"binnings unknown", set("binnings", "sphere,cube"), "unknown binning 'cube'"},
      {"binnings empty item", set("binnings", "sphere,"), "unknown binning ''"},
      {"binnings empty", set("binnings", ""), "attribute binnings is empty"},
      {"binnings binary", set("binnings", std::string("\x01\xfe", 2)), "unknown binning '\\x01\\xFE'"},
      {"binning json", set("binning.sphere", "{not json"), "attribute binning.sphere = '{not json' is not a JSON object"},
      {"binning rows", set("binning.sphere", R"({"kind":"sphere","rows":1e300})"), "rows and cols must be the image's 3 and 6"},
      {"binning kind", set("binning.sphere", R"({"kind":"lobe","rows":3})"), "does not describe a 'sphere' binning"},
      {"lobe alpha", set("binning.lobe", R"({"kind":"lobe","rows":3,"alpha":[-1,0.3],"wi":[0,0,1],"domain":"microfacet_normal"})"),
       "needs alpha (2 positive numbers)"},
      {"missing attribute", [](microgeom::ExrImage& img) { img.attributes.erase("rays"); }, "attribute 'rays' is missing"},
      {"foreign channel", [](microgeom::ExrImage& img) { img.add_channel("cube.count"); },
       "channel 'cube.count' belongs to no binning"},
      {"count disagrees", [](microgeom::ExrImage& img) { img.find("sphere.count")->data[0] += 1; },
       "channel sphere.count = "},
      {"expected nan", [](microgeom::ExrImage& img) { img.find("lobe.expected")->data[2] = std::nanf(""); },
       "channel lobe.expected has nan at bin 2"},
      {"counts over hits", set("hits", "3"), "counts add up to more than the 3 hits"},
      {"huge value", set("hits", std::string(10 << 20, '9')), "...' (10485760 bytes)"},
  };
  for (const HistogramCase& c : cases) {
    microgeom::ExrImage img = histogram_image();
    c.edit(img);
    try {
      histogram_from_exr(img, "h.exr");
      ADD_FAILURE() << c.name << ": accepted";
    } catch (const HistogramIoError& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find(c.message), std::string::npos) << c.name << ": " << m;
      EXPECT_NE(m.find("'h.exr'"), std::string::npos) << c.name << ": " << m;
      EXPECT_LT(m.size(), kShortMessage) << c.name << ": " << m.substr(0, 300);
    }
  }
}

TEST(HistogramAttributes, AlphaAndViewAreWholeFiniteNumbers) {
  TracedHistogram h = histogram_from_exr(histogram_image(), "h.exr");
  for (const char* bad : {"0.3,", ",0.3", "0.3", " 0.3,0.3", "nan,0.3", "1e999,0.3", "0.3,0.3,0.3", "0.3;0.3"}) {
    h.attributes["alpha"] = bad;
    const std::string m = message_of([&] { histogram_ggx(h); });
    EXPECT_NE(m.find("attribute alpha = '" + std::string(bad) + "' is not 2 finite numbers"), std::string::npos) << m;
  }
  h.attributes["wi"] = "0,0,1x";
  EXPECT_NE(message_of([&] { histogram_wi(h); }).find("attribute wi = '0,0,1x'"), std::string::npos);
}

// ---- heightmap and analytic-reference attributes ---------------------------------------------------------

TEST(HeightmapAttributes, TileSizeIsAWholeFinitePositiveNumber) {
  microgeom::ExrImage img;
  img.width = img.height = 4;
  img.add_channel("height");
  for (const char* bad : {"1x", "nan", "inf", " 1", "1e999", "-1", "0", "0x1p0", ""}) {
    img.attributes["microsim.tile_size"] = bad;
    const std::string m = message_of([&] { microgeom::heightfield_from_exr(img, "t.exr"); });
    EXPECT_NE(m.find("attribute microsim.tile_size = '" + std::string(bad) + "' is not a finite number > 0"),
              std::string::npos)
        << m;
  }
  img.attributes["microsim.tile_size"] = "2.5";
  EXPECT_EQ(microgeom::heightfield_from_exr(img, "t.exr").tile_size(), 2.5);
  // Heights so steep for the tile that a slope overflows.
  img.channels[0].data[5] = 3e38f;
  img.attributes["microsim.tile_size"] = "1e-300";
  EXPECT_NE(message_of([&] { microgeom::heightfield_from_exr(img, "t.exr"); }).find("the slopes overflow"),
            std::string::npos);
}

TEST(HeightmapAttributes, MalformedStatedRoughnessIsAnErrorNotAFit) {
  microgeom::Heightfield f(8, 1.0, std::vector<float>(64, 0.0f));
  f.metadata["alpha_x"] = "0.5";
  f.metadata["alpha_y"] = "0.5";
  std::string source;
  EXPECT_EQ(analytic_reference(f, &source).alpha_x(), 0.5);
  EXPECT_EQ(source, "metadata");
  for (const char* bad : {"0.5,", "nan", "0.5abc", "-0.5", "1e999", " 0.5"}) {
    f.metadata["alpha_y"] = bad;
    const std::string m = message_of([&] { analytic_reference(f); });
    EXPECT_NE(m.find("microsim.alpha_y = '" + std::string(bad) + "'"), std::string::npos) << m;
  }
  f.metadata["alpha_y"] = "0.5";
  f.metadata["reference_ndf"] = "cook";
  EXPECT_NE(message_of([&] { analytic_reference(f); }).find("microsim.reference_ndf = 'cook'"), std::string::npos);
}

// ---- sample files ----------------------------------------------------------------------------------------

TEST(SampleMessages, TokensAreQuotedAsShortEscapedExcerpts) {
  const std::string huge = "0 0 " + std::string(10 << 20, '1') + "\n";
  std::string m = message_of([&] { parse_direction_samples(huge, "t.txt"); });
  EXPECT_NE(m.find("line 1: value '1111"), std::string::npos) << m.substr(0, 300);
  EXPECT_NE(m.find("...' (10485760 bytes)"), std::string::npos) << m.substr(0, 300);
  EXPECT_LT(m.size(), kShortMessage);
  std::string binary = "0 0 ";
  for (int i = 0; i < (5 << 20); ++i) binary += "x\x01";
  m = message_of([&] { parse_direction_samples(binary + "\n", "t.txt"); });
  EXPECT_NE(m.find("'x\\x01x\\x01"), std::string::npos) << m.substr(0, 300);
  EXPECT_LT(m.size(), kShortMessage);
  for (char c : m) EXPECT_TRUE(c >= 0x20 && c < 0x7f) << int(c);
}

TEST(SampleMessages, NpyHeaderNamesAreQuotedAsShortExcerpts) {
  const auto npy = [](const std::string& dict) {
    std::string header = dict + "\n";
    std::string out = "\x93NUMPY\x01";
    out.push_back('\0');
    out.push_back(char(header.size() & 0xff));
    out.push_back(char(header.size() >> 8));
    return out + header;
  };
  std::string m = message_of([&] { parse_direction_samples(npy("{'" + std::string(60000, 'k') + "': 1}"), "k.npy"); });
  EXPECT_NE(m.find("unexpected key 'kkkk"), std::string::npos) << m.substr(0, 300);
  EXPECT_NE(m.find("...' (60000 bytes)"), std::string::npos) << m.substr(0, 300);
  m = message_of([&] {
    parse_direction_samples(npy("{'descr': '\x01\xfe', 'fortran_order': False, 'shape': (1, 3), }"), "d.npy");
  });
  EXPECT_NE(m.find("unsupported NPY dtype '\\x01\\xFE'"), std::string::npos) << m;
  std::string shape = "(1";
  for (int i = 0; i < 20000; ++i) shape += ", 1";
  m = message_of([&] {
    parse_direction_samples(npy("{'descr': '<f8', 'fortran_order': False, 'shape': " + shape + "), }"), "s.npy");
  });
  EXPECT_NE(m.find("20001 dimensions"), std::string::npos) << m.substr(0, 300);
  EXPECT_LT(m.size(), kShortMessage);
}

TEST(SampleMessages, NpyHeaderWithoutNewlineIsRejected) {
  std::string dict = "{'descr': '<f8', 'fortran_order': False, 'shape': (1, 3), }";
  dict.append(128 - 10 - dict.size(), ' ');  // padded, but ending in a blank instead of '\n'
  std::string bytes = "\x93NUMPY\x01";
  bytes.push_back('\0');
  bytes.push_back(char(dict.size()));
  bytes.push_back('\0');
  bytes += dict;
  const double row[3] = {0, 0, 1};
  bytes.append(reinterpret_cast<const char*>(row), sizeof row);
  const std::string m = message_of([&] { parse_direction_samples(bytes, "n.npy"); });
  EXPECT_NE(m.find("NPY header does not end with a newline '\\n' (its last byte is ' ')"), std::string::npos) << m;
  bytes[9 + dict.size()] = '\n';
  EXPECT_EQ(parse_direction_samples(bytes, "n.npy").size(), 1u);
}

}  // namespace test_readers_strict
