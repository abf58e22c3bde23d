// Tests of the merge as a library call (src/measure/merge.h): the shards of one ellipsoid VNDF run, written
// as `trace vndf --shard` writes them (JSON parts), merge in any order into the single run's counts; the
// kind is found from the files; a missing or repeated block range, parts of two kinds and an EXR part (the
// form of earlier versions) are MergeErrors naming them (negative controls).
#include "measure/merge.h"

#include "measure/vndf.h"
#include "stats/histogram_io.h"

#include "scratch_dir.h"

#include <gtest/gtest.h>

#include <fstream>
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

}  // namespace
}  // namespace microsim
