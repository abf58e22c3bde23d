// The ellipsoid's exact intersection (double) and its triangle mesh (OpenMesh).
#include "microgeom/ellipsoid.h"
#include "microgeom/ellipsoid_mesh.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <numbers>
#include <random>
#include <unistd.h>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_ellipsoid_geometry {

using microgeom::Ellipsoid;

namespace {
double implicit(const Ellipsoid& e, const Eigen::Vector3d& p) {
  return e.ax * e.ax * p.x() * p.x() + e.ay * e.ay * p.y() * p.y() + p.z() * p.z() - 1.0;
}
}  // namespace

TEST(EllipsoidIntersect, PointsOnSurfaceNormalsAlongGradient) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  for (const Ellipsoid e : {Ellipsoid{1, 1}, Ellipsoid{0.01, 0.01}, Ellipsoid{0.1, 0.8}, Ellipsoid{2, 2}}) {
    int hits = 0;
    for (int k = 0; k < 5000; ++k) {
      const Eigen::Vector3d o(3.0 / e.ax * uni(rng), 3.0 / e.ay * uni(rng), 3.0 + uni(rng));
      const Eigen::Vector3d target(uni(rng) / e.ax, uni(rng) / e.ay, uni(rng));
      const Eigen::Vector3d d = target - o;  // not normalised on purpose
      const auto hit = e.intersect(o, d, 0.0, 1e300);
      if (!hit) continue;
      ++hits;
      EXPECT_NEAR(implicit(e, hit->point), 0.0, 1e-12);
      EXPECT_NEAR((o + hit->t * d - hit->point).norm() / (1.0 / std::min(e.ax, e.ay)), 0.0, 1e-12);
      const Eigen::Vector3d grad(e.ax * e.ax * hit->point.x(), e.ay * e.ay * hit->point.y(), hit->point.z());
      EXPECT_NEAR(hit->normal.cross(grad.normalized()).norm(), 0.0, 1e-12);
      EXPECT_GT(hit->normal.dot(grad), 0.0);
      EXPECT_LT(hit->normal.dot(d), 0.0);  // entering from outside
      EXPECT_TRUE(hit->entering);
    }
    EXPECT_GT(hits, 1000);
  }
}

TEST(EllipsoidIntersect, GrazingAndMissAndInside) {
  const Ellipsoid e{0.5, 0.25};  // semi-axes 2, 4, 1
  // A vertical ray just inside the rim x = 2: hits near the equator with a nearly horizontal normal.
  const double x = 2.0 * (1.0 - 1e-12);
  const auto hit = e.intersect({x, 0.0, 5.0}, {0.0, 0.0, -1.0}, 0.0, 1e9);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->point.z(), std::sqrt(1.0 - x * x / 4.0), 1e-9);
  EXPECT_GT(hit->normal.x(), 0.999);
  EXPECT_TRUE(std::isfinite(hit->normal.z()));
  EXPECT_FALSE(e.intersect({2.0 + 1e-9, 0.0, 5.0}, {0.0, 0.0, -1.0}, 0.0, 1e9));
  EXPECT_FALSE(e.intersect({0.0, 0.0, 5.0}, {0.0, 0.0, 1.0}, 0.0, 1e9));     // pointing away
  EXPECT_FALSE(e.intersect({0.0, 0.0, 5.0}, {0.0, 0.0, 0.0}, 0.0, 1e9));     // zero direction
  EXPECT_FALSE(e.intersect({0.0, 0.0, 5.0}, {0.0, 0.0, -1.0}, 0.0, 3.9));    // beyond tfar
  const auto from_inside = e.intersect({0.0, 0.0, 0.0}, {1.0, 0.0, 0.0}, 0.0, 1e9);
  ASSERT_TRUE(from_inside);
  EXPECT_FALSE(from_inside->entering);
  EXPECT_NEAR(from_inside->t, 2.0, 1e-15);
  // Far origin, tiny ellipsoid cross-section: the stable form keeps full relative accuracy.
  const Ellipsoid flat{0.01, 0.01};
  const auto far = flat.intersect({0.0, 0.0, 1e6}, {0.0, 0.0, -1.0}, 0.0, 1e9);
  ASSERT_TRUE(far);
  EXPECT_NEAR(far->point.z(), 1.0, 1e-9);
  EXPECT_NEAR(far->t, 1e6 - 1.0, 1e-9);
}

TEST(EllipsoidIntersect, SupportFunctionBoundsTheEllipsoid) {
  const Ellipsoid e{0.1, 0.8};
  EXPECT_DOUBLE_EQ(e.support({1, 0, 0}), 10.0);
  EXPECT_DOUBLE_EQ(e.support({0, 1, 0}), 1.25);
  EXPECT_DOUBLE_EQ(e.support({0, 0, 1}), 1.0);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (int k = 0; k < 1000; ++k) {
    const Eigen::Vector3d dir = Eigen::Vector3d(uni(rng) - 0.5, uni(rng) - 0.5, uni(rng) - 0.5).normalized();
    const double h = e.support(dir);
    // The plane dir . x = h touches the ellipsoid: a ray along -dir aimed at the centre hits at distance
    // (start - h) when started at start * dir.
    const Eigen::Vector3d p = e.point_over(uni(rng) * 0.99 / e.ax * 0.7, uni(rng) * 0.99 / e.ay * 0.7);
    EXPECT_LE(p.dot(dir), h * (1 + 1e-12));
  }
}

