// The Embree RAII wrapper: hits and misses on known geometry, error reporting, FTZ/DAZ scope, and the
// exact-quadric user geometry against the double-precision intersection it wraps.
#include "trace/embree.h"
#include "trace/quadric.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_embree {

using namespace microsim;
using microsim::embree::BuildQuality;
using microsim::embree::Device;
using microsim::embree::EmbreeError;
using microsim::embree::Scene;

TEST(Embree, TriangleHitAndMiss) {
  Device device;
  Scene scene(device, BuildQuality::high);
  // One triangle in the plane z = 1, counter-clockwise seen from +z.
  const std::vector<float> v{0, 0, 1, 1, 0, 1, 0, 1, 1};
  const std::vector<std::uint32_t> idx{0, 1, 2};
  const unsigned id = scene.add_triangles(v, idx);
  scene.commit();
  const auto hit = scene.intersect({0.25f, 0.25f, 3.0f}, {0.0f, 0.0f, -1.0f}, 0.0f, 100.0f);
  ASSERT_TRUE(hit);
  EXPECT_FLOAT_EQ(hit->t, 2.0f);
  EXPECT_EQ(hit->geom_id, id);
  EXPECT_EQ(hit->prim_id, 0u);
  // Embree's geometric normal is perpendicular to the triangle.
  EXPECT_FLOAT_EQ(hit->Ng.x(), 0.0f);
  EXPECT_FLOAT_EQ(hit->Ng.y(), 0.0f);
  EXPECT_NE(hit->Ng.z(), 0.0f);
  // Outside the triangle, beyond tfar, or before tnear: misses.
  EXPECT_FALSE(scene.intersect({0.75f, 0.75f, 3.0f}, {0.0f, 0.0f, -1.0f}, 0.0f, 100.0f));
  EXPECT_FALSE(scene.intersect({0.25f, 0.25f, 3.0f}, {0.0f, 0.0f, -1.0f}, 0.0f, 1.5f));
  EXPECT_FALSE(scene.intersect({0.25f, 0.25f, 3.0f}, {0.0f, 0.0f, -1.0f}, 2.5f, 100.0f));
  EXPECT_TRUE(scene.occluded({0.25f, 0.25f, 3.0f}, {0.0f, 0.0f, -1.0f}, 0.0f, 100.0f));
  EXPECT_FALSE(scene.occluded({0.25f, 0.25f, 3.0f}, {0.0f, 0.0f, 1.0f}, 0.0f, 100.0f));
  const RTCBounds b = scene.bounds();
  EXPECT_FLOAT_EQ(b.lower_z, 1.0f);
  EXPECT_FLOAT_EQ(b.upper_x, 1.0f);
}

TEST(Embree, BadInputThrows) {
  Device device;
  Scene scene(device);
  const std::vector<float> v{0, 0, 0, 1, 0, 0, 0, 1, 0};
  const std::vector<std::uint32_t> bad{0, 1, 3};
  EXPECT_THROW(scene.add_triangles(v, bad), EmbreeError);
  const std::vector<std::uint32_t> not_triples{0, 1};
  EXPECT_THROW(scene.add_triangles(v, not_triples), EmbreeError);
}

TEST(Embree, ErrorCallbackIsRecordedAndThrownByCheck) {
  Device device;
  EXPECT_NO_THROW(device.check("nothing"));
  // An invalid geometry type makes Embree report RTC_ERROR_INVALID_ARGUMENT through the callback.
  RTCGeometry g = rtcNewGeometry(device.handle(), RTCGeometryType(12345));
  if (g) rtcReleaseGeometry(g);
  EXPECT_FALSE(device.pending_error().empty());
  EXPECT_THROW(device.check("rtcNewGeometry"), EmbreeError);
  EXPECT_NO_THROW(device.check("after"));  // consumed
}

TEST(Embree, FlushDenormalsScopeSetsAndRestores) {
  const bool before = embree::FlushDenormalsScope::active_in_this_thread();
  {
    embree::FlushDenormalsScope scope;
    EXPECT_TRUE(embree::FlushDenormalsScope::active_in_this_thread());
    volatile float tiny = 1e-39f;  // a denormal: read as zero under DAZ
    volatile float product = tiny * 1.0f;
    EXPECT_EQ(product, 0.0f);
  }
  EXPECT_EQ(embree::FlushDenormalsScope::active_in_this_thread(), before);
}

// The user geometry reports exactly what Ellipsoid::intersect computes for the same float ray.
TEST(QuadricEllipsoid, EmbreeUserGeometryMatchesDoubleIntersection) {
  Device device;
  Scene scene(device);
  QuadricEllipsoid quadric(microgeom::Ellipsoid{0.3, 0.7});
  const unsigned id = quadric.attach(scene);
  scene.commit();
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<float> uni(-1.0f, 1.0f);
  int hits = 0;
  for (int k = 0; k < 2000; ++k) {
    const Vec3<float> o(4.0f * uni(rng), 4.0f * uni(rng), 3.0f + uni(rng));
    const Vec3<float> target(3.5f * uni(rng), 1.5f * uni(rng), uni(rng));
    const Vec3<float> d = (target - o).normalized();
    const auto hit = scene.intersect(o, d, 0.0f, 1e30f);
    const auto exact = quadric.ellipsoid().intersect(o.cast<double>(), d.cast<double>(), 0.0, 1e30);
    ASSERT_EQ(hit.has_value(), exact.has_value()) << k;
    if (!hit) continue;
    ++hits;
    EXPECT_EQ(hit->geom_id, id);
    EXPECT_EQ(hit->t, float(exact->t));
    EXPECT_NEAR((hit->Ng.cast<double>() - exact->normal).norm(), 0.0, 1e-7);
    EXPECT_TRUE(exact->entering);
    EXPECT_TRUE(scene.occluded(o, d, 0.0f, 1e30f));
  }
  EXPECT_GT(hits, 500);
  // From inside, the exit crossing is reported.
  const auto inside = scene.intersect({0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 0.0f, 1e30f);
  ASSERT_TRUE(inside);
  EXPECT_FLOAT_EQ(inside->t, 1.0f);
  EXPECT_FLOAT_EQ(inside->Ng.z(), 1.0f);
}

}  // namespace test_embree
