// tests: the worked BSDFs of battery_bsdfs.h.
#include "battery_bsdfs.h"

#include "microfacet/bsdf.h"
#include "microfacet/bsdf_samplers.h"
#include "scatter/smith_walk.h"

#include <bit>
#include <cmath>
#include <memory>
#include <numbers>
#include <stdexcept>

namespace microsim::test {

std::string to_string(PlantedBug bug) {
  switch (bug) {
    case PlantedBug::none: return "none";
    case PlantedBug::eta2_in_transmission: return "eta^2 in transmission f";
    case PlantedBug::no_same_hemisphere_check: return "no same-hemisphere check in transmission f";
    case PlantedBug::weight_not_eval_over_pdf: return "weight != eval / pdf (no G1(wo))";
    case PlantedBug::one_lobe_weight: return "weight of the chosen lobe only";
    case PlantedBug::non_reciprocal_lobe: return "(1 - E(mu_i))^2 lobe";
    case PlantedBug::stale_height: return "stale height after refraction";
    case PlantedBug::eval_not_sampler_integral: return "eval orders 1-2 only";
    case PlantedBug::eval_scale: return "eval scaled";
    case PlantedBug::weight_scale: return "weight scaled";
    case PlantedBug::swapped_alphas: return "alpha_x and alpha_y swapped";
    case PlantedBug::unrotated_anisotropy: return "view turned to phi 0, roughness not";
  }
  return "?";
}

namespace {

Vec3<double> mirrored(const Vec3<double>& w) { return {w.x(), w.y(), -w.z()}; }

Vec3<double> turned(const Vec3<double>& w, double phi) {
  const double c = std::cos(phi), s = std::sin(phi);
  return {c * w.x() - s * w.y(), s * w.x() + c * w.y(), w.z()};
}

// Per row: f, and the zoo's sampler and pdf, for a view on either side (from inside: mirrored, 1 / eta).
struct Exact {
  GGX<double> ggx;
  Material material;
  BsdfConvention convention;
  const BsdfSamplerInfo* sampler;
  PlantedBug bug;
  double scale;

