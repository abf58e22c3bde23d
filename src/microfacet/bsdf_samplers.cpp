#include "microfacet/bsdf_samplers.h"

#include "microfacet/bsdf.h"
#include "microfacet/samplers.h"

#include <algorithm>
#include <cmath>

namespace microsim {

namespace {

// ---- the two half-vector Jacobians (Walter et al. 2007 eq. 14 and 17) ---------------------------------

// d omega_m / d omega_o of a reflection: 1 / (4 |<wo, m>|).
double reflection_jacobian(const Vec3<double>& wo, const Vec3<double>& m) { return 1.0 / (4.0 * std::abs(wo.dot(m))); }

// d omega_m / d omega_o of a refraction from index 1 into eta: eta^2 |<wo, m>| / (<wi, m> + eta <wo, m>)^2.
double refraction_jacobian(const Vec3<double>& wi, const Vec3<double>& wo, const Vec3<double>& m, double eta) {
  const double denom = sqr(wi.dot(m) + eta * wo.dot(m));
  return denom > 0 ? sqr(eta) * std::abs(wo.dot(m)) / denom : 0.0;
}

// The same Jacobian written for the wrong side (d omega_m / d omega_i): |<wi, m>| / (<wi, m> + eta <wo, m>)^2.
double refraction_jacobian_of_wi(const Vec3<double>& wi, const Vec3<double>& wo, const Vec3<double>& m, double eta) {
  const double denom = sqr(wi.dot(m) + eta * wo.dot(m));
  return denom > 0 ? std::abs(wi.dot(m)) / denom : 0.0;
}

// The refraction half vector of wi (above) and wo (below) into index eta (Walter eq. 16), oriented to +z;
// zero where there is none.
Vec3<double> refraction_half_vector(const Vec3<double>& wi, const Vec3<double>& wo, double eta) {
  Vec3<double> m = normalized_or_zero(Vec3<double>(-(wi + eta * wo)));
  return m.z() < 0 ? Vec3<double>(-m) : m;
}

// ---- one event: a visible normal, then reflection or refraction ------------------------------------------

struct VisibleNormal {
  Vec3<double> m;
  double pdf;  // D_v(wi, m)
};
std::optional<VisibleNormal> visible_normal(const GGX<double>& ggx, const Vec3<double>& wi, const Vec3<double>& u) {
  const SampleResult<double> s = sample_heitz2018(ggx, wi, Vec2<double>(u.x(), u.y()));
  if (!s || !(wi.dot(s->direction) > 0)) return std::nullopt;
  return VisibleNormal{s->direction, s->pdf};
}

// A conductor: the mirror reflection about m, lost below the horizon; weight F G2 / G1(wi).
BsdfSampleResult conductor_event(const GGX<double>& ggx, std::complex<double> eta, const Vec3<double>& wi,
                                 const Vec3<double>& u, bool without_g1_wo) {
  const auto v = visible_normal(ggx, wi, u);
  if (!v) return std::nullopt;
  const Vec3<double> wo = reflect(wi, v->m);
  if (!(wo.z() > 0)) return std::nullopt;
  const double F = fresnel_conductor(wi.dot(v->m), eta);
  // The bug: G2 / G1(wi) ~ G1(wo) left out of the weight.
  const double weight = without_g1_wo ? F : F * ggx.G2(wi, wo) / ggx.G1(wi);
  return BsdfSample{wo, v->pdf * reflection_jacobian(wo, v->m), weight};
}

enum class DielectricBug {
  none,
  jacobian_of_wrong_side,   // the refraction pdf with d omega_m / d omega_i
  eta2_twice,               // the radiance factor (n_g / n_s)^2 applied twice
  eta2_on_reflection,       // the radiance factor of a refraction applied to reflections too
  g1_for_g2,                // G2 replaced by G1(wi): the weight without G1(wo)
};

// The factor a refraction's weight carries in `mode` (bsdf_convention.h): (n_given / n_sampled)^2 = 1 / eta^2
// for radiance (eta: the index across the interface over the index on wi's side), 1 for importance.
double radiance_factor(TransportMode mode, double eta) { return mode == TransportMode::radiance ? 1 / sqr(eta) : 1.0; }

// A dielectric: reflection with probability F, else refraction; lost on the wrong side of the horizon. The
// weight G2 / G1(wi) times, for a refraction, the transport mode's factor.
BsdfSampleResult dielectric_event(const GGX<double>& ggx, double eta, const Vec3<double>& wi, const Vec3<double>& u,
                                  TransportMode mode, DielectricBug bug) {
  const auto v = visible_normal(ggx, wi, u);
  if (!v) return std::nullopt;
  const double F = fresnel_dielectric(wi.dot(v->m), eta);
  const double factor = radiance_factor(mode, eta);
  if (u.z() < F) {
    const Vec3<double> wo = reflect(wi, v->m);
    if (!(wo.z() > 0)) return std::nullopt;
    const double g = bug == DielectricBug::g1_for_g2 ? 1.0 : ggx.G2(wi, wo) / ggx.G1(wi);
    return BsdfSample{wo, F * v->pdf * reflection_jacobian(wo, v->m),
                      bug == DielectricBug::eta2_on_reflection ? g * factor : g};
  }
  Vec3<double> wo;
  if (!refract(wi, v->m, eta, wo) || !(wo.z() < 0)) return std::nullopt;
  const double jacobian = refraction_jacobian(wi, wo, v->m, eta);
  double weight = (bug == DielectricBug::g1_for_g2 ? 1.0 : ggx.G2(wi, wo) / ggx.G1(wi)) * factor;
  double pdf = (1 - F) * v->pdf * jacobian;
  if (bug == DielectricBug::eta2_twice) weight *= factor;
  if (bug == DielectricBug::jacobian_of_wrong_side) {
    const double wrong = refraction_jacobian_of_wi(wi, wo, v->m, eta);
    weight *= jacobian / wrong;  // f |wo.z| / pdf with the wrong pdf
    pdf = (1 - F) * v->pdf * wrong;
  }
  return BsdfSample{wo, pdf, weight};
}

// ---- the zoo --------------------------------------------------------------------------------------------

BsdfSampleResult sample_conductor_vndf(const GGX<double>& g, std::complex<double> eta, const Vec3<double>& wi,
                                       const Vec3<double>& u) {
  return conductor_event(g, eta, wi, u, false);
}
BsdfSampleResult sample_conductor_no_g1_wo(const GGX<double>& g, std::complex<double> eta, const Vec3<double>& wi,
                                           const Vec3<double>& u) {
  return conductor_event(g, eta, wi, u, true);
}
// The renderer squared a roughness that was already alpha: it samples and weighs the BSDF of alpha^2.
BsdfSampleResult sample_conductor_alpha_squared(const GGX<double>& g, std::complex<double> eta, const Vec3<double>& wi,
                                                const Vec3<double>& u) {
  return conductor_event(GGX<double>(sqr(g.alpha_x()), sqr(g.alpha_y())), eta, wi, u, false);
}
// The rough dielectric's samplers: correct in radiance and in importance transport, and the bugs (radiance).
template <TransportMode Mode, DielectricBug Bug>
BsdfSampleResult sample_dielectric(const GGX<double>& g, std::complex<double> eta, const Vec3<double>& wi,
                                   const Vec3<double>& u) {
  return dielectric_event(g, eta.real(), wi, u, Mode, Bug);
}
constexpr auto sample_dielectric_vndf = sample_dielectric<TransportMode::radiance, DielectricBug::none>;
constexpr auto sample_dielectric_vndf_importance = sample_dielectric<TransportMode::importance, DielectricBug::none>;
constexpr auto sample_dielectric_wrong_jacobian =
    sample_dielectric<TransportMode::radiance, DielectricBug::jacobian_of_wrong_side>;
constexpr auto sample_dielectric_eta2_twice = sample_dielectric<TransportMode::radiance, DielectricBug::eta2_twice>;
constexpr auto sample_dielectric_eta2_on_reflection =
    sample_dielectric<TransportMode::radiance, DielectricBug::eta2_on_reflection>;
constexpr auto sample_dielectric_g1_for_g2 = sample_dielectric<TransportMode::radiance, DielectricBug::g1_for_g2>;

// alpha^2 == alpha only at alpha = 1, and both clamp to kMinAlpha at or below it (GGX's constructor).
bool squaring_changes(double a) { return a > kMinAlpha && a != 1.0; }
bool squaring_has_effect(const GGX<double>& g, std::complex<double>, const Vec3<double>&, std::uint64_t) {
  return squaring_changes(g.alpha_x()) || squaring_changes(g.alpha_y());
}

// A weight bug has an effect where it moves the mean weight by 6 standard errors (p ~ 2e-9).
template <BsdfSampleFunction Bug, BsdfSampleFunction Correct>
bool shifts_mean_weight(const GGX<double>& g, std::complex<double> eta, const Vec3<double>& wi, std::uint64_t samples) {
  return mean_weight_shift_z(Bug, Correct, g, eta, wi, samples) >= 6;
}

constexpr BsdfConvention kRadiance{TransportMode::radiance, MaskingForm::height_correlated};
constexpr BsdfConvention kImportance{TransportMode::importance, MaskingForm::height_correlated};

constexpr BsdfSamplerInfo kRegistry[] = {
    {"conductor_vndf", "conductor: Heitz 2018 VNDF, mirror reflection, weight F G2 / G1(wi)", MaterialKind::conductor,
     false, sample_conductor_vndf, conductor_vndf_pdf, nullptr, kRadiance},
    {"dielectric_vndf",
     "rough dielectric, radiance transport (camera paths): Heitz 2018 VNDF, reflect with probability F else refract, "
     "weight G2 / G1(wi), a refraction's times (n_given / n_sampled)^2",
     MaterialKind::dielectric, false, sample_dielectric_vndf, dielectric_vndf_pdf, nullptr, kRadiance},
    {"dielectric_vndf_importance",
     "rough dielectric, importance transport (light paths): Heitz 2018 VNDF, reflect with probability F else refract, "
     "weight G2 / G1(wi)",
     MaterialKind::dielectric, false, sample_dielectric_vndf_importance, dielectric_vndf_pdf, nullptr, kImportance},
    {"cond_no_g1_wo", "NEGATIVE CONTROL: conductor weight F, without G1(wo)", MaterialKind::conductor, true,
     sample_conductor_no_g1_wo, conductor_vndf_pdf, shifts_mean_weight<sample_conductor_no_g1_wo, sample_conductor_vndf>,
     kRadiance},
    {"cond_alpha_sq", "NEGATIVE CONTROL: conductor with the roughness squared twice (samples and weighs alpha^2)",
     MaterialKind::conductor, true, sample_conductor_alpha_squared, conductor_vndf_pdf, squaring_has_effect, kRadiance},
    {"diel_wrong_jac", "NEGATIVE CONTROL: dielectric refraction pdf with the half-vector Jacobian of wi's side",
     MaterialKind::dielectric, true, sample_dielectric_wrong_jacobian, dielectric_vndf_pdf,
     shifts_mean_weight<sample_dielectric_wrong_jacobian, sample_dielectric_vndf>, kRadiance},
    {"diel_eta2_twice", "NEGATIVE CONTROL: dielectric refraction weight with the radiance factor 1 / eta^2 applied twice",
     MaterialKind::dielectric, true, sample_dielectric_eta2_twice, dielectric_vndf_pdf,
     shifts_mean_weight<sample_dielectric_eta2_twice, sample_dielectric_vndf>, kRadiance},
    {"diel_eta2_reflect", "NEGATIVE CONTROL: dielectric with the radiance factor 1 / eta^2 on reflections too",
     MaterialKind::dielectric, true, sample_dielectric_eta2_on_reflection, dielectric_vndf_pdf,
     shifts_mean_weight<sample_dielectric_eta2_on_reflection, sample_dielectric_vndf>, kRadiance},
    {"diel_g1_for_g2", "NEGATIVE CONTROL: dielectric weight with G1(wi) for G2 (without G1(wo))", MaterialKind::dielectric,
     true, sample_dielectric_g1_for_g2, dielectric_vndf_pdf,
     shifts_mean_weight<sample_dielectric_g1_for_g2, sample_dielectric_vndf>, kRadiance},
};

}  // namespace

double conductor_vndf_pdf(const GGX<double>& ggx, std::complex<double>, const Vec3<double>& wi, const Vec3<double>& wo) {
  return wo.z() > 0 ? ggx.visible_reflection_pdf(wi, wo) : 0.0;
}

double dielectric_vndf_pdf(const GGX<double>& ggx, std::complex<double> ior, const Vec3<double>& wi, const Vec3<double>& wo) {
  return dielectric_sampling_pdf(ggx, SampledNormals::visible, ior.real(), wi, wo);
}

double conductor_sampling_pdf(const GGX<double>& ggx, SampledNormals normals, const Vec3<double>& wi,
                              const Vec3<double>& wo) {
  if (normals == SampledNormals::visible) return conductor_vndf_pdf(ggx, {}, wi, wo);
  if (!(wo.z() > 0)) return 0.0;
  const Vec3<double> m = reflection_half_vector(wi, wo);
  if (!(wi.dot(m) > 0 && wo.dot(m) > 0)) return 0.0;
  return sampled_normal_pdf(ggx, normals, wi, m) * reflection_jacobian(wo, m);
}

double dielectric_sampling_pdf(const GGX<double>& ggx, SampledNormals normals, double eta, const Vec3<double>& wi,
                               const Vec3<double>& wo) {
  if (wo.z() > 0) {
    const Vec3<double> m = reflection_half_vector(wi, wo);
    if (!(wi.dot(m) > 0 && wo.dot(m) > 0)) return 0.0;
    return fresnel_dielectric(wi.dot(m), eta) * sampled_normal_pdf(ggx, normals, wi, m) * reflection_jacobian(wo, m);
  }
  if (!(wo.z() < 0)) return 0.0;
  const Vec3<double> m = refraction_half_vector(wi, wo, eta);
  if (!(m.z() > 0 && wi.dot(m) > 0 && wo.dot(m) < 0)) return 0.0;
  return (1 - fresnel_dielectric(wi.dot(m), eta)) * sampled_normal_pdf(ggx, normals, wi, m) *
         refraction_jacobian(wi, wo, m, eta);
}

double mean_weight_shift_z(BsdfSampleFunction bug, BsdfSampleFunction correct, const GGX<double>& ggx,
                           std::complex<double> eta, const Vec3<double>& wi, std::uint64_t samples) {
  constexpr int n = 1 << 16;
  constexpr double g = 1.2207440846057596;  // R3's generalised golden ratio: g^4 = g + 1
  const Vec3<double> step(1 / g, 1 / (g * g), 1 / (g * g * g));
  double shift = 0, sum = 0, sum_sq = 0;
  for (int i = 0; i < n; ++i) {
    const Vec3<double> u =
        (Vec3<double>::Constant(0.5) + double(i + 1) * step).unaryExpr([](double x) { return x - std::floor(x); });
    const auto rb = bug(ggx, eta, wi, u), rc = correct(ggx, eta, wi, u);
    const double wb = rb ? rb->weight : 0.0, wc = rc ? rc->weight : 0.0;
    shift += wb - wc;
    sum += wc;
    sum_sq += wc * wc;
  }
  const double mean = sum / n, sd = std::sqrt(std::max(sum_sq / n - mean * mean, 0.0));
  const double se = sd / std::sqrt(double(samples));
  return se > 0 ? std::abs(shift / n) / se : (shift != 0 ? INFINITY : 0.0);
}

std::span<const BsdfSamplerInfo> bsdf_sampler_registry() { return kRegistry; }

const BsdfSamplerInfo* find_bsdf_sampler(std::string_view name) {
  for (const BsdfSamplerInfo& s : kRegistry)
    if (s.name == name) return &s;
  return nullptr;
}

}  // namespace microsim
