// A renderer's eval() and pdf() against the exact single-scattering BSDF, pointwise (eval_check.h).
#include "validate/eval_check.h"
#include "stats/json_values.h"

#include "microfacet/bsdf.h"
#include "microfacet/bsdf_samplers.h"

#include <fmt/core.h>
#include <fmt/format.h>

#include <algorithm>
#include <functional>
#include <span>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace microsim {

namespace {

constexpr double kToleranceFactor = 16;      // K of eval_check.h
constexpr double kLooseRelativeTolerance = 1e-2;
constexpr double kDerivativeStep = 1e-6;
// A renderer's formula may be conditioned worse than the reference's (at grazing views, G1(wi) / cos wi of the
// visible normals): an allowance of that many epsilons of its arithmetic, beside the Fresnel amplification.
constexpr double kConditioningAllowance = 1024;

}  // namespace

template <class T>
T bsdf_value_cos(const Material& bsdf, const GGX<T>& ggx, const BsdfConvention& convention, int c, const Vec3<T>& wi,
                 const Vec3<T>& wo) {
  switch (bsdf.kind()) {
    case MaterialKind::mirror: return mirror_brdf(ggx, wi, wo, convention.masking) * std::max(wo.z(), T(0));
    case MaterialKind::conductor: {
      const std::complex<T> ior(T(bsdf.ior(c).real()), T(bsdf.ior(c).imag()));
      return conductor_brdf(ggx, ior, wi, wo, convention.masking) * std::max(wo.z(), T(0));
    }
    case MaterialKind::dielectric: return dielectric_bsdf_as(ggx, T(bsdf.eta()), wi, wo, convention) * std::abs(wo.z());
    case MaterialKind::lambertian: break;
  }
  throw std::invalid_argument("an eval check needs a mirror, a conductor or a dielectric");
}

namespace {

// A dielectric pair seen from wi's side (mirrored when wi is below): reflection or refraction by the side of
// wo, the generalised half vector (Walter 2007 eq. 13, 16) oriented to +z, and F at it; valid = false for
// backfacing microfacets or a degenerate pair.
template <class T> struct DielectricPair {
  bool valid = false, reflect = false;
  Vec3<T> wi, wo, h;
  T eta = 1, F = 0;
};

template <class T>
DielectricPair<T> dielectric_pair(double eta_material, const Vec3<T>& wi_given, const Vec3<T>& wo_given) {
  DielectricPair<T> p;
  const bool below = wi_given.z() < T(0);
  p.wi = Vec3<T>(wi_given.x(), wi_given.y(), below ? -wi_given.z() : wi_given.z());
  p.wo = Vec3<T>(wo_given.x(), wo_given.y(), below ? -wo_given.z() : wo_given.z());
  p.reflect = p.wo.z() > T(0);
  p.eta = below ? T(1 / eta_material) : T(eta_material);  // across over wi's side
  if (!(p.wi.z() > T(0)) || p.wo.z() == T(0)) return p;
  Vec3<T> h = p.reflect ? Vec3<T>(p.wi + p.wo) : Vec3<T>(-(p.wi + p.eta * p.wo));
  const T len = h.norm();
  if (!(len > T(0))) return p;
  p.h = h / len;
  if (p.h.z() < T(0)) p.h = -p.h;
  const T ih = p.wi.dot(p.h), oh = p.wo.dot(p.h);
  p.valid = ih > T(0) && (p.reflect ? oh > T(0) : oh < T(0));
  if (p.valid) p.F = fresnel_dielectric(ih, p.eta);
  return p;
}

}  // namespace

template <class T>
T renderer_pdf(const Material& bsdf, const GGX<T>& ggx, const Vec3<T>& wi, const Vec3<T>& wo, SampledNormals normals) {
  if (!bsdf.transmits() && normals == SampledNormals::visible)
    return wi.z() > T(0) && wo.z() > T(0) ? ggx.visible_reflection_pdf(wi, wo) : T(0);
  if (!bsdf.transmits()) {
    if (!(wi.z() > T(0) && wo.z() > T(0))) return T(0);
    const Vec3<T> h = (wi + wo).normalized();
    return sampled_normal_pdf(ggx, normals, wi, h) / (T(4) * wo.dot(h));
  }
  const DielectricPair<T> p = dielectric_pair(bsdf.eta(), wi, wo);
  if (!p.valid) return T(0);
  const T ih = p.wi.dot(p.h), oh = p.wo.dot(p.h), dv = sampled_normal_pdf(ggx, normals, p.wi, p.h);
  if (p.reflect) return dv * p.F / (T(4) * oh);
  const T denom = ih + p.eta * oh;
  return dv * (T(1) - p.F) * p.eta * p.eta * std::abs(oh) / (denom * denom);
}

