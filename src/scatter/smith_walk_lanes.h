// scatter: the Smith random walk (smith_walk.h) with paths in SIMD lanes, the vector kernel of
// WalkKernel::lanes. Internal to scatter: smith_walk.cpp runs it per block and reduces its ends as it reduces
// the scalar walk's.
//
// The same walk as the scalar one (Heitz, Hanika, d'Eon, Dachsbacher 2016, sec. 3-5), in double, for the
// case it covers: GGX (isotropic or anisotropic), uniform heights followed through g = ln C1(h), a mirror, a
// conductor (F per channel) or a dielectric (lit from either side). The paths of a block occupy the lanes of a vector (Google
// Highway: the widest instruction set the CPU has, chosen at run time, as stats/direction_binner.cpp does);
// every meeting is computed for all lanes at once, the branches (escape or meet, the order cap, a lost path)
// are lane masks, and a lane whose path ended takes the block's next path. Path j of block b draws
// mix64(K_b + 0x9e3779b97f4a7c15 i) for i = j 2^32 + 1, 2, ... (CounterRng's form, core/random.h, with the
// block's key K_b = the first draw of CounterRng(seed, b)), three numbers per step (the height's, then the
// normal's two, which an escaping step leaves unused; a dielectric's fourth chooses reflection or
// refraction), so a path's numbers depend on (seed, b, j) only; its end is stored at index j. The result is a function of (seed, blocks) whatever the threads, shards or lane count, but not
// the scalar walk's numbers (another order of the random numbers, and Highway's Log, Sin, Cos differ from
// the C library's in the last bits): the two agree statistically (tests/scatter/test_smith_walk_lanes.cpp).
#pragma once

#include "microfacet/material.h"
#include "stats/direction_binner.h"

#include <array>
#include <cstdint>
#include <string>

namespace microsim::walk_lanes {

// What the kernel needs of a walk: the surface, the light, the material, the cap, the seed.
struct LaneWalk {
  double alpha_x = 0.5, alpha_y = 0.5;
  double wi[3] = {0, 0, 1};  // toward the light, global (wi[2] < 0: from inside, a dielectric only)
  int max_order = 100;
  int channels = 1;
  bool conductor = false;   // F per channel
  bool dielectric = false;  // of relative index eta (inside / outside); neither: the mirror, F = 1
  double eta = 1.5;
  std::array<double, Material::kMaxChannels> n{}, k{};  // the conductor's eta = n + i k per channel
  std::uint64_t seed = 1;
};

// How a path ended (smith_walk.cpp's WalkEnd without the bin).
struct LaneEnd {
  int kind;   // 0 escaped, 1 unfinished (the order cap), 2 lost
  int order;  // facet events
  double x, y, z;  // the last direction (global); escaped: the outgoing direction
};

// Walks the `paths` paths of block `block`: ends[j] and weights[j * channels + c] for path j.
void walk_block(const LaneWalk& walk, std::uint64_t block, std::uint64_t paths, LaneEnd* ends, double* weights);

// The bins of the n escaped directions ends[i] (kind 0; the others get -1), exactly as `bins`' operator()
// (= DirectionBinning::bin_of) bins them, for a binner of a hemispheres binning (the walk's histogram): pass 1
// of its float batch code (FastDirectionBinner::classify_floats, vector) on the directions rounded to float,
// then operator() on the double direction wherever pass 1 is not certain. Exact: rounding to float moves a
// unit direction by at most about 2^-23 (a relative 2^-24 per component), so its fractional row index by
// 2^-23 rows / 2 and its column index by 2^-23 cols / (2 pi) bin widths (rows and cols of the whole sphere),
// a hundredth of pass 1's guard bands (1e-5 rows and 1e-5 cols bin widths, direction_binner.h), which
// already hold 16 times pass 1's own float errors. Binnings without a pass 1 use operator() throughout.
void bin_escaped(const FastDirectionBinner& bins, const LaneEnd* ends, int n, int* out);

// Tests: the kernel's (cos 2 pi u, sin 2 pi u) for the first k u[i], k the largest multiple of the vector
// width <= n (returned).
std::size_t sincos_two_pi(const double* u, std::size_t n, double* c, double* s);

// The Highway target walk_block runs ("AVX3", "AVX2", "SSE4", ...).
std::string walk_lanes_target();

}  // namespace microsim::walk_lanes
