// microfacet: the visible normals of the upper microsurface seen from ANY direction, as the Smith random
// walk needs them (Heitz, Hanika, d'Eon, Dachsbacher 2016, "Multiple-Scattering Microfacet BSDFs with the
// Smith Model", SIGGRAPH, sec. 3: a ray travelling upward inside the microsurface, w.z > 0, hits microfacets
// m (m.z > 0) that face -w, a view from below the horizon).
//
// The zoo's convention for views below the horizon is the back side (samplers.h: sample for -v, negate),
// which a dielectric's single-scattering BSDF needs; the walk needs the other reading: the same upper
// normals, weighted by <v, m>+ D(m), for v on either side:
//   D_v^up(m) = <v, m>+ D(m) / A(v),   m.z > 0,
// with A(v) = integral of <v, m>+ D(m) = projected_area(v) for v.z >= 0 and, since the signed projected
// area is v.z for every v, A(v) = |v.z| Lambda(v) for v.z < 0 (Heitz et al. 2016 write this with the
// Lambda(v) = -1 - Lambda(-v) of downward directions: A = v.z (1 + Lambda(v))).
#pragma once

#include "microfacet/beckmann.h"
#include "microfacet/ggx.h"
#include "microfacet/samplers.h"

#include <optional>

namespace microsim {

// A(v) for GGX: (|vz| + t) / 2 above the horizon, (t - |vz|) / 2 = (ax^2 vx^2 + ay^2 vy^2) / (2 (t + |vz|))
// below (no cancellation as v turns straight down, where A -> 0).
inline double upper_visible_area(const GGX<double>& g, const Vec3<double>& v) {
  if (v.z() >= 0) return g.projected_area(v);
  const double num = sqr(g.alpha_x() * v.x()) + sqr(g.alpha_y() * v.y());
  return num / (2 * (g.stretched_length(v) - v.z()));
}
// A(v) for Beckmann: |vz| + |vz| Lambda above, |vz| Lambda below (beckmann.h masked_area).
inline double upper_visible_area(const Beckmann<double>& b, const Vec3<double>& v) {
  return v.z() >= 0 ? b.projected_area(v) : b.masked_area(v);
}

// D_v^up(v, m) per unit solid angle of m (0 for m.z <= 0, for <v, m> <= 0 and when nothing is visible).
template <class Ndf> double upper_visible_normal_pdf(const Ndf& ndf, const Vec3<double>& v, const Vec3<double>& m) {
  if (!v.allFinite() || !m.allFinite() || !(m.z() > 0)) return 0.0;
  const double vm = v.dot(m);
  if (!(vm > 0)) return 0.0;
  const double area = upper_visible_area(ndf, v);
  return area > 0 ? vm * ndf.D(m) / area : 0.0;
}

// Samples D_v^up(v, .) for GGX. Above the horizon it is the zoo's reference sampler (Heitz 2018,
// sample_heitz2018). Below it, the spherical-cap construction of Dupuy & Benyoub 2023 (samplers.h), read
// for Vh.z < 0: in the hemisphere configuration the half vectors of the unit Vh and the directions c of
// the cap z >= -Vh.z are exactly the upper normals facing Vh (c.z + Vh.z = 2 <Vh, Nh> Nh.z), and c uniform
// on the cap gives Nh the density 4 <Vh, Nh> / (2 pi (1 + Vh.z)), the visible-normal density whose
// normaliser pi (1 + Vh.z) / 2 is the stretched A(v) on both sides of the horizon. nullopt when nothing
// faces v (v straight down) or the input is not finite.
inline std::optional<Vec3<double>> sample_upper_visible_normal(const GGX<double>& g, const Vec3<double>& v,
                                                               Vec2<double> u) {
  if (!v.allFinite() || !u.allFinite()) return std::nullopt;
  if (v.z() >= 0) {
    const SampleResult<double> s = sample_heitz2018(g, v, u);
    if (!s) return std::nullopt;
    return s->direction;
  }
  u = Vec2<double>(clamp_unit(u.x()), clamp_unit(u.y()));
  const Vec3<double> vh = detail::to_hemisphere_config(g, v);
  if (!(vh.z() > -1)) return std::nullopt;
  const Vec3<double> h = detail::cap_half_vector(vh, vh.z(), 0.0, 1 - vh.z(), u);
  const double len = h.norm();
  if (!(len > 0)) return std::nullopt;
  const SampleResult<double> m = detail::from_hemisphere_config(g, Vec3<double>(h / len), 1.0);
  if (!m) return std::nullopt;
  return m->direction;
}

// Samples D_v^up(v, .) for Beckmann: the exact slope inversion (beckmann.h) covers both sides of the horizon.
inline std::optional<Vec3<double>> sample_upper_visible_normal(const Beckmann<double>& b, const Vec3<double>& v,
                                                               Vec2<double> u) {
  const Vec3<double> m = detail::beckmann_upper_visible_normal(b.alpha_x(), b.alpha_y(), v, u);
  if (m.isZero()) return std::nullopt;
  return m;
}

}  // namespace microsim
