#include "microgeom/ellipsoid_mesh.h"

#include "core/atomic_file.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace microgeom {

int ellipsoid_mesh_rings(int level) { return 1 << (level + 1); }
int ellipsoid_mesh_segments(int level) { return 1 << (level + 3); }
std::size_t ellipsoid_mesh_triangle_count(int level) {
  const std::size_t rings = std::size_t(ellipsoid_mesh_rings(level)), segments = std::size_t(ellipsoid_mesh_segments(level));
  return segments * (2 * rings - 1);  // a fan of `segments` around the pole, 2 per cell in the other rings
}

EllipsoidTriMesh build_ellipsoid_mesh(const Ellipsoid& e, int level) {
  if (level < 0 || level > kMaxEllipsoidMeshLevel) {
    throw EllipsoidMeshError(fmt::format("ellipsoid mesh level {} is outside [0, {}]", level, kMaxEllipsoidMeshLevel));
  }
  if (!(e.ax > 0.0) || !(e.ay > 0.0) || !std::isfinite(e.ax) || !std::isfinite(e.ay)) {
    throw EllipsoidMeshError(fmt::format("ellipsoid roughness ({}, {}) must be positive and finite", e.ax, e.ay));
  }
  const int rings = ellipsoid_mesh_rings(level), segments = ellipsoid_mesh_segments(level);
  EllipsoidTriMesh mesh;
  // A disk: Euler characteristic 1, so edges = vertices + faces - 1.
  const std::size_t n_vertices = std::size_t(rings) * segments + 1, n_faces = ellipsoid_mesh_triangle_count(level);
  mesh.reserve(n_vertices, n_vertices + n_faces - 1, n_faces);
  using VH = EllipsoidTriMesh::VertexHandle;
  const VH pole = mesh.add_vertex(EllipsoidTriMesh::Point(0.0, 0.0, 1.0));
  // Ring i (1..rings) at theta' = (i / rings) pi/2. sin and cos of the exact fraction; the rim (i = rings)
  // is set to (1, 0) exactly so that the rim vertices lie in the plane z = 0.
  std::vector<VH> ring_vertices(std::size_t(rings) * segments);
  for (int i = 1; i <= rings; ++i) {
    const double theta = 0.5 * std::numbers::pi * double(i) / double(rings);
    const double r = (i == rings) ? 1.0 : std::sin(theta);
    const double z = (i == rings) ? 0.0 : std::cos(theta);
    for (int j = 0; j < segments; ++j) {
      const double phi = 2.0 * std::numbers::pi * double(j) / double(segments);
      ring_vertices[std::size_t(i - 1) * segments + j] =
          mesh.add_vertex(EllipsoidTriMesh::Point(r * std::cos(phi) / e.ax, r * std::sin(phi) / e.ay, z));
    }
  }
  auto at = [&](int ring, int segment) { return ring_vertices[std::size_t(ring - 1) * segments + (segment % segments)]; };
  // Counter-clockwise seen from outside: with phi increasing counter-clockwise seen from +z and the rings
  // going outwards, (inner j, outer j, outer j+1) and (inner j, outer j+1, inner j+1) face outwards.
  for (int j = 0; j < segments; ++j) mesh.add_face(pole, at(1, j), at(1, j + 1));
  for (int i = 1; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      mesh.add_face(at(i, j), at(i + 1, j), at(i + 1, j + 1));
      mesh.add_face(at(i, j), at(i + 1, j + 1), at(i, j + 1));
    }
  }
  return mesh;
}

TriangleBuffers triangle_buffers(const EllipsoidTriMesh& mesh) {
  TriangleBuffers out;
  out.vertices.reserve(3 * mesh.n_vertices());
  for (const auto vh : mesh.vertices()) {
    const auto& p = mesh.point(vh);
    out.vertices.insert(out.vertices.end(), {float(p[0]), float(p[1]), float(p[2])});
  }
  out.indices.reserve(3 * mesh.n_faces());
  out.face_normals.reserve(mesh.n_faces());
  for (const auto fh : mesh.faces()) {
    Eigen::Vector3d p[3];
    int k = 0;
    for (const auto vh : mesh.fv_range(fh)) {
      if (k < 3) {
        out.indices.push_back(std::uint32_t(vh.idx()));
        const auto& q = mesh.point(vh);
        p[k] = Eigen::Vector3d(q[0], q[1], q[2]);
      }
      ++k;
    }
    if (k != 3) throw EllipsoidMeshError(fmt::format("face {} has {} vertices, not 3", fh.idx(), k));
    out.face_normals.push_back((p[1] - p[0]).cross(p[2] - p[0]).normalized());
  }
  return out;
}

void write_ellipsoid_mesh(const EllipsoidTriMesh& mesh, const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (ext != ".ply" && ext != ".obj" && ext != ".off" && ext != ".stl") {
    throw EllipsoidMeshError(fmt::format("mesh output '{}': unknown format (use .ply or .obj)", path.string()));
  }
  OpenMesh::IO::Options options;
  if (ext == ".ply" || ext == ".stl") options += OpenMesh::IO::Options::Binary;
  try {
    microsim::write_file_atomically(path, [&](const std::filesystem::path& tmp) {
      // OpenMesh logs "[OBJWriter] : write file" on its info stream; keep stdout/stderr for our own messages.
      const bool log_was_enabled = omlog().is_enabled();
      omlog().disable();
      const bool written = OpenMesh::IO::write_mesh(mesh, tmp.string(), options);
      if (log_was_enabled) omlog().enable();
      if (!written) throw EllipsoidMeshError(fmt::format("cannot write mesh '{}'", path.string()));
    });
  } catch (const microsim::FileWriteError& e) {
    throw EllipsoidMeshError(e.what());
  }
}

}  // namespace microgeom
