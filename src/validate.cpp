// microsim: the statistical validator of direction samplers (validate.h, docs/validation.md).
#include "microsim/validate.h"

#include "microsim/progress.h"
#include "microsim/random.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace microsim {
namespace {

// Samples are drawn and reduced in blocks of this many: per-block partial sums combined in block order
// keep every floating-point result independent of the thread count.
constexpr std::uint64_t kBlock = 1 << 16;

template <class T>
SampleSet draw_samples_as(SampleResult<T> (*sample)(const GGX<T>&, const Vec3<T>&, Vec2<T>), const GGX<double>& ggx,
                       const Vec3<double>& wi, const ValidationOptions& options) {
  const std::uint64_t n = options.samples;
  SampleSet set;
  set.directions.assign(n, Vec3<double>::Zero());
  set.pdfs.assign(n, 0.0);
  set.valid.assign(n, 0);
  const GGX<T> g(T(ggx.alpha_x()), T(ggx.alpha_y()));
  const Vec3<T> w = wi.template cast<T>();
  const std::uint64_t blocks = (n + kBlock - 1) / kBlock;
  ProgressBar bar("sampling", n, options.progress);
  tbb::parallel_for(std::uint64_t(0), blocks, [&](std::uint64_t b) {
    const std::uint64_t end = std::min(n, (b + 1) * kBlock);
    for (std::uint64_t i = b * kBlock; i < end; ++i) {
      CounterRng rng(options.seed, i);
      Vec2<T> u;
      if constexpr (std::is_same_v<T, float>) {
        u = Vec2<T>(rng.uniform_float(), rng.uniform_float());
      } else {
        u = Vec2<T>(rng.uniform(), rng.uniform());
      }
      const SampleResult<T> s = sample(g, w, u);
      if (!s) continue;
      set.directions[i] = s->direction.template cast<double>();
      set.pdfs[i] = double(s->pdf);
      set.valid[i] = 1;
    }
    bar.add(end - b * kBlock);
  });
  bar.finish();
  return set;
}

// Mean and sum of squared deviations of a block (Welford), combined across blocks in order
// (Chan, Golub, LeVeque 1983).
struct Moments {
  double n = 0, mean = 0, m2 = 0;
  void add(double x) {
    n += 1;
    const double d = x - mean;
    mean += d / n;
    m2 += d * (x - mean);
  }
  void merge(const Moments& o) {
    if (o.n == 0) return;
    const double total = n + o.n, d = o.mean - mean;
    mean += d * o.n / total;
    m2 += o.m2 + d * d * n * o.n / total;
    n = total;
  }
};

double relative_difference(double a, double b) {
  if (a == b) return 0.0;  // both 0 included
  if (!std::isfinite(a) || !std::isfinite(b)) return std::numeric_limits<double>::infinity();
  return std::abs(a - b) / std::max(std::abs(a), std::abs(b));
}

// Largest relative change of the claimed pdf when the direction w moves by `step` (radians) along
// either tangent direction: how much of a pdf mismatch the rounding of w alone can explain.
double rounding_sensitivity(const ReferenceDistribution& ref, const Vec3<double>& w, double claimed, double step) {
  Vec3<double> t1, t2;
  orthonormal_basis(w, t1, t2);
  double s = 0;
  for (const Vec3<double>& t : {t1, Vec3<double>(-t1), t2, Vec3<double>(-t2)})
    s = std::max(s, relative_difference(ref.pdf(Vec3<double>((w + step * t).normalized())), claimed));
  return s;
}

std::string format_direction(const Vec3<double>& w) { return fmt::format("({:.6f}, {:.6f}, {:.6f})", w.x(), w.y(), w.z()); }

ValidationReport validate_set(std::string name, const SampleSet& set, const ReferenceDistribution& ref,
                              const ValidationOptions& options, Precision precision) {
  ValidationReport r;
  r.sampler = std::move(name);
  r.domain = ref.domain;
  r.alpha_x = ref.ggx.alpha_x();
  r.alpha_y = ref.ggx.alpha_y();
  r.wi = ref.wi;
  r.samples = set.directions.size();
  r.seed = options.seed;
  r.precision = precision;
  r.significance = options.significance;
  const std::uint64_t n = r.samples;
  if (n == 0) throw std::invalid_argument("validation needs at least one sample");
  const bool has_pdf = !set.pdfs.empty();

  // ---- per-sample work in parallel: bins, domain, pdf error, weight moments ---------------------------
  std::vector<int> sphere_bin(n, -1), lobe_bin(n, -1);
  std::vector<std::uint8_t> outside(n, 0);
  const std::uint64_t blocks = (n + kBlock - 1) / kBlock;
  std::vector<Moments> weight_moments(blocks);
  std::vector<double> pdf_worst(blocks, 0.0);
  std::vector<std::uint64_t> pdf_worst_index(blocks, 0), pdf_outliers(blocks, 0);
  // The stored direction carries the rounding of its precision (a float sample has |dw| ~ 1e-7): where
  // the claimed pdf is ill-conditioned (a jump, or D at alpha = 1e-3 seen through a cancelling half
  // vector) that alone can change the analytic pdf by more than the tolerance.
  const double direction_rounding = precision == Precision::float32 ? 2 * 0x1p-24 : 2 * 0x1p-53;
  const double pdf_tol = options.pdf_tolerance > 0 ? options.pdf_tolerance
                         : precision == Precision::float32 ? kPdfToleranceFloat
                                                           : kPdfToleranceDouble;
  const bool weight_applicable = has_pdf && ref.domain == SampleDomain::microfacet_normal;
  const bool back = ref.wi.z() < 0;
  const Vec3<double> wi_front = back ? Vec3<double>(-ref.wi) : ref.wi;
  tbb::parallel_for(std::uint64_t(0), blocks, [&](std::uint64_t b) {
    const std::uint64_t end = std::min(n, (b + 1) * kBlock);
    for (std::uint64_t i = b * kBlock; i < end; ++i) {
      if (!set.valid[i]) {
        if (weight_applicable) weight_moments[b].add(0.0);  // a failed sample contributes weight 0
        continue;
      }
      const Vec3<double>& w = set.directions[i];
      if (!w.allFinite() || !(std::abs(w.norm() - 1) <= options.unit_tolerance)) {
        outside[i] = 1;
        continue;
      }
      if (const auto s = ref.sphere.bin_of(w)) sphere_bin[i] = *s;
      if (const auto l = ref.lobe.bin_of(w)) lobe_bin[i] = *l;
      if (has_pdf) {
        const double claimed = ref.pdf(w);
        const double e = relative_difference(set.pdfs[i], claimed);
        if (e > pdf_tol && e > pdf_tol + 2 * rounding_sensitivity(ref, w, claimed, direction_rounding)) ++pdf_outliers[b];
        if (e > pdf_worst[b]) {
          pdf_worst[b] = e;
          pdf_worst_index[b] = i;
        }
      }
      if (weight_applicable) {
        const Vec3<double> m = back ? Vec3<double>(-w) : w;
        const double numerator = ref.ggx.D(m) * std::max(wi_front.dot(m), 0.0);
        const double p = set.pdfs[i];
        double weight = 0;
        if (numerator > 0) weight = p > 0 ? numerator / p : std::numeric_limits<double>::infinity();
        weight_moments[b].add(weight);
      }
    }
  });

  // ---- counts (integers: order-free) -------------------------------------------------------------------
  const int ns = ref.sphere.size(), nl = ref.lobe.size();
  std::vector<double> sphere_obs(ns + 1, 0.0), lobe_obs(nl + 1, 0.0);
  for (std::uint64_t i = 0; i < n; ++i) {
    if (!set.valid[i]) {
      ++r.failed_samples;
      sphere_obs[ns] += 1;
      lobe_obs[nl] += 1;
      continue;
    }
    if (outside[i]) {
      ++r.outside_domain;
      continue;
    }
    // A finite unit vector always has a sphere bin.
    sphere_obs[sphere_bin[i]] += 1;
    lobe_obs[lobe_bin[i] >= 0 ? lobe_bin[i] : nl] += 1;
  }
  // Expected probabilities; the last cell is the remainder: mass the claimed pdf leaves outside the
  // bins, where failed samples (and samples outside the lobe parameter space) are counted.
  auto with_remainder = [](const BinIntegrals& b) {
    std::vector<double> p = b.probability;
    p.push_back(std::max(0.0, 1.0 - b.total));
    return p;
  };
  ChiSquareOptions chi;
  chi.significance = options.significance;  // replaced by the Sidak level below for the verdict
  chi.worst_cells = options.worst_cells;
  chi.describe_cell = [&](int bin) {
    return bin < ns ? ref.sphere.describe_bin(bin) : std::string("remainder (failed samples)");
  };
  r.sphere = goodness_of_fit(sphere_obs, with_remainder(ref.sphere_probability), double(n), chi, double(r.outside_domain));
  chi.describe_cell = [&](int bin) {
    return bin < nl ? ref.lobe.describe_bin(bin) : std::string("remainder (failed or outside the lobe space)");
  };
  r.lobe = goodness_of_fit(lobe_obs, with_remainder(ref.lobe_probability), double(n), chi, double(r.outside_domain));
  auto comparison = [&](const DirectionBinning& b, const std::vector<double>& obs, const BinIntegrals& p) {
    BinnedComparison c{b, std::vector<double>(obs.begin(), obs.begin() + b.size()), p.probability, "analytic pdf"};
    for (double& e : c.expected) e *= double(n);
    return c;
  };
  r.histograms = {comparison(ref.sphere, sphere_obs, ref.sphere_probability),
                  comparison(ref.lobe, lobe_obs, ref.lobe_probability)};

  // ---- hard checks ---------------------------------------------------------------------------------------
  r.domain_check.name = "domain";
  r.domain_check.value = double(r.outside_domain);
  r.domain_check.tolerance = 0;
  r.domain_check.passed = r.outside_domain == 0;
  r.domain_check.detail = fmt::format("{} sample(s) non-finite or with | |w| - 1 | > {}", r.outside_domain,
                                      options.unit_tolerance);

  r.integral.name = "pdf_integral";
  r.integral.value = ref.sphere_probability.total;
  r.integral.tolerance = options.integral_tolerance;
  r.integral.passed = std::isfinite(ref.sphere_probability.total) &&
                      ref.sphere_probability.total <= 1 + options.integral_tolerance;
  r.integral.detail = fmt::format("integral of the claimed pdf over the sphere = {:.9f} (cubature error estimate {:.1e}), "
                                  "must not exceed 1 + {}",
                                  ref.sphere_probability.total, ref.sphere_probability.error_estimate,
                                  options.integral_tolerance);

  r.pdf.name = "returned_pdf";
  r.pdf.applicable = has_pdf;
  if (has_pdf) {
    double worst = 0;
    std::uint64_t worst_i = 0, outliers = 0;
    for (std::uint64_t b = 0; b < blocks; ++b) {
      outliers += pdf_outliers[b];
      if (pdf_worst[b] > worst) {
        worst = pdf_worst[b];
        worst_i = pdf_worst_index[b];
      }
    }
    const double fraction = std::max(options.pdf_outlier_fraction, 0.0);
    const auto allowed = std::uint64_t(std::floor(fraction * double(n)));
    r.pdf.value = worst;
    r.pdf.tolerance = pdf_tol;
    r.pdf.passed = outliers <= allowed;
    r.pdf.detail = worst > 0 ? fmt::format("max |returned - claimed| / max(returned, claimed) = {:.3e} at sample {} "
                                           "{}: returned {:.9g}, claimed {:.9g}; {} sample(s) above {:.0e} plus the "
                                           "change a rounding of the direction can cause ({} allowed)",
                                           worst, worst_i, format_direction(set.directions[worst_i]),
                                           set.pdfs[worst_i], ref.pdf(set.directions[worst_i]), outliers, pdf_tol,
                                           allowed)
                             : std::string("returned pdf equals the claimed pdf on every sample");
  } else {
    r.pdf.detail = "no returned pdf (samples from a file)";
  }

  // ---- E[weight] against the projected area |wi.z| / G1(wi) --------------------------------------------
  r.weight.name = "weight_mean";
  r.weight.applicable = weight_applicable;
  r.weight.statistical = weight_applicable;
  if (weight_applicable) {
    Moments all;
    for (const Moments& m : weight_moments) all.merge(m);
    const double expected = ref.ggx.projected_area(ref.wi);
    const double rounding = options.weight_rounding > 0 ? options.weight_rounding
                            : precision == Precision::float32 ? 1e-5
                                                              : 1e-9;
    const double se_stat = all.n > 1 ? std::sqrt(all.m2 / (all.n - 1) / all.n) : 0.0;
    const double se = std::sqrt(se_stat * se_stat + (rounding * expected) * (rounding * expected));
    const double z = (all.mean - expected) / se;
    r.weight.value = all.mean;
    r.weight.tolerance = expected;
    r.weight.p_value = std::isfinite(z) ? std::erfc(std::abs(z) / std::sqrt(2.0)) : 0.0;
    r.weight.detail = fmt::format("mean weight {:.9g} vs |wi.z|/G1 = {:.9g}: z = {:.3f} (standard error {:.3e}, "
                                  "rounding floor {:.0e} relative)",
                                  all.mean, expected, z, se_stat, rounding);
  } else {
    r.weight.detail = has_pdf ? "not applicable: samples are reflected directions"
                              : "not applicable: no returned pdf (samples from a file)";
  }

  // ---- verdict ---------------------------------------------------------------------------------------------
  std::vector<double> p_values = {r.sphere.p_value, r.lobe.p_value};
  if (r.weight.statistical) p_values.push_back(r.weight.p_value);
  r.statistical_tests = int(p_values.size());
  r.per_test_significance = sidak_significance(options.significance, r.statistical_tests);
  const double p_min = *std::min_element(p_values.begin(), p_values.end());
  r.p_value = sidak_adjusted_p(p_min, r.statistical_tests);
  for (ChiSquareResult* c : {&r.sphere, &r.lobe}) {
    c->significance = r.per_test_significance;
    c->rejected = c->p_value < r.per_test_significance;
  }
  r.weight.passed = !r.weight.statistical || r.weight.p_value >= r.per_test_significance;
  const ChiSquareResult& headline = r.sphere.p_value < r.lobe.p_value ? r.sphere : r.lobe;
  r.statistic = headline.statistic;
  r.dof = headline.dof;

  if (!r.domain_check.passed) r.failures.push_back(r.domain_check.detail);
  if (!r.integral.passed) r.failures.push_back(r.integral.detail);
  if (has_pdf && !r.pdf.passed) r.failures.push_back("returned pdf differs from the claimed pdf: " + r.pdf.detail);
  if (r.sphere.rejected)
    r.failures.push_back(fmt::format("chi-square in sphere bins rejects: p = {:.3g} < {:.3g}{}", r.sphere.p_value,
                                     r.per_test_significance, r.sphere.reason.empty() ? "" : " (" + r.sphere.reason + ")"));
  if (r.lobe.rejected)
    r.failures.push_back(fmt::format("chi-square in lobe bins rejects: p = {:.3g} < {:.3g}{}", r.lobe.p_value,
                                     r.per_test_significance, r.lobe.reason.empty() ? "" : " (" + r.lobe.reason + ")"));
  if (!r.weight.passed)
    r.failures.push_back(fmt::format("E[weight] test rejects: p = {:.3g} < {:.3g}: {}", r.weight.p_value,
                                     r.per_test_significance, r.weight.detail));
  r.passed = r.failures.empty();
  return r;
}

double elapsed(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

std::shared_ptr<const ReferenceDistribution> prepare_reference(DirectionFunction pdf, SampleDomain domain,
                                                               const GGX<double>& ggx, const Vec3<double>& wi_in, int rows,
                                                               std::vector<DirectionFunction> breaks) {
  const Vec3<double> wi = wi_in.normalized();
  auto sphere = DirectionBinning::sphere(rows);
  auto lobe = DirectionBinning::lobe(ggx, wi, domain, rows);
  // In lobe space the pdfs of the zoo are smooth and spread over the whole parameter space (the VNDF
  // is a clamped cosine there): plain adaptive cubature suffices.
  IntegrationOptions options;
  options.breaks = std::move(breaks);
  IntegrationOptions sphere_options = options;
  // In sphere space the lobe can be far narrower than a bin: focus on it with a lattice uniform in the
  // lobe parameter space, which covers every region with mass however narrow (alpha = 1e-3) or thin
  // (anisotropy, grazing reflections).
  sphere_options.focus = lobe.lattice_directions(4096);
  // Where the pdfs of the zoo jump, in sphere coordinates: normals at m.z = 0; reflected directions
  // where the half vector reaches the horizon, wo.z = -wi.z.
  sphere_options.z_breaks = {0.0};
  if (domain == SampleDomain::reflected_direction) sphere_options.z_breaks.push_back(-wi.z());
  auto sphere_p = sphere.integrate(pdf, sphere_options);
  auto lobe_p = lobe.integrate(pdf, options);
  return std::make_shared<const ReferenceDistribution>(ReferenceDistribution{
      domain, ggx, wi, std::move(pdf), std::move(sphere), std::move(lobe), std::move(sphere_p), std::move(lobe_p)});
}

namespace {
// The boundary of the support of the bounded VNDF sampler (Eto & Tokuyoshi 2023, sec. 3): the cap
// direction c = reflect(Vh, Nh) of the half vector must satisfy c.z >= -k Vh.z. Zero on the boundary
// (same back-side and half-vector conventions as bounded2023_reflection_pdf).
DirectionFunction bounded2023_cap_boundary(const GGX<double>& ggx, const Vec3<double>& wi_in) {
  return [ggx, wi_in](const Vec3<double>& wo_in) {
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
  };
}
}  // namespace

std::shared_ptr<const ReferenceDistribution> claimed_reference(const SamplerInfo& sampler, const GGX<double>& ggx,
                                                               const Vec3<double>& wi_in, int rows) {
  const Vec3<double> wi = wi_in.normalized();
  std::vector<DirectionFunction> breaks;
  // Known jumps of the zoo's claimed pdfs beyond the common ones: the bounded sampler's cap.
  if (sampler.name == "bounded2023") breaks.push_back(bounded2023_cap_boundary(ggx, wi));
  auto claimed = sampler.claimed_pdf;
  return prepare_reference([claimed, ggx, wi](const Vec3<double>& d) { return claimed(ggx, wi, d); }, sampler.domain,
                           ggx, wi, rows, std::move(breaks));
}

std::shared_ptr<const ReferenceDistribution> vndf_reference(SampleDomain domain, const GGX<double>& ggx,
                                                            const Vec3<double>& wi, int rows) {
  const Vec3<double> w = wi.normalized();
  if (domain == SampleDomain::microfacet_normal)
    return prepare_reference([ggx, w](const Vec3<double>& m) { return ggx.visible_normal_pdf(w, m); }, domain, ggx, w, rows);
  return prepare_reference([ggx, w](const Vec3<double>& o) { return ggx.visible_reflection_pdf(w, o); }, domain, ggx, w,
                           rows);
}

SampleSet SampleSet::from_directions(std::span<const Vec3<double>> directions) {
  SampleSet set;
  set.directions.assign(directions.begin(), directions.end());
  set.valid.assign(directions.size(), 1);
  return set;
}

SampleSet draw_samples(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                       const ValidationOptions& options) {
  return options.precision == Precision::float32 ? draw_samples_as<float>(sampler.sample_float, ggx, wi, options)
                                                 : draw_samples_as<double>(sampler.sample_double, ggx, wi, options);
}

ValidationReport validate_sampler(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                                  const ValidationOptions& options, std::shared_ptr<const ReferenceDistribution> reference) {
  const auto t0 = std::chrono::steady_clock::now();
  if (options.samples == 0) throw std::invalid_argument("validation needs at least one sample");
  if (!reference) reference = claimed_reference(sampler, ggx, wi, options.rows);
  const SampleSet set = draw_samples(sampler, ggx, reference->wi, options);
  ValidationReport r = validate_set(std::string(sampler.name), set, *reference, options, options.precision);
  r.seconds = elapsed(t0);
  return r;
}

ValidationReport validate_samples(std::span<const Vec3<double>> samples, SampleDomain domain, const GGX<double>& ggx,
                                  const Vec3<double>& wi, const ValidationOptions& options,
                                  std::shared_ptr<const ReferenceDistribution> reference) {
  const auto t0 = std::chrono::steady_clock::now();
  if (samples.empty()) throw std::invalid_argument("validation needs at least one sample");
  if (!reference) reference = vndf_reference(domain, ggx, wi, options.rows);
  ValidationOptions o = options;
  o.samples = samples.size();
  ValidationReport r = validate_set("samples", SampleSet::from_directions(samples), *reference, o, Precision::float64);
  r.seconds = elapsed(t0);
  return r;
}

std::string to_string(Precision precision) { return precision == Precision::float32 ? "float" : "double"; }

nlohmann::json to_json(const SubTest& t) {
  auto num = [](double v) -> nlohmann::json { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  nlohmann::json j;
  j["name"] = t.name;
  j["applicable"] = t.applicable;
  j["statistical"] = t.statistical;
  j["passed"] = t.passed;
  if (t.statistical) j["p_value"] = t.p_value;
  j["value"] = num(t.value);
  j["tolerance"] = num(t.tolerance);
  j["detail"] = t.detail;
  return j;
}

nlohmann::json to_json(const ValidationReport& r) {
  auto num = [](double v) -> nlohmann::json { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  nlohmann::json j;
  j["verdict"] = r.passed ? "pass" : "fail";
  j["p_value"] = r.p_value;
  j["statistic"] = num(r.statistic);
  j["dof"] = r.dof;
  j["samples"] = r.samples;
  j["seed"] = r.seed;
  j["sampler"] = r.sampler;
  j["domain"] = to_string(r.domain);
  j["alpha"] = {r.alpha_x, r.alpha_y};
  j["wi"] = {r.wi.x(), r.wi.y(), r.wi.z()};
  j["theta_deg"] = std::acos(std::clamp(r.wi.z(), -1.0, 1.0)) * 180 / kPi<double>;
  j["phi_deg"] = std::atan2(r.wi.y(), r.wi.x()) * 180 / kPi<double>;
  j["precision"] = to_string(r.precision);
  j["failed_samples"] = r.failed_samples;
  j["outside_domain"] = r.outside_domain;
  j["significance"] = r.significance;
  j["statistical_tests"] = r.statistical_tests;
  j["per_test_significance"] = r.per_test_significance;
  j["failures"] = r.failures;
  j["seconds"] = r.seconds;
  nlohmann::json tests;
  tests["chi2_sphere"] = to_json(r.sphere);
  tests["chi2_lobe"] = to_json(r.lobe);
  tests["weight_mean"] = to_json(r.weight);
  tests["returned_pdf"] = to_json(r.pdf);
  tests["pdf_integral"] = to_json(r.integral);
  tests["domain"] = to_json(r.domain_check);
  j["tests"] = tests;
  return j;
}

}  // namespace microsim
