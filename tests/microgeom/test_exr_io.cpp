// Round-trip and failure tests of the OpenEXR helper (microgeom/exr_io.h).
#include "microgeom/exr_io.h"

#include "scratch_dir.h"

#include <fmt/core.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>

#include <unistd.h>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_exr_io {

namespace fs = std::filesystem;
using microgeom::ExrImage;

namespace {

ExrImage sample_image() {
  ExrImage img;
  img.width = 37;  // odd, non-square sizes catch row/column mix-ups
  img.height = 11;
  auto& a = img.add_channel("height");
  auto& b = img.add_channel("N.x");
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      a.data[y * img.width + x] = float(x) * 0.25f - float(y) * 1.0e-7f;
      b.data[y * img.width + x] = std::nextafter(float(y * 1000 + x), 1.0e9f);  // exercises all mantissa bits
    }
  b.data[3] = std::numeric_limits<float>::denorm_min();
  b.data[4] = -0.0f;
  img.attributes["assembly"] = "smith";
  img.attributes["alpha"] = "0.5,0.25";
  return img;
}

}  // namespace

TEST(ExrIo, RoundTripIsBitExact) {
  const auto dir = microsim::test::scratch_dir("test_exr", "roundtrip");
  const auto path = dir / "img.exr";
  const ExrImage img = sample_image();
  microgeom::write_exr(path, img);
  const ExrImage back = microgeom::read_exr(path);
  ASSERT_EQ(back.width, img.width);
  ASSERT_EQ(back.height, img.height);
  ASSERT_EQ(back.channels.size(), 2u);
  for (const auto& c : img.channels) {
    const auto* r = back.find(c.name);
    ASSERT_NE(r, nullptr) << c.name;
    ASSERT_EQ(r->data.size(), c.data.size());
    for (std::size_t i = 0; i < c.data.size(); ++i)
      ASSERT_EQ(std::signbit(r->data[i]), std::signbit(c.data[i])) << c.name << " " << i;
    EXPECT_EQ(r->data, c.data) << c.name;
  }
  EXPECT_EQ(back.attributes.at("assembly"), "smith");
  EXPECT_EQ(back.attributes.at("alpha"), "0.5,0.25");
  EXPECT_EQ(back.find("nope"), nullptr);
  // Only the destination remains: the temporary file was renamed.
  int files = 0;
  for ([[maybe_unused]] auto& e : fs::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 1);
  fs::remove_all(dir);
}

TEST(ExrIo, OverwriteReplacesTheFile) {
  const auto dir = microsim::test::scratch_dir("test_exr", "overwrite");
  const auto path = dir / "img.exr";
  ExrImage img = sample_image();
  microgeom::write_exr(path, img);
  img.channels[0].data[0] = 42.0f;
  microgeom::write_exr(path, img);
  EXPECT_EQ(microgeom::read_exr(path).find("height")->data[0], 42.0f);
  fs::remove_all(dir);
}

TEST(ExrIo, BadImagesThrowNamingThePathAndLeaveNothing) {
  const auto dir = microsim::test::scratch_dir("test_exr", "bad");
  const auto path = dir / "bad.exr";
  ExrImage img = sample_image();
  img.channels[1].data.pop_back();  // wrong size
  try {
    microgeom::write_exr(path, img);
    FAIL() << "expected a throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("bad.exr"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("N.x"), std::string::npos) << e.what();
  }
  ExrImage empty;
  EXPECT_THROW(microgeom::write_exr(path, empty), std::runtime_error);
  ExrImage reserved = sample_image();
  reserved.attributes["channels"] = "x";
  EXPECT_THROW(microgeom::write_exr(path, reserved), std::runtime_error);
  // Unwritable destination: directory does not exist.
  EXPECT_THROW(microgeom::write_exr(dir / "no_such_dir" / "x.exr", sample_image()), std::runtime_error);
  EXPECT_TRUE(fs::is_empty(dir));
  fs::remove_all(dir);
}

TEST(ExrIo, ReadingGarbageOrMissingFilesThrowsNamingThePath) {
  const auto dir = microsim::test::scratch_dir("test_exr", "garbage");
  const auto missing = dir / "missing.exr";
  try {
    microgeom::read_exr(missing);
    FAIL() << "expected a throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("missing.exr"), std::string::npos) << e.what();
  }
  const auto garbage = dir / "garbage.exr";
  { std::ofstream(garbage) << "this is not an EXR file"; }
  try {
    microgeom::read_exr(garbage);
    FAIL() << "expected a throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("garbage.exr"), std::string::npos) << e.what();
  }
  // A truncated real file.
  const auto good = dir / "good.exr";
  microgeom::write_exr(good, sample_image());
  const auto size = fs::file_size(good);
  fs::resize_file(good, size / 2);
  EXPECT_THROW(microgeom::read_exr(good), std::runtime_error);
  fs::remove_all(dir);
}

// Regression: add_channel returned a reference into a vector that the next
// add_channel reallocated, so every multi-channel writer wrote through freed memory. The reference to the
// first channel must still name the stored channel after many more are added.
TEST(ExrIo, AddChannelReferencesSurviveLaterChannels) {
  ExrImage img;
  img.width = 3;
  img.height = 2;
  auto& first = img.add_channel("first");
  first.data[5] = 7.0f;
  for (int i = 0; i < 64; ++i) img.add_channel(fmt::format("c{}", i)).data[0] = float(i);
  EXPECT_EQ(&first, img.find("first"));
  EXPECT_EQ(img.find("first")->data[5], 7.0f);
  EXPECT_EQ(img.find("c63")->data[0], 63.0f);
}

}  // namespace test_exr_io
