// microsim: the sampler registry (names, descriptions, claimed pdfs and the traits tests ask for).
#include "microfacet/samplers.h"

#include <algorithm>
#include <stdexcept>

namespace microsim {
namespace {

double claimed_vndf(const GGX<double>& ggx, const Vec3<double>& wi, const Vec3<double>& m) {
  return ggx.visible_normal_pdf(wi, m);
}

// D(m) m.z, with the back-side convention (wi.z < 0: the normals are mirrored to the lower side).
double claimed_ndf(const GGX<double>& ggx, const Vec3<double>& wi, const Vec3<double>& m) {
  const Vec3<double> mu = wi.z() < 0 ? Vec3<double>(-m) : m;
  return ggx.D(mu) * std::max(mu.z(), 0.0);
}

double claimed_bounded(const GGX<double>& ggx, const Vec3<double>& wi, const Vec3<double>& wo) {
  return bounded2023_reflection_pdf(ggx, wi, wo);
}

// The boundary of the support of the bounded VNDF sampler (Eto & Tokuyoshi 2023, sec. 3): the cap
// direction c = reflect(Vh, Nh) of the half vector must satisfy c.z >= -k Vh.z; zero on the boundary
// (same back-side and half-vector conventions as bounded2023_reflection_pdf).
double bounded_cap_edge(const GGX<double>& ggx, const Vec3<double>& wi_in, const Vec3<double>& wo_in) {
  const bool flip = wi_in.z() < 0;
  const Vec3<double> wi = flip ? Vec3<double>(-wi_in) : wi_in;
  const Vec3<double> wo = flip ? Vec3<double>(-wo_in) : wo_in;
  Vec3<double> m = normalized_or_zero(Vec3<double>(wi + wo));
  if (m.isZero()) return 1.0;
  if (m.z() < 0) m = -m;
  const Vec3<double> vh = normalized_or_zero(Vec3<double>(ggx.alpha_x() * wi.x(), ggx.alpha_y() * wi.y(), wi.z()));
  const Vec3<double> nh = normalized_or_zero(Vec3<double>(m.x() / ggx.alpha_x(), m.y() / ggx.alpha_y(), m.z()));
  const Vec3<double> c = reflect(vh, nh);
  const double k = wi.z() > 0 ? bounded2023_k(ggx, wi) : 1.0;
  return c.z() + k * vh.z();
}

constexpr SamplerInfo kSamplers[] = {
    {.name = "ndf", .description = "Walter et al. 2007: samples D(m) m.z (not the VNDF)",
     .domain = SampleDomain::microfacet_normal, .negative_control = false, .claims = ClaimedPdf::ndf_cosine,
     .reference = true, .returned_pdf_check = ReturnedPdfCheck::everywhere, .sample_float = &sample_ndf<float>,
     .sample_double = &sample_ndf<double>, .claimed_pdf = &claimed_ndf, .claimed_pdf_jump = nullptr},
    {.name = "heitz2014", .description = "Heitz & d'Eon 2014: visible slopes in the stretched configuration",
     .domain = SampleDomain::microfacet_normal, .negative_control = false, .claims = ClaimedPdf::visible_normals,
     .reference = false, .returned_pdf_check = ReturnedPdfCheck::everywhere,
     .sample_float = &sample_heitz2014<float>, .sample_double = &sample_heitz2014<double>,
     .claimed_pdf = &claimed_vndf, .claimed_pdf_jump = nullptr},
    {.name = "heitz2018", .description = "Heitz 2018 JCGT: stretched hemisphere, warped disk",
     .domain = SampleDomain::microfacet_normal, .negative_control = false, .claims = ClaimedPdf::visible_normals,
     .reference = true, .returned_pdf_check = ReturnedPdfCheck::everywhere,
     .sample_float = &sample_heitz2018<float>, .sample_double = &sample_heitz2018<double>,
     .claimed_pdf = &claimed_vndf, .claimed_pdf_jump = nullptr},
    {.name = "dupuy2023", .description = "Dupuy & Benyoub 2023: spherical caps",
     .domain = SampleDomain::microfacet_normal, .negative_control = false, .claims = ClaimedPdf::visible_normals,
     .reference = false, .returned_pdf_check = ReturnedPdfCheck::everywhere,
     .sample_float = &sample_dupuy2023<float>, .sample_double = &sample_dupuy2023<double>,
     .claimed_pdf = &claimed_vndf, .claimed_pdf_jump = nullptr},
    {.name = "bounded2023", .description = "Eto & Tokuyoshi 2023: bounded VNDF, samples reflected directions",
     .domain = SampleDomain::reflected_direction, .negative_control = false,
     .claims = ClaimedPdf::bounded_reflection, .reference = true,
     .returned_pdf_check = ReturnedPdfCheck::except_near_back_reflection,
     .sample_float = &sample_bounded2023<float>, .sample_double = &sample_bounded2023<double>,
     .claimed_pdf = &claimed_bounded, .claimed_pdf_jump = &bounded_cap_edge},
    {.name = "heitz2018-talk", .description = "NEGATIVE CONTROL: the 2018 talk's slide listing (wrong)",
     .domain = SampleDomain::microfacet_normal, .negative_control = true, .claims = ClaimedPdf::visible_normals,
     .reference = false, .returned_pdf_check = ReturnedPdfCheck::everywhere,
     .sample_float = &sample_heitz2018_talk<float>, .sample_double = &sample_heitz2018_talk<double>,
     .claimed_pdf = &claimed_vndf, .claimed_pdf_jump = nullptr},
};

}  // namespace

std::span<const SamplerInfo> sampler_registry() { return kSamplers; }

const SamplerInfo* find_sampler(std::string_view name) {
  for (const SamplerInfo& s : kSamplers)
    if (s.name == name) return &s;
  return nullptr;
}

const SamplerInfo& reference_sampler(ClaimedPdf claims) {
  for (const SamplerInfo& s : kSamplers)
    if (s.reference && s.claims == claims) return s;
  throw std::logic_error("the sampler registry has no reference sampler for this density");
}

std::vector<std::string> sampler_names() {
  std::vector<std::string> names;
  for (const SamplerInfo& s : kSamplers) names.emplace_back(s.name);
  return names;
}

}  // namespace microsim
