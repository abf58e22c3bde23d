// Tests of the periodic heightfield type (microgeom/heightfield.h): the documented triangle split,
// wrap-around, interpolation, and the heightmap / normal-map EXR files with their validation.
#include "microgeom/exr_io.h"
#include "microgeom/heightfield.h"

#include "core/random.h"

#include "scratch_dir.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "error_message.h"

#include <cmath>
#include <functional>
#include <limits>

#include <unistd.h>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_heightfield {

namespace fs = std::filesystem;
using microgeom::Heightfield;

namespace {

Heightfield random_field(int n, double tile, std::uint64_t seed) {
  std::vector<float> h(std::size_t(n) * n);
  microsim::CounterRng rng(seed, 0);
  for (auto& z : h) z = float(rng.uniform() - 0.5) * float(tile);
  return Heightfield(n, tile, std::move(h));
}

using microsim::test::message_of;

}  // namespace

TEST(Heightfield, ConstructorValidatesAndNamesTheBadValue) {
  EXPECT_THROW(Heightfield(1, 1.0, {0.0f}), std::invalid_argument);
  EXPECT_THROW(Heightfield(4, 1.0, std::vector<float>(15)), std::invalid_argument);
  EXPECT_THROW(Heightfield(4, 0.0, std::vector<float>(16)), std::invalid_argument);
  EXPECT_THROW(Heightfield(4, -2.0, std::vector<float>(16)), std::invalid_argument);
  EXPECT_THROW(Heightfield(4, std::numeric_limits<double>::infinity(), std::vector<float>(16)), std::invalid_argument);
  std::vector<float> h(16, 0.0f);
  h[2 * 4 + 3] = std::numeric_limits<float>::quiet_NaN();
  const std::string msg = message_of([&] { Heightfield(4, 1.0, h); });
  EXPECT_NE(msg.find("x=3, y=2"), std::string::npos) << msg;
  h[2 * 4 + 3] = std::numeric_limits<float>::infinity();
  EXPECT_THROW(Heightfield(4, 1.0, h), std::invalid_argument);
}

TEST(Heightfield, AccessorsAndWrapAround) {
  const Heightfield f = random_field(8, 2.0, 1);
  EXPECT_EQ(f.resolution(), 8);
  EXPECT_DOUBLE_EQ(f.cell_size(), 0.25);
  EXPECT_EQ(f.triangle_count(), 128u);
  float lo = f.heights()[0], hi = lo;
  for (float z : f.heights()) {
    lo = std::min(lo, z);
    hi = std::max(hi, z);
  }
  EXPECT_EQ(f.min_height(), lo);
  EXPECT_EQ(f.max_height(), hi);
  for (int j = -9; j < 17; ++j)
    for (int i = -9; i < 17; ++i)
      EXPECT_EQ(f.height(i, j), f.height_unchecked(((i % 8) + 8) % 8, ((j % 8) + 8) % 8));
  EXPECT_EQ(f.height(8, 0), f.height_unchecked(0, 0));
  EXPECT_EQ(f.height(-1, -1), f.height_unchecked(7, 7));
  for (std::uint32_t id = 0; id < f.triangle_count(); ++id) {
    const auto c = f.triangle_index(id);
    EXPECT_EQ(f.triangle_id(c.i, c.j, c.t), id);
  }
}

