// microsim: DirectionBinning::bin_of, made cheap for the tracers' inner loops (the binning kernel).
//
// bin_of normalises the direction, maps it to its parameter space (u = w for sphere bins, u =
// normalize(wx/ax, wy/ay, wz) for lobe bins), and takes row = floor((z_max - u.z) / dz), col =
// floor(atan2(u.y, u.x) / dphi).
//
// operator() (double): the column comes from (x, y) of the unnormalised point (only its direction
// matters) by a polynomial arctangent (Abramowitz & Stegun 1964, eq. 4.4.47: |error| <= 1e-5 rad on
// [0, 1]) checked against the precomputed sector edges by cross-product signs; the row from u.z computed
// with one square root and one division. Whenever the point is within a relative 1e-9 of a row edge or
// 1e-12 of a column edge, at the pole, or the binning is one it does not specialise (reflected-direction
// lobes, fewer than 8 columns), bin_of itself decides: the result always equals bin_of (tested on
// millions of directions, edges included).
//
// bin_floats() bins a batch of single-precision directions (the tracer's Embree normals) in two passes:
// pass 1, branch-free in float, computes the fractional row index r = (z_max - u.z) / dz and column
// index c = phi / dphi with absolute errors (in bin widths) below 6e-7 x rows and 4e-7 x cols (float
// round-off of the normalisation, the arctangent polynomial of A&S 4.4.49 with |error| <= 2e-8 rad, and
// the octant map; fused multiply-adds, where the target has them, are more accurate, so the bounds
// hold with and without). A direction whose r lies within 1e-5 x rows of an integer, or c within
// 1e-5 x cols (guard bands over 16 times those errors), or that is degenerate or near under/overflow, is
// marked kNeedsExact, and pass 2 bins it by bin_of itself (about 2e-5 (rows + cols) of all directions;
// beyond 2500 rows the bands would exceed a twentieth of a bin and bin_of does all). The result equals
// bin_of(Vec3<double>(x, y, z)) exactly, whichever code ran pass 1.
//
// Pass 1 is written once, with Google Highway (portable SIMD): the widest instruction set the CPU has
// is chosen at run time (AVX-512, AVX2 + FMA, SSE4, SSSE3 on x86; NEON, SVE on Arm; ...). A batch's
// last n mod (vector width) directions, and every direction in bin_floats_scalar(), go through the plain
// scalar loop: the reference of the vector code (tests/stats/test_direction_binner.cpp compares them).
#pragma once

#include "stats/binning.h"

#include <limits>
#include <string>
#include <vector>

namespace microsim {

class FastDirectionBinner {
public:
  explicit FastDirectionBinner(const DirectionBinning& binning);
  // The bin of a direction, or -1 where bin_of returns nullopt (a plain int: no std::optional in the
  // inner loop).
  int operator()(const Vec3<double>& direction) const;
  // bins[i] = the bin of (x[i], y[i], z[i]) for i < n, or -1 where bin_of returns nullopt.
  void bin_floats(const float* x, const float* y, const float* z, int n, int* bins) const;
  // The same with pass 1 in the scalar reference loop only (tests and benchmarks).
  void bin_floats_scalar(const float* x, const float* y, const float* z, int n, int* bins) const;

  // Pass 1 alone (tests): bins[i] = the bin where it is certain, -1 where the direction is certainly
  // outside the parameter space, kNeedsExact where bin_of must decide. `vector`: the run-time chosen
  // vector code (then the scalar loop for the tail), else the scalar loop for all. Returns the number of
  // kNeedsExact. Only for binnings that pass 1 specialises (specialised_for_floats(); else throws
  // std::logic_error).
  static constexpr int kNeedsExact = std::numeric_limits<int>::min();
  int classify_floats(const float* x, const float* y, const float* z, int n, int* bins, bool vector) const;
  // Whether bin_floats runs pass 1 at all (false: it calls bin_of for every direction).
  bool specialised_for_floats() const { return !float_exact_only_; }

private:
  int exact(const Vec3<double>& direction) const { return binning_->bin_of(direction).value_or(-1); }
  // Pass 1 (vector: the chosen target's code, then the scalar loop for the tail), then pass 2.
  void classify(const float* x, const float* y, const float* z, int n, int* bins, bool vector) const;
  void bin(const float* x, const float* y, const float* z, int n, int* bins, bool vector) const;
  const DirectionBinning* binning_;
  bool lobe_ = false, exact_only_ = false, float_exact_only_ = false;
  double inv_ax_ = 1, inv_ay_ = 1, z_min_ = -1, z_max_ = 1, inv_dz_ = 1, cols_per_radian_ = 1;
  int rows_ = 1, cols_ = 2;
  float row_guard_ = 0.5f, col_guard_ = 0.5f;  // guard bands of bin_floats, in bin widths
  std::vector<double> edge_cos_, edge_sin_;  // cols + 1 sector edges (edge cols = edge 0)
};

// The vector code of pass 1: Highway's targets, named as Highway names them ("AVX2", "SSE4", "EMU128", ...).
// The targets compiled in that this CPU runs, best first.
std::vector<std::string> direction_binner_targets();
// The target bin_floats runs now (the best, unless use_direction_binner_target chose another).
std::string direction_binner_target();
// Tests and benchmarks: from now on run `name`, one of direction_binner_targets(); "" goes back to the
// best. Throws std::invalid_argument for another name. A global choice: call it while no binning runs.
void use_direction_binner_target(const std::string& name);

}  // namespace microsim