  std::complex<double> eta_for(const Vec3<double>& wi) const {
    if (!material.transmits()) return sampler_index(material);
    return wi.z() < 0 ? 1 / material.eta() : material.eta();
  }
  double f_cos(const Vec3<double>& wi, const Vec3<double>& wo) const {
    if (!material.transmits()) return conductor_brdf(ggx, sampler_index(material), wi, wo, convention.masking) * std::abs(wo.z());
    return dielectric_bsdf_as(ggx, material.eta(), wi, wo, convention) * std::abs(wo.z());
  }
  // The azimuth the unrotated_anisotropy bug turns the pair by (0 otherwise).
  double turn(const Vec3<double>& wi) const {
    return bug == PlantedBug::unrotated_anisotropy ? -std::atan2(wi.y(), wi.x()) : 0.0;
  }
  double eval(const Vec3<double>& wi, const Vec3<double>& wo) const {
    const double t = turn(wi);
    return t == 0 ? eval_as_given(wi, wo) : eval_as_given(turned(wi, t), turned(wo, t));
  }
  double pdf(const Vec3<double>& wi, const Vec3<double>& wo) const {
    const double t = turn(wi);
    return t == 0 ? pdf_as_given(wi, wo) : pdf_as_given(turned(wi, t), turned(wo, t));
  }
  BsdfSampleResult sample(const Vec3<double>& wi, const Vec3<double>& u) const {
    const double t = turn(wi);
    BsdfSampleResult s = sample_as_given(t == 0 ? wi : turned(wi, t), u);
    if (s && t != 0) s->wo = turned(s->wo, -t);
    return s;
  }
  double eval_as_given(const Vec3<double>& wi, const Vec3<double>& wo) const {
    double v = f_cos(wi, wo);
    const double ni = wi.z() < 0 ? material.eta() : 1, no = wo.z() < 0 ? material.eta() : 1;
    if (bug == PlantedBug::eta2_in_transmission && wi.z() * wo.z() < 0) v *= (no * no) / (ni * ni);
    if (bug == PlantedBug::no_same_hemisphere_check && wi.z() * wo.z() > 0 && material.transmits())
      v += f_cos(wi, mirrored(wo));
    if (bug == PlantedBug::eval_scale) v *= 1 + scale;
    return v;
  }
  double pdf_as_given(const Vec3<double>& wi, const Vec3<double>& wo) const {
    const bool inside = wi.z() < 0;
    const Vec3<double> a = inside ? mirrored(wi) : wi, b = inside ? mirrored(wo) : wo;
    return sampler->claimed_pdf(ggx, eta_for(wi), a, b);
  }
  BsdfSampleResult sample_as_given(const Vec3<double>& wi, const Vec3<double>& u) const {
    const bool inside = wi.z() < 0;
    BsdfSampleResult s = sampler->sample(ggx, eta_for(wi), inside ? mirrored(wi) : wi, u);
    if (s && inside) s->wo = mirrored(s->wo);
    if (s && bug == PlantedBug::weight_scale) s->weight *= 1 + scale;
    return s;
  }
};

BsdfUnderTest from_exact(const std::shared_ptr<const Exact>& e, const std::string& name) {
  BsdfUnderTest b;
  b.name = name;
  b.convention = e->convention;
  b.sample = [e](std::span<const Vec3<double>> wi, std::span<const double> u, std::span<Vec3<double>> wo,
                 std::span<double> pdf, std::span<double> weight, std::span<unsigned char> kept) {
    for (std::size_t i = 0; i < wi.size(); ++i) {
      const BsdfSampleResult s = e->sample(wi[i], {u[3 * i], u[3 * i + 1], u[3 * i + 2]});
      kept[i] = s.has_value();
      if (s) wo[i] = s->wo, pdf[i] = s->pdf, weight[i] = s->weight;
    }
  };
  b.eval = [e](std::span<const Vec3<double>> wi, std::span<const Vec3<double>> wo, std::span<double> v) {
    for (std::size_t i = 0; i < wi.size(); ++i) v[i] = e->eval(wi[i], wo[i]);
  };
  b.pdf = [e](std::span<const Vec3<double>> wi, std::span<const Vec3<double>> wo, std::span<double> p) {
    for (std::size_t i = 0; i < wi.size(); ++i) p[i] = e->pdf(wi[i], wo[i]);
  };
  return b;
}

}  // namespace

WorkedBsdf exact_conductor(double alpha, PlantedBug bug, double scale) {
  const Material m = Material::conductor({kZooConductorIor});
  const char* sampler = bug == PlantedBug::weight_not_eval_over_pdf ? "cond_no_g1_wo" : "conductor_vndf";
  auto e = std::make_shared<const Exact>(Exact{GGX<double>(alpha, alpha), m, {}, find_bsdf_sampler(sampler), bug, scale});
  return {from_exact(e, "conductor"), m, e->ggx, BatteryReference::single_scattering};
}

WorkedBsdf anisotropic_conductor(double alpha_x, double alpha_y, PlantedBug bug) {
  const Material m = Material::conductor({kZooConductorIor});
  const GGX<double> claimed(alpha_x, alpha_y);
  const GGX<double> used = bug == PlantedBug::swapped_alphas ? GGX<double>(alpha_y, alpha_x) : claimed;
  auto e = std::make_shared<const Exact>(Exact{used, m, {}, find_bsdf_sampler("conductor_vndf"), bug, 0});
  return {from_exact(e, "anisotropic conductor"), m, claimed, BatteryReference::single_scattering};
}

WorkedBsdf exact_dielectric(double alpha, TransportMode mode, PlantedBug bug, double scale) {
  const Material m = Material::dielectric(kZooDielectricEta);
  const char* sampler = mode == TransportMode::radiance ? "dielectric_vndf" : "dielectric_vndf_importance";
  const BsdfConvention c{mode, MaskingForm::height_correlated};
  auto e = std::make_shared<const Exact>(Exact{GGX<double>(alpha, alpha), m, c, find_bsdf_sampler(sampler), bug, scale});
  return {from_exact(e, "dielectric " + to_string(mode)), m, e->ggx, BatteryReference::single_scattering};
}

namespace {

struct Walk {
  SmithMicrosurface surface;
  Material material;
  detail::WalkFault fault;
  PlantedBug bug;
  int paths_per_eval;
  double scale = 0;  // eval_scale, weight_scale: 1 + scale
  std::shared_ptr<std::uint64_t> calls = std::make_shared<std::uint64_t>(0);