TEST(Heightfield, TriangleSplitSlopesAndNormalsAgreeWithTheVertices) {
  const Heightfield f = random_field(6, 3.0, 2);
  const double h = f.cell_size();
  for (int j = 0; j < 6; ++j)
    for (int i = 0; i < 6; ++i) {
      // The documented split: t0 = (i,j),(i+1,j),(i+1,j+1); t1 = (i,j),(i+1,j+1),(i,j+1).
      const auto v0 = f.triangle_vertices(i, j, 0), v1 = f.triangle_vertices(i, j, 1);
      EXPECT_EQ(v0[0], v1[0]);
      EXPECT_EQ(v0[2], v1[1]);  // the shared diagonal
      EXPECT_DOUBLE_EQ(v0[1].x(), (i + 1) * h);
      EXPECT_DOUBLE_EQ(v0[1].y(), j * h);
      EXPECT_DOUBLE_EQ(v1[2].x(), i * h);
      EXPECT_DOUBLE_EQ(v1[2].y(), (j + 1) * h);
      EXPECT_EQ(v0[1].z(), double(f.height(i + 1, j)));
      EXPECT_EQ(v1[2].z(), double(f.height(i, j + 1)));
      for (int t = 0; t < 2; ++t) {
        const auto v = f.triangle_vertices(i, j, t);
        const Eigen::Vector3d cross = (v[1] - v[0]).cross(v[2] - v[0]);
        EXPECT_NEAR(cross.z(), h * h, 1e-12);  // counter-clockwise from +z, projected area h^2/2
        const Eigen::Vector3d n = cross.normalized();
        const Eigen::Vector3d m = f.triangle_normal(i, j, t);
        EXPECT_NEAR((n - m).norm(), 0.0, 1e-12);
        EXPECT_NEAR(m.norm(), 1.0, 1e-12);
        const Eigen::Vector2d s = f.triangle_slope(i, j, t);
        EXPECT_NEAR(s.x(), -n.x() / n.z(), 1e-9);
        EXPECT_NEAR(s.y(), -n.y() / n.z(), 1e-9);
        EXPECT_NEAR(f.triangle_centroid_height(i, j, t), (v[0].z() + v[1].z() + v[2].z()) / 3.0, 1e-12);
        EXPECT_EQ(f.triangle_slope(f.triangle_id(i, j, t)), s);
      }
    }
}

TEST(Heightfield, HeightAtInterpolatesOnTheSplitAndIsPeriodic) {
  const Heightfield f = random_field(5, 1.0, 3);
  const double h = f.cell_size(), L = f.tile_size();
  for (int j = 0; j < 5; ++j)
    for (int i = 0; i < 5; ++i) {
      EXPECT_NEAR(f.height_at(i * h, j * h), f.height(i, j), 1e-7);
      for (double u : {0.1, 0.5, 0.9})
        for (double v : {0.05, 0.45, 0.85}) {
          const int t = u >= v ? 0 : 1;
          const auto vx = f.triangle_vertices(i, j, t);
          const Eigen::Vector3d n = (vx[1] - vx[0]).cross(vx[2] - vx[0]);
          const double x = (i + u) * h, y = (j + v) * h;
          // The plane through the triangle: n . (p - v0) = 0.
          const double z = vx[0].z() - (n.x() * (x - vx[0].x()) + n.y() * (y - vx[0].y())) / n.z();
          EXPECT_NEAR(f.height_at(x, y), z, 1e-7);
          EXPECT_NEAR(f.height_at(x + L, y - 2 * L), z, 1e-6);
          EXPECT_NEAR(f.height_at(x - 3 * L, y + L), z, 1e-6);
          EXPECT_EQ(f.triangle_at(x, y), f.triangle_id(i, j, t));
          EXPECT_EQ(f.triangle_at(x - L, y + L), f.triangle_id(i, j, t));
        }
    }
  EXPECT_EQ(f.height_at(std::numeric_limits<double>::quiet_NaN(), 0.0), 0.0);  // degenerate input: 0, not NaN
}

TEST(Heightfield, HeightmapExrRoundTripKeepsHeightsTileSizeAndMetadata) {
  const auto dir = microsim::test::scratch_dir("test_hf", "roundtrip");
  Heightfield f = random_field(16, 0.125, 4);
  f.metadata["assembly"] = "smith";
  f.metadata["seed"] = "7";
  microgeom::save_heightmap_exr(dir / "h.exr", f);
  const Heightfield g = microgeom::load_heightmap_exr(dir / "h.exr");
  EXPECT_EQ(g.resolution(), 16);
  EXPECT_EQ(g.tile_size(), 0.125);  // %.17g round-trips exactly
  EXPECT_EQ(g.heights(), f.heights());
  EXPECT_EQ(g.metadata.at("assembly"), "smith");
  EXPECT_EQ(g.metadata.at("seed"), "7");
  // An explicit tile size overrides the attribute.
  EXPECT_EQ(microgeom::load_heightmap_exr(dir / "h.exr", 3.0).tile_size(), 3.0);

  microgeom::save_normal_map_exr(dir / "n.exr", f);
  const auto img = microgeom::read_exr(dir / "n.exr");
  ASSERT_NE(img.find("R"), nullptr);
  for (std::size_t k = 0; k < 256; ++k) {
    const double r = img.find("R")->data[k], gg = img.find("G")->data[k], b = img.find("B")->data[k];
    EXPECT_NEAR(r * r + gg * gg + b * b, 1.0, 1e-6);
    EXPECT_GT(b, 0.0);
  }
  fs::remove_all(dir);
}

