// microsim: the sampler registry (names, descriptions, claimed pdfs).
#include "microfacet/samplers.h"

#include <algorithm>

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

constexpr SamplerInfo kSamplers[] = {
    {"ndf", "Walter et al. 2007: samples D(m) m.z (not the VNDF)", SampleDomain::microfacet_normal, false, false,
     &sample_ndf<float>, &sample_ndf<double>, &claimed_ndf},
    {"heitz2014", "Heitz & d'Eon 2014: visible slopes in the stretched configuration", SampleDomain::microfacet_normal,
     false, true, &sample_heitz2014<float>, &sample_heitz2014<double>, &claimed_vndf},
    {"heitz2018", "Heitz 2018 JCGT: stretched hemisphere, warped disk", SampleDomain::microfacet_normal, false, true,
     &sample_heitz2018<float>, &sample_heitz2018<double>, &claimed_vndf},
    {"dupuy2023", "Dupuy & Benyoub 2023: spherical caps", SampleDomain::microfacet_normal, false, true,
     &sample_dupuy2023<float>, &sample_dupuy2023<double>, &claimed_vndf},
    {"bounded2023", "Eto & Tokuyoshi 2023: bounded VNDF, samples reflected directions",
     SampleDomain::reflected_direction, false, false, &sample_bounded2023<float>, &sample_bounded2023<double>,
     &claimed_bounded},
    {"heitz2018-talk", "NEGATIVE CONTROL: the 2018 talk's slide listing (wrong)", SampleDomain::microfacet_normal,
     true, true, &sample_heitz2018_talk<float>, &sample_heitz2018_talk<double>, &claimed_vndf},
};

}  // namespace

std::span<const SamplerInfo> sampler_registry() { return kSamplers; }

const SamplerInfo* find_sampler(std::string_view name) {
  for (const SamplerInfo& s : kSamplers)
    if (s.name == name) return &s;
  return nullptr;
}

std::vector<std::string> sampler_names() {
  std::vector<std::string> names;
  for (const SamplerInfo& s : kSamplers) names.emplace_back(s.name);
  return names;
}

}  // namespace microsim
