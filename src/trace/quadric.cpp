#include "trace/quadric.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace microsim {

void check_quadric_roughness(double ax, double ay) {
  const auto in_range = [](double a) { return a >= kMinAlpha && a <= kQuadricMaxAlpha; };  // false for NaN
  const bool ok = in_range(ax) && in_range(ay) &&
                  std::max(ax, ay) <= kQuadricMaxAnisotropy * (1 + 1e-12) * std::min(ax, ay);
  if (ok) return;
  throw UnsupportedRoughness(fmt::format(
      "ellipsoid roughness ({:g}, {:g}) is outside the range where the traced quadric is verified: alpha in "
      "[{:g}, {:g}] per axis and anisotropy max/min <= {:g}",
      ax, ay, kMinAlpha, kQuadricMaxAlpha, kQuadricMaxAnisotropy));
}

QuadricEllipsoid::QuadricEllipsoid(const microgeom::Ellipsoid& ellipsoid) : ellipsoid_(ellipsoid) {
  check_quadric_roughness(ellipsoid.ax, ellipsoid.ay);
}

unsigned int QuadricEllipsoid::attach(embree::Scene& scene) {
  return scene.add_user_geometry(1, this, {&QuadricEllipsoid::bounds, &QuadricEllipsoid::intersect,
                                           &QuadricEllipsoid::occluded});
}

void QuadricEllipsoid::bounds(const RTCBoundsFunctionArguments* args) {
  const auto* self = static_cast<const QuadricEllipsoid*>(args->geometryUserPtr);
  // Half-extents 1/ax, 1/ay, 1, rounded outwards to float so that the box contains the double ellipsoid.
  const auto up = [](double x) {
    const float f = float(x);
    return double(f) >= x ? f : std::nextafter(f, std::numeric_limits<float>::infinity());
  };
  const float hx = up(1.0 / self->ellipsoid_.ax), hy = up(1.0 / self->ellipsoid_.ay), hz = 1.0f;
  RTCBounds* b = args->bounds_o;
  b->lower_x = -hx;
  b->lower_y = -hy;
  b->lower_z = -hz;
  b->upper_x = hx;
  b->upper_y = hy;
  b->upper_z = hz;
}

void QuadricEllipsoid::intersect(const RTCIntersectFunctionNArguments* args) {
  const auto* self = static_cast<const QuadricEllipsoid*>(args->geometryUserPtr);
  RTCRayN* rays = RTCRayHitN_RayN(args->rayhit, args->N);
  RTCHitN* hits = RTCRayHitN_HitN(args->rayhit, args->N);
  const unsigned int n = args->N;
  for (unsigned int i = 0; i < n; ++i) {
    if (args->valid[i] != -1) continue;
    const Eigen::Vector3d o(RTCRayN_org_x(rays, n, i), RTCRayN_org_y(rays, n, i), RTCRayN_org_z(rays, n, i));
    const Eigen::Vector3d d(RTCRayN_dir_x(rays, n, i), RTCRayN_dir_y(rays, n, i), RTCRayN_dir_z(rays, n, i));
    const float tnear = RTCRayN_tnear(rays, n, i), tfar = RTCRayN_tfar(rays, n, i);
    const auto hit = self->ellipsoid_.intersect(o, d, tnear, tfar);
    if (!hit) continue;
    // t is in [tnear, tfar] in double; rounding to nearest keeps it there because both ends are floats.
    RTCRayN_tfar(rays, n, i) = float(hit->t);
    RTCHitN_Ng_x(hits, n, i) = float(hit->normal.x());
    RTCHitN_Ng_y(hits, n, i) = float(hit->normal.y());
    RTCHitN_Ng_z(hits, n, i) = float(hit->normal.z());
    RTCHitN_u(hits, n, i) = 0.0f;
    RTCHitN_v(hits, n, i) = 0.0f;
    RTCHitN_primID(hits, n, i) = args->primID;
    RTCHitN_geomID(hits, n, i) = args->geomID;
    for (unsigned int l = 0; l < RTC_MAX_INSTANCE_LEVEL_COUNT; ++l) {
      RTCHitN_instID(hits, n, i, l) = args->context->instID[l];
    }
  }
}

void QuadricEllipsoid::occluded(const RTCOccludedFunctionNArguments* args) {
  const auto* self = static_cast<const QuadricEllipsoid*>(args->geometryUserPtr);
  RTCRayN* rays = args->ray;
  const unsigned int n = args->N;
  for (unsigned int i = 0; i < n; ++i) {
    if (args->valid[i] != -1) continue;
    const Eigen::Vector3d o(RTCRayN_org_x(rays, n, i), RTCRayN_org_y(rays, n, i), RTCRayN_org_z(rays, n, i));
    const Eigen::Vector3d d(RTCRayN_dir_x(rays, n, i), RTCRayN_dir_y(rays, n, i), RTCRayN_dir_z(rays, n, i));
    if (self->ellipsoid_.intersect(o, d, RTCRayN_tnear(rays, n, i), RTCRayN_tfar(rays, n, i))) {
      RTCRayN_tfar(rays, n, i) = -std::numeric_limits<float>::infinity();
    }
  }
}

}  // namespace microsim