TEST(Heightfield, ExternalHeightmapsAreValidatedWithClearMessages) {
  const auto dir = microsim::test::scratch_dir("test_hf", "external");
  auto write = [&](const std::string& name, int w, int h, std::vector<std::string> channels, float bad = 0.0f,
                   bool with_bad = false) {
    microgeom::ExrImage img;
    img.width = w;
    img.height = h;
    for (auto& c : channels) {
      auto& ch = img.add_channel(c);
      for (std::size_t k = 0; k < ch.data.size(); ++k) ch.data[k] = float(k % 7) * 0.01f;
      if (with_bad) ch.data[w + 1] = bad;
    }
    microgeom::write_exr(dir / name, img);
    return dir / name;
  };
  // Accepted layouts: "height", "Y", or a single channel of any name, with an explicit tile size.
  EXPECT_EQ(microgeom::load_heightmap_exr(write("y.exr", 8, 8, {"Y", "A"}), 2.0).resolution(), 8);
  EXPECT_EQ(microgeom::load_heightmap_exr(write("z.exr", 8, 8, {"Z"}), 2.0).resolution(), 8);
  // No tile size anywhere.
  EXPECT_NE(message_of([&] { microgeom::load_heightmap_exr(dir / "z.exr"); }).find("--tile-size"), std::string::npos);
  // Tile size <= 0 or not finite.
  EXPECT_NE(message_of([&] { microgeom::load_heightmap_exr(dir / "z.exr", 0.0); }).find("tile size 0"),
            std::string::npos);
  EXPECT_THROW(microgeom::load_heightmap_exr(dir / "z.exr", -1.0), std::runtime_error);
  EXPECT_THROW(microgeom::load_heightmap_exr(dir / "z.exr", std::numeric_limits<double>::quiet_NaN()),
               std::runtime_error);
  // Wrong channels: names what was found.
  const std::string rgb = message_of([&] { microgeom::load_heightmap_exr(write("rgb.exr", 8, 8, {"R", "G", "B"}), 1.0); });
  EXPECT_NE(rgb.find("'B', 'G', 'R'"), std::string::npos) << rgb;
  EXPECT_NE(rgb.find("rgb.exr"), std::string::npos) << rgb;
  // Non-square.
  const std::string rect = message_of([&] { microgeom::load_heightmap_exr(write("rect.exr", 8, 4, {"height"}), 1.0); });
  EXPECT_NE(rect.find("8 x 4"), std::string::npos) << rect;
  // NaN and infinite heights, naming the texel.
  const std::string nan = message_of([&] {
    microgeom::load_heightmap_exr(write("nan.exr", 8, 8, {"height"}, std::numeric_limits<float>::quiet_NaN(), true), 1.0);
  });
  EXPECT_NE(nan.find("x=1, y=1"), std::string::npos) << nan;
  EXPECT_THROW(microgeom::load_heightmap_exr(
                   write("inf.exr", 8, 8, {"height"}, -std::numeric_limits<float>::infinity(), true), 1.0),
               std::runtime_error);
  // A garbage tile-size attribute.
  {
    microgeom::ExrImage img;
    img.width = img.height = 4;
    img.add_channel("height");
    img.attributes["microsim.tile_size"] = "12abc";
    microgeom::write_exr(dir / "attr.exr", img);
    EXPECT_NE(message_of([&] { microgeom::load_heightmap_exr(dir / "attr.exr"); }).find("12abc"), std::string::npos);
  }
  EXPECT_THROW(microgeom::load_heightmap_exr(dir / "missing.exr", 1.0), std::runtime_error);
  fs::remove_all(dir);
}

}  // namespace test_heightfield