template double bsdf_value_cos(const Material&, const GGX<double>&, const BsdfConvention&, int, const Vec3<double>&,
                               const Vec3<double>&);
template float bsdf_value_cos(const Material&, const GGX<float>&, const BsdfConvention&, int, const Vec3<float>&,
                              const Vec3<float>&);
template double renderer_pdf(const Material&, const GGX<double>&, const Vec3<double>&, const Vec3<double>&,
                             SampledNormals);
template float renderer_pdf(const Material&, const GGX<float>&, const Vec3<float>&, const Vec3<float>&, SampledNormals);

EvalColumns EvalColumns::parse(std::string_view spec) {
  EvalColumns c;
  std::size_t start = 0;
  while (start <= spec.size()) {
    const std::size_t end = std::min(spec.find(',', start), spec.size());
    const std::string item(spec.substr(start, end - start));
    if (item != "wi" && item != "wo" && item != "value" && item != "pdf" && item != "-")
      throw std::invalid_argument(fmt::format("eval columns '{}': unknown column '{}' (wi, wo, value, pdf, -)", spec, item));
    if (item != "-" && std::count(c.items.begin(), c.items.end(), item) > 0)
      throw std::invalid_argument(fmt::format("eval columns '{}': {} given twice", spec, item));
    c.items.push_back(item);
    start = end + 1;
  }
  for (const char* needed : {"wi", "wo", "value"})
    if (std::count(c.items.begin(), c.items.end(), needed) == 0)
      throw std::invalid_argument(fmt::format("eval columns '{}': no {} column", spec, needed));
  return c;
}

bool EvalColumns::has_pdf() const { return std::count(items.begin(), items.end(), "pdf") > 0; }

namespace {

// The sample-file column spec of an eval row: `wanted` direction as x,y,z, the values as weights and the pdf
// when `extras`, every other column skipped.
SampleColumns eval_sample_columns(const EvalColumns& c, int channels, const std::string& wanted, bool extras) {
  std::vector<std::string> names;
  for (const std::string& item : c.items) {
    if (item == wanted) names.insert(names.end(), {"x", "y", "z"});
    else if (item == "wi" || item == "wo") names.insert(names.end(), {"-", "-", "-"});
    else if (item == "value") names.insert(names.end(), std::size_t(channels), extras ? "weight" : "-");
    else names.push_back(item == "pdf" && extras ? "pdf" : "-");
  }
  return SampleColumns::parse(fmt::format("{}", fmt::join(names, ",")));
}

}  // namespace

SampleColumns EvalColumns::wi_columns(int channels) const { return eval_sample_columns(*this, channels, "wi", true); }
SampleColumns EvalColumns::wo_columns(int channels) const { return eval_sample_columns(*this, channels, "wo", false); }

double EvalMismatch::excess() const {
  if (!std::isfinite(given)) return std::numeric_limits<double>::infinity();
  return std::abs(given - reference) / tolerance;
}

