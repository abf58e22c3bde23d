// microsim: single-scattering Smith-GGX BRDFs and the rough dielectric BSDF.
//
// References:
// - Walter, Marschner, Li, Torrance 2007, "Microfacet Models for Refraction through Rough Surfaces",
//   EGSR: half vectors (eq. 13, 16), reflection and transmission terms (eq. 20, 21), Fresnel (eq. 22).
// - Born & Wolf, "Principles of Optics", section 14.2: Fresnel equations for an absorbing medium
//   (complex index of refraction eta + i k), used for conductors.
//
// Conventions: z-up frame, wi and wo point away from the surface, eta is the ratio
// (index below the surface) / (index above), i.e. n_inside / n_outside. All functions return the BSDF
// value f (without the cosine factor), 0 for impossible configurations, never NaN.
#pragma once

#include "microfacet/bsdf_convention.h"
#include "microfacet/ggx.h"

#include <cmath>
#include <complex>

namespace microsim {

// Unpolarised Fresnel reflectance of a dielectric interface (Walter 2007 eq. 22), for the cosine
// cos_i of the angle between the incident direction and the (micro)normal, measured on the side the
// light comes from. eta = n_transmitted / n_incident for cos_i > 0; a negative cos_i means the light
// comes from the other side and eta is inverted. Returns 1 on total internal reflection.
template <class T> T fresnel_dielectric(T cos_i, T eta) {
  cos_i = std::clamp(cos_i, T(-1), T(1));
  if (cos_i < T(0)) {
    eta = T(1) / eta;
    cos_i = -cos_i;
  }
  const T sin2_t = (T(1) - sqr(cos_i)) / sqr(eta);
  if (sin2_t >= T(1)) return T(1);
  const T cos_t = safe_sqrt(T(1) - sin2_t);
  const T r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  const T r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
  return (sqr(r_parl) + sqr(r_perp)) / T(2);
}

// Unpolarised Fresnel reflectance of a conductor with complex relative index eta + i k (Born & Wolf
// 14.2), exact (no Schlick approximation). cos_i in [0, 1].
template <class T> T fresnel_conductor(T cos_i, std::complex<T> eta) {
  using C = std::complex<T>;
  cos_i = std::clamp(cos_i, T(0), T(1));
  const T sin2_i = T(1) - sqr(cos_i);
  const C sin2_t = C(sin2_i) / (eta * eta);
  const C cos_t = std::sqrt(C(1) - sin2_t);
  const C r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
  const C r_perp = (C(cos_i) - eta * cos_t) / (C(cos_i) + eta * cos_t);
  return (std::norm(r_parl) + std::norm(r_perp)) / T(2);
}

// Half vector of a reflection, oriented to the upper hemisphere; zero for wo == -wi.
template <class T> Vec3<T> reflection_half_vector(const Vec3<T>& wi, const Vec3<T>& wo) {
  Vec3<T> h = normalized_or_zero(Vec3<T>(wi + wo));
  return h.z() < T(0) ? Vec3<T>(-h) : h;
}

// The BSDFs below take any Smith microfacet distribution with D and G2: GGX (ggx.h) or Beckmann
// (beckmann.h); the formulas of Walter et al. 2007 hold for both.
//
// The masking-shadowing of a pair in the named form (bsdf_convention.h): Heitz 2014 eq. 99 or eq. 98.
template <class T, template <class> class Ndf>
T masking_shadowing(const Ndf<T>& ndf, const Vec3<T>& wi, const Vec3<T>& wo, MaskingForm form) {
  return form == MaskingForm::separable ? ndf.G2_separable(wi, wo) : ndf.G2(wi, wo);
}

//
// Single-scattering BRDF of a perfect mirror microsurface (F = 1): D G2 / (4 |cos i| |cos o|),
// with the height-correlated G2. Reflection only: both directions on the upper side.
// `masking` names the masking-shadowing form (the height-correlated G2 unless said).
template <class T, template <class> class Ndf>
T mirror_brdf(const Ndf<T>& ggx, const Vec3<T>& wi, const Vec3<T>& wo,
              MaskingForm masking = MaskingForm::height_correlated) {
  if (!(wi.z() > T(0) && wo.z() > T(0))) return T(0);
  const Vec3<T> m = reflection_half_vector(wi, wo);
  if (!(wi.dot(m) > T(0) && wo.dot(m) > T(0))) return T(0);
  return ggx.D(m) * masking_shadowing(ggx, wi, wo, masking) / (T(4) * wi.z() * wo.z());
}

// Single-scattering BRDF of a conductor: F(<wi, m>) D G2 / (4 cos i cos o).
template <class T, template <class> class Ndf>
T conductor_brdf(const Ndf<T>& ggx, std::complex<T> eta, const Vec3<T>& wi, const Vec3<T>& wo,
                 MaskingForm masking = MaskingForm::height_correlated) {
  if (!(wi.z() > T(0) && wo.z() > T(0))) return T(0);
  const Vec3<T> m = reflection_half_vector(wi, wo);
  const T im = wi.dot(m);
  if (!(im > T(0) && wo.dot(m) > T(0))) return T(0);
  return fresnel_conductor(im, eta) * ggx.D(m) * masking_shadowing(ggx, wi, wo, masking) / (T(4) * wi.z() * wo.z());
}

// The height-correlated masking-shadowing of a REFRACTED pair on the Smith microsurface: the two ends of
// the path are on opposite sides, so seen from the transmitted side the first point, at height h with
// C1(h) = c, sits at C1 = 1 - c. With c distributed as (1 + Lambda_i) c^Lambda_i (the visible point seen
// from wi), the probability that wo escapes on the other side is E[(1 - c)^Lambda_o], and with the G1 of
// the visible normals G2_t = B(1 + Lambda_i, 1 + Lambda_o) (Euler's beta function; derived here, and what
// order 1 of the Smith random walk produces, tests/scatter/test_smith_walk.cpp). Symmetric in (i, o). It is not the
// reflection form 1 / (1 + Lambda_i + Lambda_o) (Heitz 2014 eq. 99, ggx.G2, where both ends are on one side,
// E[c^Lambda_o]), which dielectric_bsdf below uses for both lobes: the two agree when either Lambda is 0 and
// differ at grazing angles (B(2, 2) = 1/6 against 1/3 for Lambda_i = Lambda_o = 1).
template <class T, template <class> class Ndf>
T transmission_G2(const Ndf<T>& ndf, const Vec3<T>& wi, const Vec3<T>& wo) {
  const T gi = ndf.G1(wi), go = ndf.G1(wo);  // 1 / (1 + Lambda)
  if (!(gi > T(0) && go > T(0))) return T(0);
  return T(std::beta(double(T(1) / gi), double(T(1) / go)));
}

namespace detail {
template <class T, template <class> class Ndf>
T dielectric_bsdf_with(const Ndf<T>& ggx, T eta, const Vec3<T>& wi, const Vec3<T>& wo, bool smith_transmission,
                       MaskingForm masking) {
  const T ci = wi.z(), co = wo.z();
  if (ci == T(0) || co == T(0)) return T(0);
  const bool reflection = (ci > T(0)) == (co > T(0));
  if (reflection) {
    const Vec3<T> m = reflection_half_vector(wi, wo);
    const T im = wi.dot(m), om = wo.dot(m);
    // Both directions must see the same side of the facet.
    if (im * ci <= T(0) || om * co <= T(0) || m.z() <= T(0)) return T(0);
    const T F = fresnel_dielectric(im, eta);
    return F * ggx.D(m) * masking_shadowing(ggx, wi, wo, masking) / (T(4) * std::abs(ci) * std::abs(co));
  }
  const T eta_i = ci > T(0) ? T(1) : eta;  // index on wi's side (relative to outside = 1)
  const T eta_o = ci > T(0) ? eta : T(1);
  Vec3<T> m = normalized_or_zero(Vec3<T>(-(eta_i * wi + eta_o * wo)));
  if (m.z() < T(0)) m = -m;
  if (m.z() <= T(0)) return T(0);
  const T im = wi.dot(m), om = wo.dot(m);
  // wi and wo on opposite sides of the facet, each on the facet side matching its macro side.
  if (im * ci <= T(0) || om * co <= T(0)) return T(0);
  const T denom = sqr(eta_i * im + eta_o * om);
  if (!(denom > T(0))) return T(0);
  // F is the same for both directions of a refracted pair (Stokes), but evaluating it from the denser
  // side computes the thinner side's cosine as sqrt(1 - sin^2 (n_dense/n_thin)^2), which cancels near
  // grazing refraction (relative error of 1 - F ~ eps / cos^2). Evaluate it from the thinner side's
  // cosine: accurate, and the same value for wi -> wo and wo -> wi (exact reciprocity).
  const bool wi_on_thin_side = (eta_o >= eta_i);
  const T F = wi_on_thin_side ? fresnel_dielectric(im, eta) : fresnel_dielectric(om, eta);
  const T G2 = smith_transmission ? transmission_G2(ggx, wi, wo) : masking_shadowing(ggx, wi, wo, masking);
  return std::abs(im) * std::abs(om) / (std::abs(ci) * std::abs(co)) * sqr(eta_o) * (T(1) - F) * ggx.D(m) * G2 / denom;
}
}  // namespace detail

// Rough dielectric BSDF (Walter 2007): reflection (eq. 20) and refraction (eq. 21) from both sides.
// eta = n_inside / n_outside (the lower half-space is the inside). The refraction half vector is
// m = -(eta_i wi + eta_o wo) (eq. 16), oriented to +z. The refraction term follows eq. 21 including the
// eta_o^2 factor (radiance, not importance): f_t(i->o) / eta_o^2 = f_t(o->i) / eta_i^2. Both lobes use the
// height-correlated G2 of reflection, 1 / (1 + Lambda_i + Lambda_o), unless `masking` names another form.
template <class T, template <class> class Ndf>
T dielectric_bsdf(const Ndf<T>& ggx, T eta, const Vec3<T>& wi, const Vec3<T>& wo,
                  MaskingForm masking = MaskingForm::height_correlated) {
  return detail::dielectric_bsdf_with(ggx, eta, wi, wo, false, masking);
}

// The rough dielectric as a renderer's BSDF evaluates it for a sample: wg the direction it was given, ws the
// one it sampled, in its convention. Importance: light flows from wg to ws, dielectric_bsdf(wg, ws).
// Radiance: light flows from ws to wg, dielectric_bsdf(ws, wg) = dielectric_bsdf(wg, ws) (n_g / n_s)^2 for a
// refraction (Walter 2007 eq. 21 with the reciprocity f_t(i->o) / eta_o^2 = f_t(o->i) / eta_i^2).
template <class T, template <class> class Ndf>
T dielectric_bsdf_as(const Ndf<T>& ggx, T eta, const Vec3<T>& wg, const Vec3<T>& ws, const BsdfConvention& c) {
  return c.transport == TransportMode::importance ? dielectric_bsdf(ggx, eta, wg, ws, c.masking)
                                                  : dielectric_bsdf(ggx, eta, ws, wg, c.masking);
}

// The same BSDF with the refraction lobe's masking of the Smith microsurface itself, transmission_G2: the
// single scattering of the Smith random walk (Heitz, Hanika, d'Eon, Dachsbacher 2016), i.e. its order 1.
template <class T, template <class> class Ndf>
T dielectric_bsdf_smith(const Ndf<T>& ggx, T eta, const Vec3<T>& wi, const Vec3<T>& wo) {
  return detail::dielectric_bsdf_with(ggx, eta, wi, wo, true, MaskingForm::height_correlated);
}

}  // namespace microsim
