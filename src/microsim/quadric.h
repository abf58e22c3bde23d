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
#include "microsim/embree.h"

namespace microsim {

class QuadricEllipsoid {
public:
  explicit QuadricEllipsoid(const microgeom::Ellipsoid& ellipsoid) : ellipsoid_(ellipsoid) {}
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