namespace {

// The epsilons a compared number is known to: the renderer's arithmetic, the stored values and directions.
struct Epsilons {
  double arithmetic, value, direction;
};

// Text has no storage epsilon: each row's printed digits say how exact it is (RowDigits).
Epsilons epsilons(const DirectionSampleReader& reader, Precision arithmetic) {
  const double e32 = std::numeric_limits<float>::epsilon() / 2, e64 = std::numeric_limits<double>::epsilon() / 2;
  const double a = arithmetic == Precision::float32 ? e32 : e64;
  if (reader.storage().find("text") != std::string::npos) return {a, 0, 0};
  return reader.is_float32() ? Epsilons{a, e32, e32} : Epsilons{a, e64, e64};
}

// A text row's printed rounding (sample_io.h, PrintedRounding), absolute: of its values, its pdf and its two
// directions' components; 0 for binary storage.
struct RowDigits {
  double value = 0, pdf = 0, direction = 0;
};

Vec3<float> float_direction(const Vec3<double>& w) { return w.cast<float>(); }

// One reference (a channel's value, or the pdf) at (wi, wo), in double and in the renderer's arithmetic.
using Reference = std::function<double(const Vec3<double>&, const Vec3<double>&, bool as_float)>;

// The summed |d ref / d x| over the six direction components (central differences, renormalised).
double direction_sensitivity(const Reference& ref, const Vec3<double>& wi, const Vec3<double>& wo) {
  double sum = 0;
  for (int k = 0; k < 6; ++k) {
    Vec3<double> a = k < 3 ? wi : wo, b = a;
    a[k % 3] += kDerivativeStep;
    b[k % 3] -= kDerivativeStep;
    const double fa = k < 3 ? ref(a.normalized(), wo, false) : ref(wi, a.normalized(), false);
    const double fb = k < 3 ? ref(b.normalized(), wo, false) : ref(wi, b.normalized(), false);
    sum += std::abs(fa - fb) / (2 * kDerivativeStep);
  }
  return sum;
}

// The factor a relative rounding of the cosine at the facet is amplified by in a dielectric's value: c F'(c)
// over F (a reflection) or over 1 - F (a refraction), F' by central differences. Renderers compute F from
// that cosine with a square root of 1 - sin^2 that cancels near total internal reflection (pbrt-v4
// FrDielectric), and 1 - F cancels there too; 1 for a conductor, whose F is smooth.
double fresnel_amplification(const Material& bsdf, const Vec3<double>& wi, const Vec3<double>& wo) {
  if (!bsdf.transmits()) return 1;
  const DielectricPair<double> p = dielectric_pair(bsdf.eta(), wi, wo);
  if (!p.valid) return 1;
  const double c = p.wi.dot(p.h), step = 1e-7 * c;
  const double slope = (fresnel_dielectric(c + step, p.eta) - fresnel_dielectric(c - step, p.eta)) / (2 * step);
  const double lobe = p.reflect ? p.F : 1 - p.F;
  return lobe > 0 ? 1 + std::abs(c * slope) / lobe + (p.reflect ? 0 : p.F / lobe) : 1;
}

// The amplification of a rounded sin^2 of the pair's half vector in D, as renderers compute D
// (GGX::cancellation_of_D); 0 for no lobe.
double ndf_conditioning(const Material& bsdf, const GGX<double>& ggx, const Vec3<double>& wi, const Vec3<double>& wo) {
  const DielectricPair<double> p = dielectric_pair(bsdf.transmits() ? bsdf.eta() : 1.0, wi, wo);
  if (!p.valid || (!bsdf.transmits() && !p.reflect)) return 0;
  return ggx.cancellation_of_D(p.h);
}

// The renderer's rounding of the directions and the half vector is a perturbation of its inputs by its
// epsilon: the direction term takes the larger of storage (or printed digits) and arithmetic. A printed
// number is within its half unit of the value held: that much more, once.
double eval_tolerance(const Reference& ref, double value, const Vec3<double>& wi, const Vec3<double>& wo, const Epsilons& e,
                      double amplification, double printed, double printed_direction) {
  const double in_arithmetic = e.arithmetic > 1e-10 ? ref(wi, wo, true) : value;
  const double rounding = std::isfinite(in_arithmetic) ? std::abs(in_arithmetic - value) : std::abs(value);
  const double eps_in = std::max({e.direction, e.arithmetic, printed_direction});
  return kToleranceFactor * (rounding + e.arithmetic * (amplification + kConditioningAllowance) * std::abs(value) + e.value * std::abs(value)) +
         printed + 2 * eps_in * direction_sensitivity(ref, wi, wo) + 1e-300;
}

// Keeps the `limit` largest excesses, failures first.
void keep_worst(std::vector<EvalMismatch>& worst, EvalMismatch m, std::size_t limit) {
  worst.push_back(std::move(m));
  std::sort(worst.begin(), worst.end(), [](const EvalMismatch& a, const EvalMismatch& b) { return a.excess() > b.excess(); });
  if (worst.size() > limit) worst.pop_back();
}

struct EvalContext {
  const Material& bsdf;
  GGX<double> ggx;
  GGX<float> ggx32;
  EvalCheckOptions options;
  Epsilons eps;
};

// Compares one number; records it in the report.
void compare_number(EvalCheckReport& r, const EvalContext& x, const Reference& ref, std::uint64_t row, const Vec3<double>& wi,
                    const Vec3<double>& wo, const std::string& quantity, double given, bool pdf, const RowDigits& digits) {
  const double value = ref(wi, wo, false);
  EvalMismatch m{row, wi, wo, quantity, given, value,
                 eval_tolerance(ref, value, wi, wo, x.eps,
                                fresnel_amplification(x.bsdf, wi, wo) + ndf_conditioning(x.bsdf, x.ggx, wi, wo),
                                pdf ? digits.pdf : digits.value, digits.direction)};
  ++(pdf ? r.pdfs_checked : r.values_checked);
  if (value != 0 && m.tolerance > kLooseRelativeTolerance * std::abs(value)) ++r.loose;
  else if (value != 0) r.max_relative_tolerance_tight = std::max(r.max_relative_tolerance_tight, m.tolerance / std::abs(value));
  const bool failed = !(m.excess() <= 1);
  if (failed) ++(pdf ? r.pdf_failures : r.value_failures);
  if (failed || r.worst.size() < x.options.worst || m.excess() > r.worst.back().excess())
    keep_worst(r.worst, std::move(m), x.options.worst);
}

Reference value_reference(const EvalContext& x, int c) {
  return [&x, c](const Vec3<double>& wi, const Vec3<double>& wo, bool as_float) {
    return as_float ? double(bsdf_value_cos(x.bsdf, x.ggx32, x.options.convention, c, float_direction(wi), float_direction(wo)))
                    : bsdf_value_cos(x.bsdf, x.ggx, x.options.convention, c, wi, wo);
  };
}

Reference pdf_reference(const EvalContext& x) {
  return [&x](const Vec3<double>& wi, const Vec3<double>& wo, bool as_float) {
    const SampledNormals normals = x.options.convention.normals;
    return as_float ? double(renderer_pdf(x.bsdf, x.ggx32, float_direction(wi), float_direction(wo), normals))
                    : renderer_pdf(x.bsdf, x.ggx, wi, wo, normals);
  };
}

// One row: every channel's value and the pdf (a mirror's or conductor's wi below the surface is skipped).
void check_row(EvalCheckReport& r, const EvalContext& x, std::uint64_t row, const Vec3<double>& wi, const Vec3<double>& wo,
               const double* values, const double* pdf, const RowDigits& digits = {}) {
  if (!x.bsdf.transmits() && wi.z() <= 0 && wi.allFinite()) {
    ++r.skipped_below;
    return;
  }
  const int channels = x.bsdf.channels();
  for (int c = 0; c < channels; ++c)
    compare_number(r, x, value_reference(x, c), row, wi, wo, "value " + x.bsdf.channel_name(c), values[c], false, digits);
  if (pdf != nullptr) compare_number(r, x, pdf_reference(x), row, wi, wo, "pdf", *pdf, true, digits);
}

std::vector<std::string> eval_notes(const EvalCheckReport& r, const EvalContext& x, bool has_pdf) {
  std::vector<std::string> notes;
  notes.push_back(fmt::format("values in {}; tolerances from {} arithmetic and the file's {} storage",
                              x.bsdf.transmits() ? describe(x.options.convention)
                                                 : (x.options.convention.masking == MaskingForm::separable
                                                        ? "separable masking G1(wi) G1(wo)"
                                                        : "height-correlated masking G2"),
                              x.options.arithmetic == Precision::float32 ? "float32" : "float64", r.storage));
  if (!has_pdf) notes.push_back("the pdfs were not checked: the file has no pdf column");
  else if (x.options.convention.normals == SampledNormals::ndf)
    notes.push_back("pdfs against sampling the normals from D(m) cos (Walter et al. 2007), the lobe chosen by wo's side "
                    "and Fresnel");
  else notes.push_back("pdfs against VNDF sampling with the lobe chosen by wo's side and Fresnel (pbrt-v4, Mitsuba 3)");
  if (r.skipped_below > 0)
    notes.push_back(fmt::format("{} rows with wi below the surface of a one-sided BSDF were not checked (renderers "
                                "differ: pbrt-v4 mirrors them, Mitsuba 3 returns 0)", r.skipped_below));
  if (r.loose > 0)
    notes.push_back(fmt::format("{} numbers checked loosely (tolerance above 1%: a kink of the BSDF, the horizon, the peak of a low roughness where D computed from cos theta_m cancels)", r.loose));
  return notes;
}

}  // namespace

