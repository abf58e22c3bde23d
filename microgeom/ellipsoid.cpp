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