  ScatterOptions options(const Vec3<double>& wi, std::uint64_t paths, std::uint64_t seed) const {
    ScatterOptions o;
    o.wi = wi, o.material = material, o.paths = paths, o.seed = seed, o.run.threads = 1;
    return o;
  }
  double eval(const Vec3<double>& wi, const Vec3<double>& wo) const {
    if (wo.z() == 0 || wi.z() == 0) return 0;
    const SmithWalkEval e = detail::smith_walk_eval(surface, options(wi, std::uint64_t(paths_per_eval), ++*calls), wo, fault);
    const double f = bug == PlantedBug::eval_not_sampler_integral ? e.value(0, 0).value + e.value(0, 1).value : e.value(0).value;
    return f * std::abs(wo.z()) * (bug == PlantedBug::eval_scale ? 1 + scale : 1);
  }
};

}  // namespace

WorkedBsdf walk_dielectric(double alpha, PlantedBug bug, int paths_per_eval, double scale) {
  auto w = std::make_shared<Walk>();
  w->surface.alpha_x = w->surface.alpha_y = alpha;
  w->material = Material::dielectric(kZooDielectricEta);
  w->fault = bug == PlantedBug::stale_height ? detail::WalkFault::keep_height_on_refraction : detail::WalkFault::none;
  w->bug = bug;
  w->paths_per_eval = paths_per_eval;
  w->scale = scale;
  BsdfUnderTest b;
  b.name = "Smith multiple-scattering dielectric (Heitz et al. 2016)";
  b.convention = {TransportMode::importance, MaskingForm::height_correlated};
  b.stochastic_eval = true;
  b.sample = [w](std::span<const Vec3<double>> wi, std::span<const double> u, std::span<Vec3<double>> wo,
                 std::span<double> pdf, std::span<double> weight, std::span<unsigned char> kept) {
    // One walk per row, seeded from the first row's uniforms (the battery's CounterRng per sample).
    const WalkSamples s = detail::smith_walk_samples(w->surface, w->options(wi[0], wi.size(), std::bit_cast<std::uint64_t>(u[0])),
                                                     w->fault);
    const std::size_t row = std::size_t(3 + s.channels), leaving = s.rows.size() / row;
    for (std::size_t i = 0; i < wi.size(); ++i) {
      kept[i] = i < leaving;
      if (i >= leaving) continue;
      wo[i] = {s.rows[row * i], s.rows[row * i + 1], s.rows[row * i + 2]};
      pdf[i] = 0, weight[i] = s.rows[row * i + 3] * (w->bug == PlantedBug::weight_scale ? 1 + w->scale : 1);
    }
  };
  b.eval = [w](std::span<const Vec3<double>> wi, std::span<const Vec3<double>> wo, std::span<double> v) {
    for (std::size_t i = 0; i < wi.size(); ++i) v[i] = w->eval(wi[i], wo[i]);
  };
  return {std::move(b), w->material, GGX<double>(alpha, alpha), BatteryReference::smith_walk};
}

namespace {

constexpr int kMus = 64;

// Kulla & Conty 2017: the compensated GGX mirror.
struct KullaConty {
  GGX<double> ggx;
  PlantedBug bug;
  std::vector<double> e;  // E at mu = (j + 0.5) / kMus
  double e_avg = 0;

