// microsim: the steps of the min-max pyramid walk (heightfield_pyramid.h) in SIMD lanes, one ray per lane,
// a lane refilled with the next ray as soon as its ray is done (the per-lane traversal with refill of Aila
// and Laine 2009, "Understanding the Efficiency of Ray Traversal on GPUs", section 3, on a CPU's vector
// lanes): the kernel of PyramidTracer::trace_batch. Node steps and cells without a hit run in the lanes;
// a cell that may hold the hit, a ray's start and its end are PyramidTracer's scalar code
// (heightfield_pyramid.cpp). Compiled once per Highway target and dispatched at run time
// (heightfield_pyramid_lanes.cpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace microsim::pyramid_lanes {

inline constexpr std::size_t kMaxLanes = 64;

// The walks in the lanes, structure of arrays; the fields of PyramidTracer's Walk and its level k.
struct State {
  alignas(64) double ox[kMaxLanes], oy[kMaxLanes], oz[kMaxLanes];  // origin, x and y in cells
  alignas(64) double dx[kMaxLanes], dy[kMaxLanes], dz[kMaxLanes];  // direction, x and y in cells
  alignas(64) double idx[kMaxLanes], idy[kMaxLanes];                // 1 / dx, 1 / dy (0 where dx, dy = 0)
  alignas(64) double t[kMaxLanes], g[kMaxLanes];                   // the walk's t, g at the cell entry
  alignas(64) std::int64_t sx[kMaxLanes], sy[kMaxLanes];  // signs of dx, dy
  alignas(64) std::int64_t ci[kMaxLanes], cj[kMaxLanes], k[kMaxLanes];
  alignas(64) std::int64_t entry[kMaxLanes], g_known[kMaxLanes];
  alignas(64) std::int64_t tile_x[kMaxLanes], tile_y[kMaxLanes], wraps[kMaxLanes];
  // Set by a step: 0 goes on, 1 escaped, 2 leaked, 3 unresolved; 4: no ray in the lane.
  alignas(64) std::int64_t done[kMaxLanes];
};

// The tracer's constants.
struct Grid {
  const std::uint64_t* nodes = nullptr;  // HeightPyramid::nodes(): {min, max} floats, min in the low bits
  const float* heights = nullptr;        // the heightfield's, row by row
  const double* level_offset = nullptr;  // [k], k = 0 .. top: level_offset(k) (0 for k = 0)
  double margin = 0, escape_height = 0, floor_height = 0;
  std::int64_t n = 0, top = 0, max_segments = 0;
  bool prefetch = false;  // prefetch every lane's next read before the steps
};

// One step of every lane i < lanes with done[i] = 0, as PyramidTracer::step with the same
// expressions: a node entered (k - 1) or passed (the walk advanced, k up if it left the parent), a cell
// over which g = z - surface height keeps its sign passed likewise, or the walk ended (done). A cell
// where g may change sign (a hit, unless the start triangle) is left to the scalar step(). A lane at a
// cell may wait a step (a
// vector's cell tests wait for two of its lanes at cells). Returns bit i set for the lanes with
// done[i] != 0 or a cell for step().
std::uint64_t step(const Grid& grid, State& state, std::size_t lanes);
// Doubles per vector of the target chosen for this CPU, and its name.
std::size_t vector_lanes();
std::string target_name();
// Tests choose the target with stats/direction_binner.h's use_direction_binner_target: Highway's choice is
// process-wide, the same for every kernel.

}  // namespace microsim::pyramid_lanes
