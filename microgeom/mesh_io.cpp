#include "microgeom/mesh_io.h"

#include "core/atomic_file.h"

// OpenMesh's IO header must come before the mesh kernel (it registers the readers/writers).
#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>

#include <fmt/core.h>

#include <algorithm>
#include <cctype>
#include <stdexcept>

namespace microgeom {

namespace {
struct HeightfieldMeshTraits : public OpenMesh::DefaultTraits {
  typedef OpenMesh::Vec3f Point;
  VertexAttributes(OpenMesh::Attributes::None);
  FaceAttributes(OpenMesh::Attributes::None);
  EdgeAttributes(OpenMesh::Attributes::None);
  HalfedgeAttributes(OpenMesh::Attributes::PrevHalfedge);
};
using HeightfieldTriMesh = OpenMesh::TriMesh_ArrayKernelT<HeightfieldMeshTraits>;
}  // namespace

void write_heightfield_mesh(const std::filesystem::path& path, const Heightfield& field, int crop_cells) {
  const int n = field.resolution();
  const int c = crop_cells == 0 ? n : crop_cells;
  if (c < 1 || c > n)
    throw std::runtime_error(fmt::format("mesh '{}': crop of {} cells is outside [1, {}]", path.string(), crop_cells, n));
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char ch) { return char(std::tolower(ch)); });
  if (ext != ".ply" && ext != ".obj" && ext != ".off" && ext != ".stl")
    throw std::runtime_error(fmt::format("mesh '{}': unknown format '{}' (use .ply or .obj)", path.string(), ext));

  HeightfieldTriMesh mesh;
  mesh.reserve(std::size_t(c + 1) * (c + 1), 3 * std::size_t(c) * c + 2 * c, 2 * std::size_t(c) * c);
  const double h = field.cell_size();
  std::vector<HeightfieldTriMesh::VertexHandle> v(std::size_t(c + 1) * (c + 1));
  for (int j = 0; j <= c; ++j)
    for (int i = 0; i <= c; ++i)
      v[std::size_t(j) * (c + 1) + i] =
          mesh.add_vertex(HeightfieldTriMesh::Point(float(i * h), float(j * h), field.height(i, j)));
  auto at = [&](int i, int j) { return v[std::size_t(j) * (c + 1) + i]; };
  for (int j = 0; j < c; ++j)
    for (int i = 0; i < c; ++i) {
      mesh.add_face(at(i, j), at(i + 1, j), at(i + 1, j + 1));      // t = 0
      mesh.add_face(at(i, j), at(i + 1, j + 1), at(i, j + 1));      // t = 1
    }

  OpenMesh::IO::Options options;
  if (ext == ".ply" || ext == ".stl") options += OpenMesh::IO::Options::Binary;
  microsim::write_file_atomically(path, [&](const std::filesystem::path& tmp) {
    // OpenMesh logs on its info stream; keep stdout/stderr for our own messages.
    const bool log_was_enabled = omlog().is_enabled(), err_was_enabled = omerr().is_enabled();
    omlog().disable();
    omerr().disable();  // failures are reported by our exception, naming the path
    bool written = false;
    try {
      written = OpenMesh::IO::write_mesh(mesh, tmp.string(), options, 9);
    } catch (...) {
      written = false;
    }
    if (log_was_enabled) omlog().enable();
    if (err_was_enabled) omerr().enable();
    if (!written) throw std::runtime_error(fmt::format("cannot write mesh '{}'", path.string()));
  });
}

}  // namespace microgeom