EvalCheckReport check_eval_file(const std::filesystem::path& file, const EvalColumns& columns, const Material& bsdf,
                                const GGX<double>& ggx, const EvalCheckOptions& options) {
  if (bsdf.kind() == MaterialKind::lambertian) throw std::invalid_argument("an eval check needs a mirror, a conductor or a dielectric");
  const int channels = bsdf.channels();
  DirectionSampleReader wi_reader(file, columns.wi_columns(channels)), wo_reader(file, columns.wo_columns(channels));
  wi_reader.set_frame(options.frame);
  wo_reader.set_frame(options.frame);
  const EvalContext x{bsdf, ggx, GGX<float>(float(ggx.alpha_x()), float(ggx.alpha_y())), options,
                      epsilons(wi_reader, options.arithmetic)};
  EvalCheckReport r;
  r.file = file.string();
  r.storage = wi_reader.storage();
  const bool has_pdf = columns.has_pdf();
  std::vector<Vec3<double>> wi(kSampleFileBlock), wo(kSampleFileBlock);
  std::vector<double> pdfs(has_pdf ? kSampleFileBlock : 0), values(kSampleFileBlock * std::size_t(channels));
  std::vector<PrintedRounding> wi_digits(kSampleFileBlock), wo_digits(kSampleFileBlock);
  for (std::size_t n; (n = wi_reader.read(wi, pdfs, values, wi_digits)) > 0;) {
    if (wo_reader.read(std::span<Vec3<double>>(wo.data(), n), {}, {}, wo_digits) != n)
      throw SampleFileError(file.string() + ": rows differ");
    if (options.run.cancelled()) throw Cancelled("the eval check");
    for (std::size_t i = 0; i < n; ++i) {
      const RowDigits digits{wi_digits[i].weight, wi_digits[i].pdf, std::max(wi_digits[i].direction, wo_digits[i].direction)};
      check_row(r, x, r.rows + i, wi[i], wo[i], &values[i * std::size_t(channels)], has_pdf ? &pdfs[i] : nullptr, digits);
    }
    r.rows += n;
  }
  r.passed = r.value_failures == 0 && r.pdf_failures == 0;
  r.notes = eval_notes(r, x, has_pdf);
  return r;
}

