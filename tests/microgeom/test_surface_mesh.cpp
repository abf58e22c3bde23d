// Tests of the heightfield mesh export through OpenMesh (microgeom/mesh_io.h).
#include "microgeom/heightfield.h"
#include "microgeom/mesh_io.h"
#include "scratch_dir.h"

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <gtest/gtest.h>

#include <unistd.h>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_surface_mesh {

namespace fs = std::filesystem;

namespace {
microgeom::Heightfield ramp_field(int n) {
  std::vector<float> h(std::size_t(n) * n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) h[std::size_t(j) * n + i] = 0.01f * float(i * i + 3 * j);
  return microgeom::Heightfield(n, 2.0, std::move(h));
}
fs::path scratch_dir() { return microsim::test::scratch_dir("test", "mesh"); }
}  // namespace

TEST(SurfaceMesh, CropWritesTheDocumentedVerticesAndFaces) {
  const auto dir = scratch_dir();
  const auto field = ramp_field(8);
  for (const char* name : {"crop.obj", "crop.ply"}) {
    microgeom::write_heightfield_mesh(dir / name, field, 3);
    OpenMesh::TriMesh_ArrayKernelT<> mesh;
    ASSERT_TRUE(OpenMesh::IO::read_mesh(mesh, (dir / name).string())) << name;
    EXPECT_EQ(mesh.n_vertices(), 16u) << name;
    EXPECT_EQ(mesh.n_faces(), 18u) << name;
    // Vertex (i, j) at (i h, j h, height(i, j)); face 2 k + t is triangle t of cell (k % 3, k / 3).
    const double h = field.cell_size();
    for (auto vh : mesh.vertices()) {
      const auto p = mesh.point(vh);
      const int i = int(std::lround(p[0] / h)), j = int(std::lround(p[1] / h));
      EXPECT_NEAR(p[2], field.height(i, j), 1e-6) << name;
    }
    for (auto fh : mesh.faces()) {
      const int k = fh.idx() / 2, t = fh.idx() % 2;
      const auto expected = field.triangle_vertices(k % 3, k / 3, t);
      int corner = 0;
      for (auto vh : mesh.fv_range(fh)) {
        // OpenMesh may start the face loop at any corner: compare as a cyclic sequence.
        (void)vh;
        ++corner;
      }
      EXPECT_EQ(corner, 3);
      auto it = mesh.fv_range(fh).begin();
      std::array<OpenMesh::Vec3f, 3> p{mesh.point(*it), mesh.point(*++it), mesh.point(*++it)};
      int match = -1;
      for (int s = 0; s < 3; ++s)
        if ((Eigen::Vector3d(p[s][0], p[s][1], p[s][2]) - expected[0]).norm() < 1e-5) match = s;
      ASSERT_GE(match, 0) << name << " face " << fh.idx();
      for (int c = 0; c < 3; ++c) {
        const auto q = p[(match + c) % 3];
        EXPECT_NEAR((Eigen::Vector3d(q[0], q[1], q[2]) - expected[c]).norm(), 0.0, 1e-5) << name << " face " << fh.idx();
      }
    }
  }
  // Whole tile: (N + 1)^2 vertices, the last row/column repeating the first (wrap-around heights).
  microgeom::write_heightfield_mesh(dir / "all.ply", field);
  OpenMesh::TriMesh_ArrayKernelT<> all;
  ASSERT_TRUE(OpenMesh::IO::read_mesh(all, (dir / "all.ply").string()));
  EXPECT_EQ(all.n_vertices(), 81u);
  EXPECT_EQ(all.n_faces(), 128u);
  fs::remove_all(dir);
}

TEST(SurfaceMesh, BadRequestsThrowAndLeaveNothing) {
  const auto dir = scratch_dir();
  const auto field = ramp_field(4);
  EXPECT_THROW(microgeom::write_heightfield_mesh(dir / "x.xyz", field), std::runtime_error);
  EXPECT_THROW(microgeom::write_heightfield_mesh(dir / "x.ply", field, 5), std::runtime_error);
  EXPECT_THROW(microgeom::write_heightfield_mesh(dir / "x.ply", field, -1), std::runtime_error);
  EXPECT_THROW(microgeom::write_heightfield_mesh(dir / "missing" / "x.ply", field), std::runtime_error);
  EXPECT_TRUE(fs::is_empty(dir));
  fs::remove_all(dir);
}

}  // namespace test_surface_mesh
