// Tests of the merge as a library call (src/measure/merge.h): the shards of one ellipsoid VNDF run, written
// as `trace vndf --shard` writes them (JSON parts), merge in any order into the single run's counts; the
// kind is found from the files; a missing or repeated block range, parts of two kinds and an EXR part (the
// form of earlier versions) are MergeErrors naming them (negative controls). A Smith-walk albedo table's cells
// measured in block ranges (measure/albedo.h), written as `albedo --shard` writes them, merge in any order into
// the whole table bit for bit; parts of another seed, a missing range and a malformed estimate are refused.
#include "measure/merge.h"

#include "measure/albedo.h"

#include "measure/vndf.h"
#include "stats/histogram_io.h"

#include "scratch_dir.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

namespace microsim {
namespace {

EllipsoidVndf run(const EllipsoidTarget& target, std::optional<BlockRange> blocks) {
  VndfRequest r;
  r.theta_deg = 40;
  r.phi_deg = 10;
  r.rays = 60000;
  r.seed = 5;
  r.rows = 9;
  r.blocks = blocks;
  return measure_ellipsoid_vndf(target, r);
}

std::string message_of(const std::vector<std::string>& parts) {
  try {
    merge_parts(parts);
  } catch (const MergeError& e) {
    return e.what();
  }
  return "no MergeError";
}

TEST(Merge, VndfShardsInAnyOrderAreTheSingleRun) {
  const auto dir = test::scratch_dir("merge", "vndf");
  const EllipsoidTarget target(0.4, 0.4, /*mesh_level=*/-1);
  const EllipsoidVndf single = run(target, std::nullopt);
  const std::uint64_t total = vndf_run_record(single.histogram).total_blocks;
  ASSERT_GE(total, 3u);
  const std::vector<BlockRange> ranges{{0, 1}, {1, total / 2}, {total / 2, total}};
  std::vector<std::string> parts;
  for (const BlockRange& b : ranges) {
    parts.push_back((dir / ("p" + std::to_string(b.begin) + ".json")).string());
    std::ofstream(parts.back()) << vndf_part_json(run(target, b).histogram).dump();
  }
  EXPECT_EQ(merge_kind(parts), PartKind::vndf);
  EXPECT_STREQ(part_kind_name(PartKind::vndf), "trace vndf");
  const MergedRun m = merge_parts({parts[2], parts[0], parts[1]});
  ASSERT_EQ(m.kind, PartKind::vndf);
  EXPECT_EQ(m.parts, 3u);
  const TracedHistogram& h = std::get<MergedVndf>(m.result).histogram;
  EXPECT_EQ(h.counts, single.histogram.counts);
  EXPECT_EQ(h.rays, single.histogram.rays);
  EXPECT_EQ(h.hits, single.histogram.hits);
  const MergedEllipsoid e = analyse_merged_ellipsoid(std::get<MergedVndf>(m.result));
  EXPECT_EQ(e.vndf.analysis.p_value, single.analysis.p_value);

  // Negative controls: a block range missing, one repeated, parts of two kinds, a part that is not there.
  EXPECT_NE(message_of({parts[0], parts[2]}).find("are missing"), std::string::npos) << message_of({parts[0], parts[2]});
  const std::string repeated = message_of({parts[0], parts[1], parts[2], parts[1]});
  EXPECT_NE(repeated.find("blocks [1, " + std::to_string(total / 2) + ") are in more than one part"), std::string::npos)
      << repeated;
  const std::string json = (dir / "q.json").string();
  std::ofstream(json) << "{}";
  EXPECT_NE(message_of({parts[0], json}).find("part '" + json + "'"), std::string::npos) << message_of({parts[0], json});
  const std::string absent = (dir / "absent.json").string();
  EXPECT_EQ(message_of({parts[0], absent}), "part '" + absent + "': no such file");
  const std::string exr = (dir / "old.exr").string();
  write_histogram_exr(exr, single.histogram);
  EXPECT_NE(message_of({parts[0], exr}).find("is an EXR file: parts are JSON now"), std::string::npos)
      << message_of({parts[0], exr});
}

// ---- albedo tables: a sampled table's cells in parts ------------------------------------------------------

AlbedoTableRequest albedo_walk_request(std::uint64_t seed) {
  AlbedoTableRequest r;
  r.model = AlbedoModel::smith_walk;
  r.material = Material::dielectric(1.5);
  r.alphas = {0.4, 0.9};
  r.mus = 3;
  r.paths = 400;
  r.seed = seed;
  return r;
}

void expect_same_albedo_bits(const AlbedoTable& a, const AlbedoTable& b) {
  ASSERT_EQ(a.quantities.size(), b.quantities.size());
  for (std::size_t q = 0; q < a.quantities.size(); ++q)
    for (const auto member : {&AlbedoQuantity::cells, &AlbedoQuantity::average}) {
      const std::vector<Estimate>&x = a.quantities[q].*member, &y = b.quantities[q].*member;
      ASSERT_EQ(x.size(), y.size());
      for (std::size_t i = 0; i < x.size(); ++i) {
        EXPECT_EQ(x[i].value, y[i].value) << a.quantities[q].name << " " << i;
        EXPECT_EQ(x[i].standard_error, y[i].standard_error) << a.quantities[q].name << " " << i;
      }
    }
}

TEST(MergeAlbedo, ShardsOfAWalkTableInAnyOrderAreTheWholeTableBitForBit) {
  const auto dir = test::scratch_dir("merge", "albedo");
  const AlbedoTableRequest r = albedo_walk_request(11);
  ASSERT_EQ(albedo_cell_count(r), 6u);
  const AlbedoTable whole = measure_albedo_table(r);
  std::vector<std::string> paths;
  std::vector<AlbedoPart> parts;
  for (const BlockRange& cells : {BlockRange{0, 2}, BlockRange{2, 5}, BlockRange{5, 6}}) {
    const std::optional<nlohmann::json> part = measure_albedo_part(r, cells);
    ASSERT_TRUE(part.has_value());
    paths.push_back((dir / ("a" + std::to_string(cells.begin) + ".json")).string());
    std::ofstream(paths.back()) << part->dump();
    parts.push_back(read_albedo_part(nlohmann::json::parse(part->dump())));
  }
  EXPECT_EQ(parts[1].request.material, r.material);
  const MergedRun m = merge_parts({paths[2], paths[0], paths[1]});
  ASSERT_EQ(m.kind, PartKind::albedo);
  expect_same_albedo_bits(std::get<AlbedoTable>(m.result), whole);
  expect_same_albedo_bits(measure_albedo_cells_table(r, walk_albedo_cells), whole);
  // Negative controls: a range missing, a part of another seed.
  EXPECT_NE(message_of({paths[0], paths[2]}).find("are missing"), std::string::npos) << message_of({paths[0], paths[2]});
  const AlbedoPart other = read_albedo_part(*measure_albedo_part(albedo_walk_request(12), {2, 5}));
  EXPECT_THROW(merge_albedo_parts({parts[0], other, parts[2]}), HistogramMergeError);
  std::filesystem::remove_all(dir);
}

TEST(MergeAlbedo, AMalformedPartIsRefusedNamingWhere) {
  nlohmann::json part = *measure_albedo_part(albedo_walk_request(11), {1, 2});
  part["cells"][0][0][1] = "not bits";
  try {
    read_albedo_part(part);
    FAIL() << "a malformed estimate was read";
  } catch (const HistogramMergeError& e) {
    EXPECT_NE(std::string(e.what()).find("cells/0"), std::string::npos) << e.what();
  }
  part = *measure_albedo_part(albedo_walk_request(11), {1, 2});
  part["provenance"]["parameters"]["model"] = "analytic";
  EXPECT_THROW(read_albedo_part(part), HistogramMergeError);
}

TEST(MergeAlbedo, TheWorstRelativeErrorIsOverTheTargetedQuantitiesOnly) {
  AlbedoTable t;
  t.quantities = {{"E", {{0.5, 0.01}}, {{0.5, 0.002}}}, {"E1", {{0.25, 0.001}}, {{0.25, 0}}},
                  {"unfinished", {{0.0, 0.3}}, {{0.0, 0.3}}}};
  EXPECT_DOUBLE_EQ(worst_relative_albedo_error(t, "E1"), 0.004);
  EXPECT_DOUBLE_EQ(worst_relative_albedo_error(t, "E"), 0.02);
  EXPECT_EQ(worst_relative_albedo_error(t, "unfinished"), std::numeric_limits<double>::infinity());
}

}  // namespace
}  // namespace microsim