EvalCheckReport check_eval_values(std::span<const BsdfQuery> pairs, std::span<const double> values,
                                  std::span<const double> pdfs, const Material& bsdf, const GGX<double>& ggx,
                                  const EvalCheckOptions& options, const std::string& name) {
  if (bsdf.kind() == MaterialKind::lambertian) throw std::invalid_argument("an eval check needs a mirror, a conductor or a dielectric");
  const std::size_t channels = std::size_t(bsdf.channels());
  if (values.size() != pairs.size() * channels || (!pdfs.empty() && pdfs.size() != pairs.size()))
    throw std::invalid_argument(fmt::format("eval check: {} pairs, {} values, {} pdfs", pairs.size(), values.size(), pdfs.size()));
  const double eps = options.arithmetic == Precision::float32 ? std::numeric_limits<float>::epsilon() / 2
                                                              : std::numeric_limits<double>::epsilon() / 2;
  const EvalContext x{bsdf, ggx, GGX<float>(float(ggx.alpha_x()), float(ggx.alpha_y())), options, Epsilons{eps, eps, eps}};
  EvalCheckReport r;
  r.file = name;
  r.storage = "in process";
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    if (i % 4096 == 0 && options.run.cancelled()) throw Cancelled("the eval check");
    check_row(r, x, i, pairs[i].wi, pairs[i].wo, &values[i * channels], pdfs.empty() ? nullptr : &pdfs[i]);
  }
  r.rows = pairs.size();
  r.passed = r.value_failures == 0 && r.pdf_failures == 0;
  r.notes = eval_notes(r, x, !pdfs.empty());
  return r;
}

namespace {
nlohmann::json mismatch_json(const EvalMismatch& m) {
  return {{"row", m.row},
          {"wi", {m.wi.x(), m.wi.y(), m.wi.z()}},
          {"wo", {m.wo.x(), m.wo.y(), m.wo.z()}},
          {"quantity", m.quantity},
          {"given", finite_or_null(m.given)},
          {"reference", m.reference},
          {"tolerance", m.tolerance},
          {"excess", finite_or_null(m.excess())}};
}
}  // namespace

nlohmann::json to_json(const EvalCheckReport& r) {
  nlohmann::json worst = nlohmann::json::array();
  for (const EvalMismatch& m : r.worst) worst.push_back(mismatch_json(m));
  return {{"verdict", r.passed ? "pass" : "fail"},
          {"file", r.file},
          {"storage", r.storage},
          {"rows", r.rows},
          {"values_checked", r.values_checked},
          {"pdfs_checked", r.pdfs_checked},
          {"value_failures", r.value_failures},
          {"pdf_failures", r.pdf_failures},
          {"skipped_below", r.skipped_below},
          {"loose", r.loose},
          {"max_relative_tolerance_tight", r.max_relative_tolerance_tight},
          {"worst", worst},
          {"notes", r.notes}};
}

}  // namespace microsim
