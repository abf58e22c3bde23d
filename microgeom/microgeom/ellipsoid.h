// microgeom: the GGX ellipsoid of Heitz 2018 ("Sampling the GGX Distribution of Visible Normals",
// JCGT 7(4), sec. 2): the upper half of the ellipsoid with semi-axes (1/ax, 1/ay, 1),
//   ax^2 x^2 + ay^2 y^2 + z^2 = 1, z >= 0,
// has, per unit of footprint area, exactly the GGX normal distribution D(m). Its footprint is the
// ellipse ax^2 x^2 + ay^2 y^2 <= 1 of area pi / (ax ay).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>

namespace microgeom {

// A ray's crossing of the full ellipsoid surface ax^2 x^2 + ay^2 y^2 + z^2 = 1.
struct EllipsoidHit {
  double t;               // ray parameter: point = origin + t * dir
  Eigen::Vector3d point;  // on the surface to round-off
  Eigen::Vector3d normal; // unit, outward (gradient (ax^2 x, ay^2 y, z) normalised)
  bool entering;          // true for the entry root (the ray crosses from outside to inside)
};

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

  // Exact ray - full-ellipsoid intersection in double: the nearest crossing with t in [tnear, tfar], or
  // nullopt. Done in the unit-sphere space (x', y', z') = (ax x, ay y, z), where the ray's closest-approach
  // vector f gives the discriminant 1 - |f|^2 without the cancellation of b^2 - c (Haines et al. 2019,
  // "Precision Improvements for Ray/Sphere Intersection", Ray Tracing Gems ch. 7), the near root is c / q
  // with q = -b - sign(b) sqrt(disc) (no subtraction of nearly equal numbers), and the hit point is
  // f -/+ sqrt(disc) d_hat (accurate even at grazing incidence, where the normal is nearly f itself).
  // `dir` need not be unit length; t is in units of |dir|. A zero or non-finite ray returns nullopt.
  std::optional<EllipsoidHit> intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double tnear,
                                        double tfar) const;
  // Half-extent of the full ellipsoid along the unit direction e (its support function):
  // sqrt(ex^2/ax^2 + ey^2/ay^2 + ez^2).
  double support(const Eigen::Vector3d& e) const;
};

}  // namespace microgeom