TEST(EllipsoidMesh, CountsVerticesOnSurfaceOrientation) {
  const Ellipsoid e{0.1, 0.8};
  for (int level : {0, 1, 3, 5}) {
    const auto mesh = microgeom::build_ellipsoid_mesh(e, level);
    const auto buffers = microgeom::triangle_buffers(mesh);
    ASSERT_EQ(buffers.triangle_count(), microgeom::ellipsoid_mesh_triangle_count(level));
    ASSERT_EQ(mesh.n_faces(), microgeom::ellipsoid_mesh_triangle_count(level));
    const int rings = microgeom::ellipsoid_mesh_rings(level), segments = microgeom::ellipsoid_mesh_segments(level);
    EXPECT_EQ(mesh.n_vertices(), std::size_t(rings) * segments + 1);
    // A disk: V - E + F = 1, and its boundary (the rim) has `segments` vertices, all at z = 0.
    EXPECT_EQ(long(mesh.n_vertices()) - long(mesh.n_edges()) + long(mesh.n_faces()), 1);
    int boundary = 0;
    for (const auto vh : mesh.vertices()) {
      const auto& p = mesh.point(vh);
      EXPECT_NEAR(implicit(e, {p[0], p[1], p[2]}), 0.0, 1e-14);
      EXPECT_GE(p[2], 0.0);
      if (mesh.is_boundary(vh)) {
        ++boundary;
        EXPECT_EQ(p[2], 0.0);
      }
    }
    EXPECT_EQ(boundary, segments);
    // Outward orientation, and the projected (footprint) area equals that of the rim polygon, an
    // inscribed (segments)-gon of the footprint ellipse: (segments / 2) sin(2 pi / segments) / (ax ay).
    double projected = 0.0;
    for (std::size_t f = 0; f < buffers.triangle_count(); ++f) {
      Eigen::Vector3d p[3];
      for (int k = 0; k < 3; ++k) {
        const auto i = buffers.indices[3 * f + k];
        const auto& q = mesh.point(microgeom::EllipsoidTriMesh::VertexHandle(int(i)));
        p[k] = {q[0], q[1], q[2]};
      }
      const Eigen::Vector3d area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]);
      const Eigen::Vector3d centroid = (p[0] + p[1] + p[2]) / 3.0;
      EXPECT_GT(area.dot(Eigen::Vector3d(e.ax * e.ax * centroid.x(), e.ay * e.ay * centroid.y(), centroid.z())), 0.0);
      EXPECT_NEAR((buffers.face_normals[f] - area.normalized()).norm(), 0.0, 1e-12);
      EXPECT_GE(area.z(), 0.0);
      projected += area.z();
    }
    const double polygon = 0.5 * segments * std::sin(2.0 * std::numbers::pi / segments) / (e.ax * e.ay);
    EXPECT_NEAR(projected, polygon, 1e-9 * polygon) << level;
  }
  EXPECT_THROW(microgeom::build_ellipsoid_mesh(e, -1), microgeom::EllipsoidMeshError);
  EXPECT_THROW(microgeom::build_ellipsoid_mesh(e, microgeom::kMaxEllipsoidMeshLevel + 1), microgeom::EllipsoidMeshError);
  EXPECT_THROW(microgeom::build_ellipsoid_mesh(Ellipsoid{0.0, 1.0}, 2), microgeom::EllipsoidMeshError);
}

TEST(EllipsoidMesh, WritesPlyAndObjThatReadBack) {
  const auto dir = std::filesystem::temp_directory_path() / ("microsim_mesh_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto mesh = microgeom::build_ellipsoid_mesh(Ellipsoid{0.5, 0.5}, 2);
  for (const char* name : {"e.ply", "e.obj"}) {
    const auto path = dir / name;
    microgeom::write_ellipsoid_mesh(mesh, path);
    microgeom::EllipsoidTriMesh back;
    ASSERT_TRUE(OpenMesh::IO::read_mesh(back, path.string())) << name;
    EXPECT_EQ(back.n_vertices(), mesh.n_vertices()) << name;
    EXPECT_EQ(back.n_faces(), mesh.n_faces()) << name;
  }
  EXPECT_THROW(microgeom::write_ellipsoid_mesh(mesh, dir / "e.xyz"), microgeom::EllipsoidMeshError);
  EXPECT_THROW(microgeom::write_ellipsoid_mesh(mesh, dir / "no_such_dir" / "e.ply"), microgeom::EllipsoidMeshError);
  // Only the two meshes: no temporary files left behind.
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir), std::filesystem::directory_iterator{}), 2);
  std::filesystem::remove_all(dir);
}

}  // namespace test_ellipsoid_geometry
