// microsim: BSDF samplers as renderers write them. sample(wi, u) returns the outgoing
// direction wo, the pdf the sampler claims for it and the weight f(wi, wo) |wo.z| / pdf a renderer
// multiplies its throughput by: a pure function of three uniforms, nullopt when the sample is lost (a
// reflection below the horizon, a refraction back up). The zoo holds the correct VNDF-based samplers of
// the conductor and the rough dielectric, and negative controls built from bugs renderers really had;
// `validate --all` tests each with its directions (chi-square against claimed_pdf) and its weights (the
// weight test against the analytic BSDF, validate/weight_test.h).
//
// Views come from above the surface (wi.z >= 0). A dielectric seen from inside, index eta below, is the
// same dielectric mirrored in z with index 1 / eta (f_eta(wi, wo) = f_(1/eta)(M wi, M wo), M = diag(1, 1,
// -1), Walter et al. 2007 eq. 21 being invariant under a common scale of both indices): the zoo validates
// both sides as eta and 1 / eta seen from above.
//
// The weights, from Walter et al. 2007 (EGSR) eq. 14 and 17 (the half-vector Jacobians), eq. 20-21 (the
// BSDF) and the VNDF of Heitz 2014 (eq. 16): with m drawn from D_v(wi, m) = G1(wi) <wi, m> D(m) / wi.z,
//   reflection   pdf = P_r D_v / (4 <wi, m>),                       weight = F G2 / (P_r G1(wi))
//   refraction   pdf = P_t D_v eta^2 |<wo, m>| / (<wi, m> + eta <wo, m>)^2,   weight = (1 - F) G2 / (P_t G1(wi)) s
// where P_r, P_t are the probabilities of choosing the lobe (1 and 0 for a conductor, F and 1 - F for a
// dielectric), G2 = 1 / (1 + Lambda_i + Lambda_o) (Heitz 2014 eq. 99), as in microfacet/bsdf.h, and s the
// transport mode's factor (bsdf_convention.h): 1 / eta^2 in radiance (camera paths), 1 in importance.
#pragma once

#include "microfacet/bsdf_convention.h"
#include "microfacet/ggx.h"
#include "microfacet/material.h"

#include <complex>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

namespace microsim {

struct BsdfSample {
  Vec3<double> wo;  // unit, pointing away from the surface
  double pdf;       // per unit solid angle of wo, as the sampler claims it
  double weight;    // f(wi, wo) |wo.z| / pdf, as the sampler computes it
};
using BsdfSampleResult = std::optional<BsdfSample>;

// The index of the zoo's samplers: a conductor's eta + i k, a dielectric's eta (imaginary part 0).
// The index a sampler takes for a material: a conductor's first channel, a dielectric's eta.
inline std::complex<double> sampler_index(const Material& m) {
  return m.transmits() ? std::complex<double>(m.eta()) : m.ior(0);
}

using BsdfSampleFunction = BsdfSampleResult (*)(const GGX<double>&, std::complex<double> eta, const Vec3<double>& wi,
                                                const Vec3<double>& u);
using BsdfPdfFunction = double (*)(const GGX<double>&, std::complex<double> eta, const Vec3<double>& wi,
                                   const Vec3<double>& wo);

// The pdf over wo of VNDF sampling followed by a mirror reflection, the samples below the horizon lost:
// GGX::visible_reflection_pdf for wo.z > 0, else 0.
double conductor_vndf_pdf(const GGX<double>& ggx, std::complex<double> eta, const Vec3<double>& wi, const Vec3<double>& wo);
// The pdf over wo (the whole sphere) of VNDF sampling followed by reflection with probability F(<wi, m>)
// or refraction, the reflections below and refractions above the horizon lost (see above).
double dielectric_vndf_pdf(const GGX<double>& ggx, std::complex<double> eta, const Vec3<double>& wi, const Vec3<double>& wo);

// The density of the normal m that a BSDF's sample() draws given wi (bsdf_convention.h SampledNormals): D_v(wi, m)
// (Heitz 2018 eq. 1), or D(m) m.z for m.z > 0 (Walter et al. 2007 eq. 38).
template <class T> T sampled_normal_pdf(const GGX<T>& ggx, SampledNormals normals, const Vec3<T>& wi, const Vec3<T>& m) {
  if (normals == SampledNormals::visible) return ggx.visible_normal_pdf(wi, m);
  return m.z() > T(0) ? ggx.D(m) * m.z() : T(0);
}
// The two densities above with the normals drawn as `normals` says (the vndf ones for SampledNormals::visible): the
// same Jacobians (Walter et al. 2007 eq. 14 and 17), the samples whose normal faces away from wi lost with the rest.
double conductor_sampling_pdf(const GGX<double>& ggx, SampledNormals normals, const Vec3<double>& wi, const Vec3<double>& wo);
double dielectric_sampling_pdf(const GGX<double>& ggx, SampledNormals normals, double eta, const Vec3<double>& wi,
                               const Vec3<double>& wo);

struct BsdfSamplerInfo {
  std::string_view name;
  std::string_view description;
  MaterialKind material;  // conductor or dielectric
  bool negative_control;  // known to be wrong: validation must reject it
  BsdfSampleFunction sample;
  BsdfPdfFunction claimed_pdf;  // the density it claims to sample (the correct sampler's)
  // Whether the bug has an effect a validation of `samples` samples can see at this configuration; nullptr:
  // everywhere. Correct samplers: nullptr. A roughness squared twice: everywhere but alpha = 1. The weight
  // bugs: where the mean weight moves by at least 6 standard errors of the mean at `samples` samples
  // (mean_weight_shift_z >= 6).
  bool (*bug_has_effect)(const GGX<double>&, std::complex<double> eta, const Vec3<double>& wi, std::uint64_t samples);
  BsdfConvention convention;  // what its weights are (bsdf_convention.h): a dielectric's transport mode
};

// The z a sample count gives the change of the mean weight that sampler `bug` makes against `correct`:
// |E[w_bug] - E[w_correct]| / (sd(w_correct) / sqrt(samples)), both means over the same 2^16 points of
// the R3 Kronecker sequence (Roberts 2018, "The Unreasonable Effectiveness of Quasirandom Sequences"),
// lost samples weighing 0.
double mean_weight_shift_z(BsdfSampleFunction bug, BsdfSampleFunction correct, const GGX<double>& ggx,
                           std::complex<double> eta, const Vec3<double>& wi, std::uint64_t samples);

std::span<const BsdfSamplerInfo> bsdf_sampler_registry();
const BsdfSamplerInfo* find_bsdf_sampler(std::string_view name);  // nullptr when none has that name

// The materials the zoo validates its samplers with: a conductor (eta 0.2 + 3.9 i, gold-like at 550 nm) and
// a glass (eta 1.5) from outside and, mirrored, from inside (eta 1 / 1.5).
inline constexpr std::complex<double> kZooConductorIor{0.2, 3.9};
inline constexpr double kZooDielectricEta = 1.5;

}  // namespace microsim
