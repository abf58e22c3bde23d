// Scatter files (stats/scatter_io.h): a histogram or an expectation written and read back is == the one
// written (the exact sums' bits), so is a shard's JSON part, the merge of shards read from parts is the single
// run bit for bit, and
// the strict reader refuses every malformed attribute and channel with a message naming it.
#include "stats/scatter_io.h"
#include "stats/scatter_merge.h"

#include "cli_helpers.h"
#include "scatter_samples.h"

#include "microgeom/exr_io.h"
#include "microgeom/heightfield.h"
#include "stats/histogram_io.h"

#include <fmt/core.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <bit>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <string>

namespace microsim {
namespace {

namespace fs = std::filesystem;

ScatterOptions small_run(std::uint64_t paths = 20000, int rows = 4) {
  ScatterOptions o;
  o.wi = Vec3<double>(std::sin(0.6), 0, std::cos(0.6));
  o.material = Material::conductor({{0.2, 3.9}, {0.5, 2.4}, {1.4, 1.8}}, {"r", "g", "b"});
  o.paths = paths;
  o.rows = rows;
  o.seed = 11;
  return o;
}

ScatterExpectation small_expectation() {
  ScatterExpectation e;
  const DirectionBinning b = DirectionBinning::hemispheres(3);
  e.binning_id = b.describe().dump();
  for (int i = 0; i < b.size(); ++i) e.reflection_bins.push_back(i < b.size() / 2);
  e.channel_names = {"c0", "c1"};
  for (int c = 0; c < 2; ++c) {
    std::vector<double> lobe;
    for (int i = 0; i < b.size(); ++i) lobe.push_back(i < b.size() / 2 ? std::exp(-0.1 * i - c) / 3.0 : 0.0);
    e.order1.push_back(lobe);
    e.error_estimate.push_back(1e-9 * (c + 1));
  }
  e.producer = "test";
  e.measurement = "expected";
  return e;
}

TEST(ScatterIo, HistogramRoundTripsBitForBit) {
  const fs::path dir = test::scratch_dir("scatter_io", "round_trip");
  ScatterHistogram h = test::synthetic_scatter(small_run(), 0.4);
  const double w[3] = {0.25, 0.5, 0.125};
  h.add_unfinished(w);
  h.add_lost(w);
  h.add_escaped_unbinned(3, w);
  h.partial = true;
  write_scatter_exr(dir / "h.exr", h, {{"material", "gold-like"}});
  const ScatterFile f = read_scatter_exr(dir / "h.exr");
  ASSERT_EQ(f.kind, ScatterFileKind::histogram);
  EXPECT_TRUE(f.histogram == h);
  EXPECT_EQ(f.notes.at("material"), "gold-like");
  // Written again from what was read: the same file content.
  write_scatter_exr(dir / "again.exr", f.histogram, f.notes);
  EXPECT_EQ(test::slurp(dir / "again.exr"), test::slurp(dir / "h.exr"));
  fs::remove_all(dir);
}

TEST(ScatterIo, ExpectationRoundTripsBitForBit) {
  const fs::path dir = test::scratch_dir("scatter_io", "expectation");
  const ScatterExpectation e = small_expectation();
  write_scatter_exr(dir / "e.exr", e);
  const ScatterFile f = read_scatter_exr(dir / "e.exr");
  ASSERT_EQ(f.kind, ScatterFileKind::expectation);
  EXPECT_TRUE(f.expectation == e);
  fs::remove_all(dir);
}

TEST(ScatterIo, MergeOfShardsReadFromFilesIsTheSingleRun) {
  const fs::path dir = test::scratch_dir("scatter_io", "merge");
  ScatterOptions o = small_run(5 * kPathsPerBlock + 123);
  const ScatterHistogram whole = test::synthetic_scatter(o, 0.3);
  std::vector<ScatterHistogram> parts;
  for (int k = 3; k >= 1; --k) {  // any order
    o.blocks = shard_range(whole.provenance.total_blocks, std::uint64_t(k), 3);
    const fs::path p = dir / fmt::format("part{}.json", k);  // as `scatter --shard K/N --out PART.json` writes it
    const ScatterHistogram shard = test::synthetic_scatter(o, 0.3);
    std::ofstream(p) << scatter_part_json(shard, {{"model", "synthetic"}}).dump();
    std::ifstream in(p);
    const ScatterPart read = read_scatter_part(nlohmann::json::parse(in));
    EXPECT_TRUE(read.histogram == shard);
    EXPECT_EQ(read.notes.at("model"), "synthetic");
    parts.push_back(read.histogram);
  }
  EXPECT_TRUE(merge_scatter_parts(parts) == whole);
  // A malformed part is named by the member that is wrong.
  nlohmann::json bad = scatter_part_json(parts[0], {});
  bad["sums"]["channels"][0]["orders"][1]["w"][2] = {-1, 0};
  try {
    read_scatter_part(bad);
    ADD_FAILURE() << "a negative sum was read";
  } catch (const HistogramMergeError& e) {
    EXPECT_NE(std::string(e.what()).find("not a scatter part: sums/channels/0/orders/1/w/2"), std::string::npos) << e.what();
  }
  // A gap and an overlap are named.
  try {
    merge_scatter_parts({parts[0], parts[2]});
    ADD_FAILURE() << "a gap was merged";
  } catch (const HistogramMergeError& e) {
    EXPECT_NE(std::string(e.what()).find("missing"), std::string::npos) << e.what();
  }
  try {
    merge_scatter_parts({parts[0], parts[1], parts[2], parts[1]});
    ADD_FAILURE() << "an overlap was merged";
  } catch (const HistogramMergeError& e) {
    EXPECT_NE(std::string(e.what()).find("more than one part"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

TEST(ScatterIo, SummaryBalancesTheEnergyOfAMirrorRun) {
  ScatterOptions o = small_run();
  o.material = Material::mirror();
  const ScatterHistogram h = test::synthetic_scatter(o, 0.5);
  const nlohmann::json j = scatter_summary_json(h);
  const nlohmann::json& c = j["channels"][0];
  // Every path of the synthetic mirror run carries weight 1 out (orders 1 and 2).
  EXPECT_NEAR(c["energy"]["value"].get<double>(), 1.0, 1e-12);
  EXPECT_NEAR(c["albedo"]["total"]["both"]["value"].get<double>(), 1.0, 1e-12);
  EXPECT_EQ(c["albedo"]["total"]["lower"]["value"].get<double>(), 0.0);
  EXPECT_GT(c["albedo"]["order1"]["both"]["standard_error"].get<double>(), 0.0);
  EXPECT_EQ(j["paths"].get<std::uint64_t>(), o.paths);
}

// ---- the strict reader -----------------------------------------------------------------------------------

struct HostileCase {
  std::string name;
  bool expectation = false;  // mutate an expectation file (else a histogram)
  std::function<void(microgeom::ExrImage&)> mutate;
  std::string message;
};

void PrintTo(const HostileCase& c, std::ostream* os) { *os << c.name; }

microgeom::ExrImage written_image(bool expectation) {
  const fs::path dir = test::scratch_dir("scatter_io", expectation ? "hostile_e" : "hostile_h");
  if (expectation) write_scatter_exr(dir / "f.exr", small_expectation());
  else write_scatter_exr(dir / "f.exr", test::synthetic_scatter(small_run(3000, 2), 0.5));
  microgeom::ExrImage image = microgeom::read_exr(dir / "f.exr");
  fs::remove_all(dir);
  return image;
}

void set_attr(microgeom::ExrImage& im, const std::string& key, const std::string& value) { im.attributes[key] = value; }
std::function<void(microgeom::ExrImage&)> attr_is(const std::string& key, const std::string& value) {
  return [=](microgeom::ExrImage& im) { set_attr(im, key, value); };
}
std::function<void(microgeom::ExrImage&)> pixel_is(const std::string& channel, std::size_t i, float v) {
  return [=](microgeom::ExrImage& im) { im.find(channel)->data.at(i) = v; };
}
std::function<void(microgeom::ExrImage&)> expected_bits(std::size_t i, double v) {
  return [=](microgeom::ExrImage& im) {
    const std::uint64_t x = std::bit_cast<std::uint64_t>(v);
    im.find("c0.order1.expected.bits0")->data.at(i) = float(x & 0xffffff);
    im.find("c0.order1.expected.bits1")->data.at(i) = float((x >> 24) & 0xffffff);
    im.find("c0.order1.expected.bits2")->data.at(i) = float(x >> 48);
  };
}

std::vector<HostileCase> hostile_cases() {
  std::string many = "[";
  for (int i = 0; i < 65; ++i) many += std::string(i ? "," : "") + "\"x\"";
  many += "]";
  return {
      {"format_other", false, attr_is("format", "microsim-histogram-1"), "not a microsim scatter file"},
      {"format_missing", false, [](auto& im) { im.attributes.erase("format"); }, "attribute 'format' is missing"},
      {"kind_unknown", false, attr_is("kind", "lobe"), "attribute kind = 'lobe'"},
      {"binning_not_json", false, attr_is("binning", "{rows"), "attribute binning = '{rows'"},
      {"binning_sphere", false, attr_is("binning", R"({"kind":"sphere","rows":3})"), "hemispheres binning"},
      {"binning_other_size", false,
       attr_is("binning", DirectionBinning::hemispheres(3).describe().dump()), "but the image is"},
      {"binning_not_canonical", false,
       [](auto& im) { im.attributes["binning"] = " " + im.attributes["binning"]; }, "canonical"},
      {"channels_not_array", false, attr_is("channel_names", "\"r\""), "attribute channel_names = '\"r\"'"},
      {"channels_too_many", false, attr_is("channel_names", many), "1 to 64 names"},
      {"channels_fewer", false, attr_is("channel_names", R"(["r"])"), "not part of"},
      {"paths_negative", false, attr_is("paths", "-1"), "attribute paths = '-1'"},
      {"seed_real", false, attr_is("seed", "1.5"), "attribute seed = '1.5'"},
      {"blocks_reversed", false, attr_is("blocks", "1,0"), "attribute blocks = '1,0'"},
      {"blocks_outside", false, attr_is("blocks", "0,99"), "attribute blocks = '0,99'"},
      {"blocks_one_number", false, attr_is("blocks", "0"), "attribute blocks = '0'"},
      {"partial_unknown", false, attr_is("partial", "maybe"), "attribute partial = 'maybe'"},
      {"unknown_attribute", false, attr_is("colour", "red"), "unknown attribute 'colour'"},
      {"unknown_channel", false, [](auto& im) { im.add_channel("c0.order6.w"); }, "channel 'c0.order6.w'"},
      {"missing_channel", false, [](auto& im) { std::erase_if(im.channels, [](auto& c) { return c.name == "c1.order2.w2.lo1"; }); },
       "channel c1.order2.w2.lo1 is missing"},
      {"limb_fraction", false, pixel_is("c0.order1.w.lo0", 0, 0.5f), "a limb must be an integer"},
      {"limb_too_large", false, pixel_is("c2.order2.w2.hi1", 1, 16777216.0f), "a limb must be an integer"},
      {"limb_nan", false, pixel_is("c0.order1.w.lo2", 3, std::nanf("")), "a limb must be an integer"},
      {"top_limb_too_large", false, pixel_is("c0.order1.w.lo2", 3, 65536.0f), "a limb must be an integer"},
      {"sum_negative", false, pixel_is("c0.order1.w.hi2", 2, 32768.0f), "the sum is negative"},
      {"float_disagrees", false, pixel_is("c0.order2.w", 0, 1e30f), "disagrees with its exact sum"},
      {"total_disagrees", false, pixel_is("c1.total.w2", 4, -1.0f), "is not the sum over orders"},
      {"unbinned_three_fields", false, attr_is("c0.order3.unbinned.w", "1,2,3"), "attribute c0.order3.unbinned.w = '1,2,3'"},
      {"unbinned_negative", false, attr_is("c0.order3.unbinned.w2", "9223372036854775808,0"), "HIGH below 2^63"},
      {"unfinished_missing", false, [](auto& im) { im.attributes.erase("c2.unfinished.w"); },
       "attribute 'c2.unfinished.w' is missing"},
      {"lost_text", false, attr_is("c1.lost.w2", "zero"), "attribute c1.lost.w2 = 'zero'"},
      {"expected_negative", true, expected_bits(2, -0.5), "is not finite and >= 0"},
      {"expected_nan", true, expected_bits(2, std::numeric_limits<double>::quiet_NaN()), "is not finite and >= 0"},
      {"expected_float_disagrees", true, pixel_is("c1.order1.expected", 0, 7.0f), "disagrees with its exact value"},
      {"error_estimate_nan", true, attr_is("c1.error_estimate", "nan"), "attribute c1.error_estimate = 'nan'"},
      {"expectation_with_paths", true, attr_is("paths", "10"), "unknown attribute 'paths'"},
      {"expectation_as_histogram", true, attr_is("kind", "histogram"), "not part of"},
  };
}

class ScatterReaderHostile : public ::testing::TestWithParam<HostileCase> {};

TEST_P(ScatterReaderHostile, RefusesWithAMessageNamingTheBadValue) {
  const HostileCase& c = GetParam();
  microgeom::ExrImage image = written_image(c.expectation);
  ASSERT_NO_THROW(scatter_from_exr(image, "f.exr"));  // the unmutated file is fine
  c.mutate(image);
  try {
    scatter_from_exr(image, "f.exr");
    ADD_FAILURE() << c.name << ": accepted";
  } catch (const ScatterIoError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(c.message), std::string::npos) << what;
    EXPECT_NE(what.find("'f.exr'"), std::string::npos) << what;
    EXPECT_LT(what.size(), 500u) << what;
  }
}

INSTANTIATE_TEST_SUITE_P(Cases, ScatterReaderHostile, ::testing::ValuesIn(hostile_cases()),
                         [](const auto& info) { return info.param.name; });

TEST(ScatterIo, FilesThatAreNotScatterFilesAreNamed) {
  const fs::path dir = test::scratch_dir("scatter_io", "not_scatter");
  std::ofstream(dir / "text.exr") << "not an image";
  EXPECT_THROW(read_scatter_exr(dir / "text.exr"), ScatterIoError);
  microgeom::ExrImage heightmap;
  heightmap.width = heightmap.height = 4;
  heightmap.add_channel("height");
  microgeom::write_exr(dir / "height.exr", heightmap);
  try {
    read_scatter_exr(dir / "height.exr");
    ADD_FAILURE() << "a heightmap was read as a scatter file";
  } catch (const ScatterIoError& e) {
    EXPECT_NE(std::string(e.what()).find("not a microsim scatter file"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

TEST(ScatterIo, WriterRefusesABinningThatIsNotHemispheres) {
  const ScatterHistogram odd("a binning", 4, {true, true, false, false}, {"c0"});
  EXPECT_THROW(write_scatter_exr(test::scratch_dir("scatter_io", "writer") / "x.exr", odd), ScatterIoError);
}

}  // namespace
}  // namespace microsim
