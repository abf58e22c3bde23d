// microgeom: the truncated GGX ellipsoid (upper half, z >= 0, semi-axes 1/ax, 1/ay, 1) as a triangle mesh.
//
// Parameterization. The ellipsoid is the image of the unit upper hemisphere under the linear map
// S^-1 = diag(1/ax, 1/ay, 1); linear maps send triangles to triangles and act on normals by S (up to
// normalisation), so a tessellation of the hemisphere that is uniform in its normals is uniform in the
// "alpha = 1" configuration of the ellipsoid's normals whatever (ax, ay) (the hemisphere configuration of
// Heitz 2018, JCGT 7(4), sec. 3). We tessellate the hemisphere by a latitude/longitude grid uniform in
// the polar angle theta' in [0, pi/2] and the azimuth phi: in footprint coordinates
//   (x, y) = (sin theta' cos phi / ax, sin theta' sin phi / ay),  z = cos theta',
// so the rings crowd towards the rim (dr = cos theta' dtheta'), where the normal turns fastest with the
// footprint position. Level K has 2^(K+1) rings and 2^(K+3) azimuthal segments: a fan of triangles
// around the pole and two triangles per remaining grid cell, 2^(2K+5) - 2^(K+3) triangles
// (K = 0: 24, K = 4: 8064, K = 8: 2 095 104). Every vertex lies exactly on the surface (computed in
// double); the rim ring has z = 0 exactly. Faces are oriented outwards (counter-clockwise seen from
// outside).
#pragma once

#include "microgeom/ellipsoid.h"

// OpenMesh's IO header must come before the mesh kernel (it registers the readers/writers).
#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <vector>

namespace microgeom {

// Double-precision points: the vertices are computed in double and only rounded to float for Embree.
struct EllipsoidMeshTraits : public OpenMesh::DefaultTraits {
  typedef OpenMesh::Vec3d Point;
  typedef OpenMesh::Vec3d Normal;
};
using EllipsoidTriMesh = OpenMesh::TriMesh_ArrayKernelT<EllipsoidMeshTraits>;

inline constexpr int kMaxEllipsoidMeshLevel = 9;  // 8.4 million triangles; beyond that memory limits

struct EllipsoidMeshError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Rings and azimuthal segments of level K (see the header comment).
int ellipsoid_mesh_rings(int level);
int ellipsoid_mesh_segments(int level);
std::size_t ellipsoid_mesh_triangle_count(int level);

// Builds the mesh of level K in [0, kMaxEllipsoidMeshLevel]; throws EllipsoidMeshError otherwise.
EllipsoidTriMesh build_ellipsoid_mesh(const Ellipsoid& ellipsoid, int level);

// Flat buffers for a ray tracer: float positions (x, y, z per vertex), uint32 indices (3 per triangle),
// and per-triangle unit outward normals computed in double from the double vertices.
struct TriangleBuffers {
  std::vector<float> vertices;
  std::vector<std::uint32_t> indices;
  std::vector<Eigen::Vector3d> face_normals;
  std::size_t vertex_count() const { return vertices.size() / 3; }
  std::size_t triangle_count() const { return indices.size() / 3; }
};
TriangleBuffers triangle_buffers(const EllipsoidTriMesh& mesh);

// Writes the mesh with OpenMesh::IO::write_mesh; the format follows the extension (.ply, .obj, also
// .off/.stl). Written to a temporary file in the same directory (same extension) and renamed, so nothing
// is ever half-written. Throws EllipsoidMeshError on an unknown extension or an I/O failure.
void write_ellipsoid_mesh(const EllipsoidTriMesh& mesh, const std::filesystem::path& path);

}  // namespace microgeom