  double albedo(double mu) const {  // E, linear between the nodes, constant beyond the end ones
    const double x = std::clamp(mu * kMus - 0.5, 0.0, double(kMus - 1));
    const int j = std::min(int(x), kMus - 2);
    return e[std::size_t(j)] + (x - j) * (e[std::size_t(j) + 1] - e[std::size_t(j)]);
  }
  double lobe(const Vec3<double>& wi, const Vec3<double>& wo) const {  // f_ms
    if (!(wi.z() > 0 && wo.z() > 0)) return 0;
    const double o = bug == PlantedBug::non_reciprocal_lobe ? 1 - albedo(wi.z()) : 1 - albedo(wo.z());
    return (1 - albedo(wi.z())) * o / (std::numbers::pi * (1 - e_avg));
  }
  double f_ss_cos(const Vec3<double>& wi, const Vec3<double>& wo) const { return mirror_brdf(ggx, wi, wo) * std::max(0.0, wo.z()); }
  double eval(const Vec3<double>& wi, const Vec3<double>& wo) const { return f_ss_cos(wi, wo) + lobe(wi, wo) * std::max(0.0, wo.z()); }
  double lobe_probability(const Vec3<double>& wi) const { return std::clamp(1 - albedo(wi.z()), 0.0, 1.0); }
  double pdf(const Vec3<double>& wi, const Vec3<double>& wo) const {
    if (!(wi.z() > 0 && wo.z() > 0)) return 0;
    const double q = lobe_probability(wi);
    return (1 - q) * ggx.visible_reflection_pdf(wi, wo) + q * wo.z() / std::numbers::pi;
  }
};

// E(mu) = the mean over the visible normals of mu of G2 / G1(wi) for the reflections above the horizon: a
// 128 x 128 midpoint rule over the sampler's uniforms; E_avg = 2 integral E mu dmu of the interpolant.
void tabulate(KullaConty& k) {
  const BsdfSamplerInfo* vndf = find_bsdf_sampler("conductor_vndf");
  constexpr int n = 128;
  for (int j = 0; j < kMus; ++j) {
    const double mu = (j + 0.5) / kMus;
    const Vec3<double> wi(std::sqrt(1 - mu * mu), 0, mu);
    double s = 0;
    for (int a = 0; a < n; ++a)
      for (int b = 0; b < n; ++b) {
        const BsdfSampleResult r = vndf->sample(k.ggx, {0.2, 3.9}, wi, {(a + 0.5) / n, (b + 0.5) / n, 0.5});
        if (r) s += k.ggx.G2(wi, r->wo) / k.ggx.G1(wi);
      }
    k.e.push_back(s / (n * n));
  }
  double avg = 0;
  constexpr int m = 4096;
  for (int i = 0; i < m; ++i) avg += 2 * k.albedo((i + 0.5) / m) * (i + 0.5) / m / m;
  k.e_avg = avg;
}

}  // namespace

WorkedBsdf kulla_conty_mirror(double alpha, PlantedBug bug) {
  auto k = std::make_shared<KullaConty>(KullaConty{GGX<double>(alpha, alpha), bug, {}, 0});
  tabulate(*k);
  const BsdfSamplerInfo* vndf = find_bsdf_sampler("conductor_vndf");
  BsdfUnderTest b;
  b.name = "Kulla-Conty compensated GGX mirror";
  b.sample = [k, vndf](std::span<const Vec3<double>> wi, std::span<const double> u, std::span<Vec3<double>> wo,
                       std::span<double> pdf, std::span<double> weight, std::span<unsigned char> kept) {
    for (std::size_t i = 0; i < wi.size(); ++i) {
      const double q = k->lobe_probability(wi[i]), u3 = u[3 * i + 2];
      Vec3<double> out;
      if (u3 < q) {  // the lobe: cosine-weighted
        const double r = std::sqrt(u[3 * i]), phi = 2 * std::numbers::pi * u[3 * i + 1];
        out = {r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.0, 1 - r * r))};
      } else {
        const BsdfSampleResult s = vndf->sample(k->ggx, {0.2, 3.9}, wi[i], {u[3 * i], u[3 * i + 1], 0.5});
        if (!s) { kept[i] = 0; continue; }
        out = s->wo;
      }
      kept[i] = out.z() > 0;
      if (!kept[i]) continue;
      wo[i] = out, pdf[i] = k->pdf(wi[i], out);
      weight[i] = k->eval(wi[i], out) / pdf[i];
      if (k->bug == PlantedBug::one_lobe_weight)
        weight[i] = u3 < q ? k->lobe(wi[i], out) * out.z() / (q * out.z() / std::numbers::pi)
                           : k->f_ss_cos(wi[i], out) / ((1 - q) * k->ggx.visible_reflection_pdf(wi[i], out));
    }
  };
  b.eval = [k](std::span<const Vec3<double>> wi, std::span<const Vec3<double>> wo, std::span<double> v) {
    for (std::size_t i = 0; i < wi.size(); ++i) v[i] = k->eval(wi[i], wo[i]);
  };
  b.pdf = [k](std::span<const Vec3<double>> wi, std::span<const Vec3<double>> wo, std::span<double> p) {
    for (std::size_t i = 0; i < wi.size(); ++i) p[i] = k->pdf(wi[i], wo[i]);
  };
  return {std::move(b), Material::mirror(), k->ggx, BatteryReference::none};
}

}  // namespace microsim::test
