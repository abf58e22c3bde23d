// microsim: the exact GGX ellipsoid as an Embree user geometry (one primitive).
//
// Embree hands the callback a single-precision ray; the intersection itself is computed in double by
// microgeom::Ellipsoid::intersect (unit-sphere space, stable quadratic, see its comment), and the hit
// reports the nearest crossing of the FULL ellipsoid with t in [tnear, tfar], with Ng = the unit analytic
// outward normal (gradient (ax^2 x, ay^2 y, z) at the exact intersection of that float ray, rounded to
// float only at the end), u = v = 0. Callers decide what to keep (the VNDF tracer keeps entering hits
// with z >= 0, i.e. Ng.z >= 0).
#pragma once

#include "microgeom/ellipsoid.h"
#include "trace/embree.h"
#include "microfacet/ggx.h"

#include <stdexcept>

namespace microsim {

// The roughness over which the traced quadric is a verified oracle for D_v: alpha in
// [kMinAlpha, kQuadricMaxAlpha] = [1e-4, 10] per axis and anisotropy max/min <= kQuadricMaxAnisotropy
// = 1000 (the supported range of the command line, docs/reference/conventions.md). Why these bounds:
// - Measured (tests/test_trace_vndf.cpp, TraceVndf.QuadricExactAtTheCornersOfItsRange; docs/reference/oracle.md,
//   "The quadric at the corners of its range"): at the corners (1e-4, 1e-4), (1e-4, 0.1), (0.1, 1e-4),
//   (10, 10), (0.01, 10), (10, 0.01), theta 0/60/85/89, 4e6 rays, the traced histogram is
//   indistinguishable from D_v in both binnings (smallest Sidak-combined p 0.17) and its TV sits at the
//   Monte Carlo floor.
// - Beyond 1:1000 the quadric itself is still right, but the oracle's comparison is not: at (1e-4, 1) the
//   traced histogram and the analytic samplers (heitz2018, dupuy2023) agree with each other (two-sample
//   p 0.85 / 0.21), and both are rejected in sphere bins (p ~1e-30) because the cubature of the expected
//   counts misses 7e-5 of D_v's mass (the lobe is a strip 1e-4 wide through the pole; the claimed-pdf
//   integral is 0.999931). At 1:1000 it misses < 4e-8 (4e6 rays: < 0.2 expected counts).
// - Below kMinAlpha GGX clamps the roughness (ggx.h), so there is no D_v to compare with.
inline constexpr double kQuadricMaxAlpha = kMaxSupportedAlpha;
inline constexpr double kQuadricMaxAnisotropy = kMaxSupportedAnisotropy;

// A roughness outside the quadric's verified range (a std::invalid_argument, so callers that catch that
// keep working).
class UnsupportedRoughness : public std::invalid_argument {
public:
  using std::invalid_argument::invalid_argument;
};

// Throws UnsupportedRoughness naming (alpha_x, alpha_y) and the range unless both are in
// [kMinAlpha, kQuadricMaxAlpha] and max/min <= kQuadricMaxAnisotropy (relative slack 1e-12, so that
// 1e-4 and 0.1 are the 1:1000 they are written as).
void check_quadric_roughness(double alpha_x, double alpha_y);

class QuadricEllipsoid {
public:
  // Throws UnsupportedRoughness outside the verified range (check_quadric_roughness).
  explicit QuadricEllipsoid(const microgeom::Ellipsoid& ellipsoid);
  // Adds this geometry to the scene (this object must outlive the scene's tracing); returns the geomID.
  unsigned int attach(embree::Scene& scene);
  const microgeom::Ellipsoid& ellipsoid() const { return ellipsoid_; }

  // The Embree callbacks (public for tests).
  static void bounds(const RTCBoundsFunctionArguments* args);
  static void intersect(const RTCIntersectFunctionNArguments* args);
  static void occluded(const RTCOccludedFunctionNArguments* args);

private:
  microgeom::Ellipsoid ellipsoid_;
};

}  // namespace microsim
