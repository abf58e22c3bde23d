// measure/albedo.h: a Smith-walk table's cells measured in block ranges, written as parts (JSON with
// provenance), read back and merged are the one-process table bit for bit, whatever the order of the parts;
// parts of another run, a missing range or a malformed estimate are refused.
#include "measure/albedo.h"

#include <gtest/gtest.h>

#include <limits>
#include <vector>

namespace {

using namespace microsim;

AlbedoTableRequest small_walk() {
  AlbedoTableRequest r;
  r.model = AlbedoModel::smith_walk;
  r.material = Material::dielectric(1.5);
  r.alphas = {0.4, 0.9};
  r.mus = 3;
  r.paths = 400;
  r.seed = 11;
  return r;
}

AlbedoPart part_of(const AlbedoTableRequest& r, const BlockRange& cells) {
  const std::optional<nlohmann::json> part = measure_albedo_part(r, cells);
  EXPECT_TRUE(part.has_value());
  return read_albedo_part(nlohmann::json::parse(part->dump()));  // through its text, as a file holds it
}

void expect_same_bits(const AlbedoTable& a, const AlbedoTable& b) {
  ASSERT_EQ(a.quantities.size(), b.quantities.size());
  for (std::size_t q = 0; q < a.quantities.size(); ++q) {
    const auto same = [&](const std::vector<Estimate>& x, const std::vector<Estimate>& y) {
      ASSERT_EQ(x.size(), y.size());
      for (std::size_t i = 0; i < x.size(); ++i) {
        EXPECT_EQ(x[i].value, y[i].value) << a.quantities[q].name << " " << i;
        EXPECT_EQ(x[i].standard_error, y[i].standard_error) << a.quantities[q].name << " " << i;
      }
    };
    same(a.quantities[q].cells, b.quantities[q].cells);
    same(a.quantities[q].average, b.quantities[q].average);
  }
}

TEST(AlbedoMeasure, PartsOfAWalkTableMergeIntoTheWholeTableBitForBit) {
  const AlbedoTableRequest r = small_walk();
  ASSERT_EQ(albedo_cell_count(r), 6u);
  const AlbedoTable whole = measure_albedo_table(r);
  const AlbedoPart a = part_of(r, {0, 2}), b = part_of(r, {2, 5}), c = part_of(r, {5, 6});
  EXPECT_EQ(b.request.material, r.material);
  expect_same_bits(merge_albedo_parts({c, a, b}), whole);
  expect_same_bits(measure_albedo_cells_table(r, walk_albedo_cells), whole);
  // Negative controls: a range missing, a part of another seed.
  EXPECT_THROW(merge_albedo_parts({a, c}), HistogramMergeError);
  AlbedoTableRequest other = r;
  other.seed = 12;
  EXPECT_THROW(merge_albedo_parts({a, part_of(other, {2, 5}), c}), HistogramMergeError);
}

TEST(AlbedoMeasure, AMalformedPartIsRefusedNamingWhere) {
  const AlbedoTableRequest r = small_walk();
  nlohmann::json part = *measure_albedo_part(r, {1, 2});
  part["cells"][0][0][1] = "not bits";
  try {
    read_albedo_part(part);
    FAIL() << "a malformed estimate was read";
  } catch (const HistogramMergeError& e) {
    EXPECT_NE(std::string(e.what()).find("cells/0"), std::string::npos) << e.what();
  }
  part = *measure_albedo_part(r, {1, 2});
  part["provenance"]["parameters"]["model"] = "analytic";
  EXPECT_THROW(read_albedo_part(part), HistogramMergeError);
}

TEST(AlbedoMeasure, WorstRelativeErrorIsOverTheTargetedQuantitiesOnly) {
  AlbedoTable t;
  t.quantities = {{"E", {{0.5, 0.01}}, {{0.5, 0.002}}}, {"E1", {{0.25, 0.001}}, {{0.25, 0}}},
                  {"unfinished", {{0.0, 0.3}}, {{0.0, 0.3}}}};
  EXPECT_DOUBLE_EQ(worst_relative_albedo_error(t, "E1"), 0.004);
  EXPECT_DOUBLE_EQ(worst_relative_albedo_error(t, "E"), 0.02);
  EXPECT_EQ(worst_relative_albedo_error(t, "unfinished"), std::numeric_limits<double>::infinity());
}

}  // namespace
