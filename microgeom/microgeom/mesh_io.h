// microgeom: heightfield meshes through OpenMesh (PLY, OBJ; also OFF and STL).
//
// The mesh of a crop of C x C cells starting at cell (0, 0) (C = N: the whole tile) has (C + 1)^2 vertices
// (i h, j h, height(i, j)) with wrap-around heights, so the whole tile's last row and column repeat the
// first ones shifted by L, and 2 C^2 triangles split exactly as in heightfield.h (diagonal from (i, j) to
// (i+1, j+1), counter-clockwise from +z). Face k of the mesh is triangle t = k % 2 of cell
// (i, j) = ((k/2) % C, (k/2) / C). Memory: OpenMesh needs about 150 bytes per triangle, so use a crop for
// tiles above ~2048^2.
#pragma once

#include "microgeom/heightfield.h"

#include <filesystem>

namespace microgeom {

// Writes the crop (crop_cells = 0 or N: the whole tile) with OpenMesh::IO::write_mesh; the format follows
// the extension (.ply and .stl binary, .obj and .off ASCII with 9 significant digits, enough for floats).
// Written to a temporary file in the same directory and renamed: nothing is ever half-written. Throws
// std::runtime_error naming the path on an unknown extension, a crop outside [1, N], or an I/O failure.
void write_heightfield_mesh(const std::filesystem::path& path, const Heightfield& field, int crop_cells = 0);

}  // namespace microgeom
