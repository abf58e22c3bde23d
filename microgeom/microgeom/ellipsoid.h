// microgeom: the GGX ellipsoid of Heitz 2018 ("Sampling the GGX Distribution of Visible Normals",
// JCGT 7(4), sec. 2): the upper half of the ellipsoid with semi-axes (1/ax, 1/ay, 1),
//   ax^2 x^2 + ay^2 y^2 + z^2 = 1, z >= 0,
// has, per unit of footprint area, exactly the GGX normal distribution D(m). Its footprint is the
// ellipse ax^2 x^2 + ay^2 y^2 <= 1 of area pi / (ax ay).
#pragma once

#include <Eigen/Core>

namespace microgeom {

struct Ellipsoid {
  double ax = 1, ay = 1;

  // Point of the upper half over the footprint point (x, y); z = 0 on and outside the rim.
  Eigen::Vector3d point_over(double x, double y) const;
  // Unit outward normal at a point of the surface: proportional to the gradient (ax^2 x, ay^2 y, z).
  Eigen::Vector3d normal_at(const Eigen::Vector3d& p) const;
  // Uniform point of the footprint ellipse from u in [0,1)^2 (polar map of the unit disk, stretched by
  // (1/ax, 1/ay): a linear map keeps uniformity).
  Eigen::Vector2d footprint_point(double u1, double u2) const;
  // An "ellipsoid facet": the normal over a uniform footprint point. Its distribution is D(m) m.z
  // (GGX), i.e. its slopes have the density P22 exactly.
  Eigen::Vector3d sample_facet_normal(double u1, double u2) const;
  double footprint_area() const;
};

}  // namespace microgeom
