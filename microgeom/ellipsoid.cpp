#include "microgeom/ellipsoid.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace microgeom {

Eigen::Vector3d Ellipsoid::point_over(double x, double y) const {
  const double r2 = ax * ax * x * x + ay * ay * y * y;
  return {x, y, std::sqrt(std::max(0.0, 1.0 - r2))};
}

Eigen::Vector3d Ellipsoid::normal_at(const Eigen::Vector3d& p) const {
  return Eigen::Vector3d(ax * ax * p.x(), ay * ay * p.y(), p.z()).normalized();
}

Eigen::Vector2d Ellipsoid::footprint_point(double u1, double u2) const {
  const double r = std::sqrt(u1), phi = 2.0 * std::numbers::pi * u2;
  return {r * std::cos(phi) / ax, r * std::sin(phi) / ay};
}

Eigen::Vector3d Ellipsoid::sample_facet_normal(double u1, double u2) const {
  // With (x, y) = (r cos / ax, r sin / ay): the normal is proportional to (ax r cos, ay r sin, sqrt(1-r^2)),
  // written directly so that r -> 1 stays finite.
  const double r = std::sqrt(u1), phi = 2.0 * std::numbers::pi * u2;
  return Eigen::Vector3d(ax * r * std::cos(phi), ay * r * std::sin(phi), std::sqrt(std::max(0.0, 1.0 - u1)))
      .normalized();
}

double Ellipsoid::footprint_area() const { return std::numbers::pi / (ax * ay); }

}  // namespace microgeom

namespace microgeom {

std::optional<EllipsoidHit> Ellipsoid::intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir,
                                                 double tnear, double tfar) const {
  // Unit-sphere space: scale x by ax and y by ay (the ellipsoid becomes the unit sphere).
  const Eigen::Vector3d o(ax * origin.x(), ay * origin.y(), origin.z());
  const Eigen::Vector3d d(ax * dir.x(), ay * dir.y(), dir.z());
  const double speed = d.norm();  // |d'|: converts unit-speed distances s back to t = s / speed
  if (!(speed > 0.0) || !std::isfinite(speed) || !o.allFinite()) return std::nullopt;
  const Eigen::Vector3d dn = d / speed;
  const double b = o.dot(dn);                   // s^2 + 2 b s + c = 0
  const Eigen::Vector3d f = o - b * dn;         // closest approach to the centre
  const double disc = 1.0 - f.squaredNorm();    // = b^2 - c, without cancellation
  if (!(disc >= 0.0)) return std::nullopt;      // passes by (or a NaN)
  const double h = std::sqrt(disc);
  const double c = o.squaredNorm() - 1.0;       // accurate unless the origin is on the surface
  const double q = -b - std::copysign(h, b);    // |q| = |b| + h: no cancellation
  // The two roots (unit speed): q and c / q. q == 0 only for b == h == 0 (origin at the centre of a
  // degenerate tangency): then both roots are 0.
  double s_entry, s_exit;
  if (q == 0.0) {
    s_entry = s_exit = 0.0;
  } else {
    const double r1 = q, r2 = c / q;
    s_entry = std::min(r1, r2);
    s_exit = std::max(r1, r2);
  }
  auto make_hit = [&](double s, bool entering) {
    // Entry point f - h dn, exit point f + h dn (exact relations; avoids o + s dn cancellation).
    const Eigen::Vector3d p = entering ? Eigen::Vector3d(f - h * dn) : Eigen::Vector3d(f + h * dn);
    const Eigen::Vector3d normal = Eigen::Vector3d(ax * p.x(), ay * p.y(), p.z()).normalized();
    return EllipsoidHit{s / speed, Eigen::Vector3d(p.x() / ax, p.y() / ay, p.z()), normal, entering};
  };
  const double t_entry = s_entry / speed, t_exit = s_exit / speed;
  if (t_entry >= tnear && t_entry <= tfar) return make_hit(s_entry, true);
  if (t_exit >= tnear && t_exit <= tfar) return make_hit(s_exit, false);
  return std::nullopt;
}

double Ellipsoid::support(const Eigen::Vector3d& e) const {
  return std::sqrt(e.x() * e.x() / (ax * ax) + e.y() * e.y() / (ay * ay) + e.z() * e.z());
}

}  // namespace microgeom
