// microsim: the numerical-stability sweep of the sampler zoo and the analytic Smith-GGX functions
// (see src/validate/stability.h for what is measured and docs/reference/stability.md for the table and its bounds).
#include "validate/stability.h"
#include "stats/json_values.h"

#include "microfacet/bsdf.h"
#include "core/block_runner.h"
#include "core/random.h"
#include "microfacet/samplers.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>

namespace microsim {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kOneMinus2m24 = 1.0 - 0x1p-24;  // the largest float below 1
constexpr double kOneMinus2m53 = 1.0 - 0x1p-53;  // the largest double below 1 (rounds to 1.0f)

// cos and sin of an angle in degrees, exact on the axes (so that theta = 90 gives z == 0 exactly and
// theta = 180 gives (0, 0, -1), not cos(pi/2) = 6e-17).
void cos_sin_degrees(double deg, double& c, double& s) {
  const double r = std::fmod(deg, 360.0);
  if (r == 0) { c = 1; s = 0; return; }
  if (r == 90) { c = 0; s = 1; return; }
  if (r == 180) { c = -1; s = 0; return; }
  if (r == 270) { c = 0; s = -1; return; }
  const double rad = deg * std::numbers::pi / 180.0;
  c = std::cos(rad);
  s = std::sin(rad);
}

Vec3<double> view_direction(double theta_deg, double phi_deg) {
  double ct, st, cp, sp;
  cos_sin_degrees(theta_deg, ct, st);
  cos_sin_degrees(phi_deg, cp, sp);
  return {st * cp, st * sp, ct};
}

// Symmetric relative difference: 0 when equal (including equal infinities), 1 when one side is 0.
double symmetric_relative(double a, double b) {
  if (a == b) return 0;
  if (!std::isfinite(a) || !std::isfinite(b)) return kInf;
  return std::abs(a - b) / std::max(std::abs(a), std::abs(b));
}

// Rounds to float component by component. The value goes through a volatile float because GCC 12 at
// -O2 miscompiles the SLP-vectorised pair (double)(float)x into a plain copy of x (observed with Eigen's
// .cast<float>().cast<double>() and with scalar casts alike), which would make the "double reference at
// the float inputs" silently use the unrounded inputs.
template <int N> Eigen::Matrix<float, N, 1> to_float(const Eigen::Matrix<double, N, 1>& v) {
  Eigen::Matrix<float, N, 1> out;
  for (int i = 0; i < N; ++i) {
    volatile float f = static_cast<float>(v[i]);
    out[i] = f;
  }
  return out;
}

double nan_as_inf(double v) { return std::isnan(v) ? kInf : v; }

// Angle between two directions, accurate for small angles (atan2 of |a x b| and a.b).
double angle_between(const Vec3<double>& a, const Vec3<double>& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

bool is_u_end(double u) { return u == 0 || u >= kOneMinus2m24; }

bool extreme_view_regime(StabilityRegime r) {
  return r == StabilityRegime::grazing || r == StabilityRegime::exactly_grazing || r == StabilityRegime::below_horizon;
}

StabilityRegime classify(double ax, double ay, double theta_deg, bool u_end) {
  if (theta_deg > 90) return StabilityRegime::below_horizon;
  if (theta_deg == 90) return StabilityRegime::exactly_grazing;
  if (theta_deg > 85) return StabilityRegime::grazing;
  if (std::max(ax, ay) >= 100 * std::min(ax, ay)) return StabilityRegime::anisotropic;
  if (std::max(ax, ay) <= 1e-3) return StabilityRegime::small_alpha;
  if (std::min(ax, ay) > 2) return StabilityRegime::large_alpha;
  if (u_end) return StabilityRegime::u_at_ends;
  return StabilityRegime::moderate;
}

// Raises `worst` to `value` (NaN counts as infinitely bad) and records where.
template <class Describe> void raise(double& worst, std::string& where, double value, Describe&& describe) {
  if (std::isnan(value)) value = kInf;
  if (value > worst) {
    worst = value;
    where = describe();
  }
}

// ---- the analytic functions under test: f(ggx, wi, x) with x prepared in double by `Input` ------------

enum class Input {
  view_only,         // f(wi)
  normal_upper,      // x = sampled normal flipped to the upper hemisphere
  normal_as_sampled, // x = sampled normal (lower hemisphere for back-side views)
  slopes,            // x = (sx, sy, 0), the slopes of the upper normal
  reflected,         // x = reflect(wi, m)
  refracted,         // x = refraction of wi through m (eta = 1.5 outside -> inside)
};

constexpr double kDielectricEta = 1.5;                        // glass
const std::complex<double> kConductorEta{0.18, 3.42};         // gold at about 600 nm

template <class T> using AnalyticFn = T (*)(const GGX<T>&, const Vec3<T>&, const Vec3<T>&);

struct AnalyticFunction {
  const char* name;
  Input input;
  AnalyticFn<float> f;
  AnalyticFn<double> d;
  FloatAccuracyCaveat caveat = FloatAccuracyCaveat::none;
};

template <class T> T fn_D(const GGX<T>& g, const Vec3<T>&, const Vec3<T>& m) { return g.D(m); }
template <class T> T fn_slope_pdf(const GGX<T>& g, const Vec3<T>&, const Vec3<T>& s) { return g.slope_pdf(s.x(), s.y()); }
template <class T> T fn_Lambda(const GGX<T>& g, const Vec3<T>& wi, const Vec3<T>&) { return g.Lambda(wi); }
template <class T> T fn_G1(const GGX<T>& g, const Vec3<T>& wi, const Vec3<T>&) { return g.G1(wi); }
template <class T> T fn_G2(const GGX<T>& g, const Vec3<T>& wi, const Vec3<T>& wo) { return g.G2(wi, wo); }
template <class T> T fn_Dv(const GGX<T>& g, const Vec3<T>& wi, const Vec3<T>& m) { return g.visible_normal_pdf(wi, m); }
template <class T> T fn_refl_pdf(const GGX<T>& g, const Vec3<T>& wi, const Vec3<T>& wo) {
  return g.visible_reflection_pdf(wi, wo);
}
template <class T> T fn_bounded_pdf(const GGX<T>& g, const Vec3<T>& wi, const Vec3<T>& wo) {
  return bounded2023_reflection_pdf(g, wi, wo);
}
template <class T> T fn_mirror(const GGX<T>& g, const Vec3<T>& wi, const Vec3<T>& wo) { return mirror_brdf(g, wi, wo); }
template <class T> T fn_conductor(const GGX<T>& g, const Vec3<T>& wi, const Vec3<T>& wo) {
  return conductor_brdf(g, std::complex<T>(kConductorEta), wi, wo);
}
template <class T> T fn_dielectric(const GGX<T>& g, const Vec3<T>& wi, const Vec3<T>& wo) {
  return dielectric_bsdf(g, T(kDielectricEta), wi, wo);
}

#define MICROSIM_FN(name, input, fn, ...) AnalyticFunction{name, input, &fn<float>, &fn<double>, ##__VA_ARGS__}
const AnalyticFunction kFunctions[] = {
    MICROSIM_FN("GGX::D", Input::normal_upper, fn_D),
    MICROSIM_FN("GGX::slope_pdf", Input::slopes, fn_slope_pdf),
    MICROSIM_FN("GGX::Lambda", Input::view_only, fn_Lambda),
    MICROSIM_FN("GGX::G1", Input::view_only, fn_G1),
    MICROSIM_FN("GGX::G2", Input::reflected, fn_G2),
    MICROSIM_FN("GGX::visible_normal_pdf", Input::normal_as_sampled, fn_Dv),
    MICROSIM_FN("GGX::visible_reflection_pdf", Input::reflected, fn_refl_pdf),
    MICROSIM_FN("bounded2023_reflection_pdf", Input::reflected, fn_bounded_pdf, FloatAccuracyCaveat::threshold_slack_of_eps),
    MICROSIM_FN("mirror_brdf", Input::reflected, fn_mirror),
    MICROSIM_FN("conductor_brdf", Input::reflected, fn_conductor),
    MICROSIM_FN("dielectric_bsdf(R)", Input::reflected, fn_dielectric),
    MICROSIM_FN("dielectric_bsdf(T)", Input::refracted, fn_dielectric, FloatAccuracyCaveat::cancelling_half_vector_at_grazing),
};
#undef MICROSIM_FN

// Refraction of wi through the facet m (wi.m > 0), from the side of wi into the other; eta_ratio =
// n_other / n_wi. Zero on total internal reflection.
Vec3<double> refract_through(const Vec3<double>& wi, const Vec3<double>& m, double eta_ratio) {
  const double ci = wi.dot(m);
  const double sin2_t = (1 - ci * ci) / (eta_ratio * eta_ratio);
  if (sin2_t >= 1) return Vec3<double>::Zero();
  const double ct = std::sqrt(1 - sin2_t);
  return (-wi / eta_ratio + (ci / eta_ratio - ct) * m).normalized();
}

// The second argument of a function, from a sampled normal m (double, exact inputs). False when the
// function has no meaningful input here (a refraction with total internal reflection, a slope of a
// horizontal normal).
bool prepare_input(Input input, const Vec3<double>& wi, const Vec3<double>& m_sampled, Vec3<double>& x) {
  const Vec3<double> m_up = m_sampled.z() < 0 ? Vec3<double>(-m_sampled) : m_sampled;
  switch (input) {
    case Input::view_only: x = Vec3<double>::Zero(); return true;
    case Input::normal_upper: x = m_up; return true;
    case Input::normal_as_sampled: x = m_sampled; return true;
    case Input::slopes:
      if (!(m_up.z() > 0)) return false;
      x = {-m_up.x() / m_up.z(), -m_up.y() / m_up.z(), 0};
      return true;
    case Input::reflected: x = reflect(wi, m_sampled); return true;
    case Input::refracted: {
      if (!(wi.dot(m_sampled) > 0)) return false;
      const double eta_ratio = wi.z() >= 0 ? kDielectricEta : 1 / kDielectricEta;
      x = refract_through(wi, m_sampled, eta_ratio);
      return !x.isZero();
    }
  }
  return false;
}

// ---- the sweep ----------------------------------------------------------------------------------------

struct Config {
  double ax, ay, theta, phi;
  Vec2<double> u;
  std::string describe() const {
    return fmt::format("alpha=({:g},{:g}) theta={:g} phi={:g} u=({:.17g},{:.17g})", ax, ay, theta, phi, u.x(), u.y());
  }
  std::string describe_view() const { return fmt::format("alpha=({:g},{:g}) theta={:g} phi={:g}", ax, ay, theta, phi); }
};

class Sweep {
public:
  Sweep(const StabilityGrid& grid, std::span<const SamplerInfo> samplers, bool include_functions)
      : samplers_(samplers), include_functions_(include_functions) {
    table_.grid = grid;
    for (const SamplerInfo& s : samplers_)
      subjects_.push_back({std::string(s.name), true, s.negative_control, s.returned_pdf_check, FloatAccuracyCaveat::none});
    for (const AnalyticFunction& f : kFunctions)
      subjects_.push_back({f.name, false, false, ReturnedPdfCheck::everywhere, f.caveat});
    rows_.resize(subjects_.size() * kStabilityRegimeCount);
    for (std::size_t i = 0; i < subjects_.size(); ++i)
      for (int r = 0; r < kStabilityRegimeCount; ++r) {
        StabilityMetrics& row = rows_[i * kStabilityRegimeCount + r];
        row.subject = subjects_[i].name;
        row.is_sampler = subjects_[i].is_sampler;
        row.negative_control = subjects_[i].negative_control;
        row.returned_pdf_check = subjects_[i].returned_pdf_check;
        row.float_caveat = subjects_[i].float_caveat;
        row.regime = StabilityRegime(r);
      }
  }

  // Every (subject, regime) row, as evaluated so far (in the table's order).
  const std::vector<StabilityMetrics>& rows() const { return rows_; }

  // Evaluates block b of the sweep (stability_blocks): view b of the grid (alpha pairs, then thetas, then
  // phis), or, past the last view, the non-finite inputs. On a fresh copy of the sweep: its rows are the
  // block's alone.
  void run_block(std::uint64_t b) {
    const StabilityGrid& g = table_.grid;
    const std::uint64_t per_alpha = g.thetas_deg.size() * g.phis_deg.size();
    if (b >= g.alphas.size() * per_alpha) return run_non_finite();
    const auto& [ax, ay] = g.alphas[b / per_alpha];
    run_view(ax, ay, g.thetas_deg[(b % per_alpha) / g.phis_deg.size()], g.phis_deg[b % g.phis_deg.size()], b);
  }

private:
  struct Subject {
    std::string name;
    bool is_sampler, negative_control;
    ReturnedPdfCheck returned_pdf_check;
    FloatAccuracyCaveat float_caveat;
  };

  StabilityMetrics& row(std::size_t subject, StabilityRegime r) {
    return rows_[subject * kStabilityRegimeCount + int(r)];
  }

  void run_view(double ax, double ay, double theta, double phi, std::uint64_t view_index) {
    const GGX<double> ggx_d(ax, ay);
    const Vec3<double> wi_d = view_direction(theta, phi);
    // Float inputs, and the double reference at exactly these inputs.
    const GGX<float> ggx_f{float(ax), float(ay)};
    const GGX<double> ggx_ref(double(ggx_f.alpha_x()), double(ggx_f.alpha_y()));
    const Vec3<float> wi_f = to_float(wi_d);
    const Vec3<double> wi_ref = wi_f.cast<double>();

    std::vector<Vec2<double>> us;
    for (double u0 : table_.grid.u_values)
      for (double u1 : table_.grid.u_values) us.emplace_back(u0, u1);
    CounterRng rng(table_.grid.seed, view_index);
    for (int i = 0; i < table_.grid.random_u_per_view; ++i) {
      const double u0 = rng.uniform();
      us.emplace_back(u0, rng.uniform());
    }

    // View-only functions: once per view.
    {
      const Config cfg{ax, ay, theta, phi, Vec2<double>(0.5, 0.5)};
      const StabilityRegime regime = classify(ax, ay, theta, false);
      for (std::size_t k = 0; k < std::size(kFunctions) && include_functions_; ++k)
        if (kFunctions[k].input == Input::view_only)
          evaluate_function(k, regime, cfg, ggx_d, wi_d, Vec3<double>::Zero(), ggx_f, ggx_ref, wi_f, wi_ref);
    }

    const auto samplers = samplers_;
    const SamplerInfo* vndf = &reference_sampler(ClaimedPdf::visible_normals);
    const SamplerInfo* ndf = &reference_sampler(ClaimedPdf::ndf_cosine);
    for (const Vec2<double>& u : us) {
      const Config cfg{ax, ay, theta, phi, u};
      const StabilityRegime regime = classify(ax, ay, theta, is_u_end(u.x()) || is_u_end(u.y()));
      for (std::size_t k = 0; k < samplers.size(); ++k)
        evaluate_sampler(k, samplers[k], regime, cfg, ggx_d, wi_d, ggx_f, ggx_ref, wi_f, wi_ref);
      // Functions of (wi, m): at the visible normals of the reference VNDF sampler and at the normals of
      // the reference NDF sampler (which include normals that wi does not see).
      for (const SamplerInfo* source : {vndf, ndf}) {
        if (!include_functions_) break;
        const auto s = source->sample_double(ggx_d, wi_d, u);
        if (!s || !s->direction.allFinite()) continue;
        for (std::size_t k = 0; k < std::size(kFunctions); ++k) {
          if (kFunctions[k].input == Input::view_only) continue;
          Vec3<double> x;
          if (!prepare_input(kFunctions[k].input, wi_d, s->direction, x)) continue;
          evaluate_function(k, regime, cfg, ggx_d, wi_d, x, ggx_f, ggx_ref, wi_f, wi_ref);
        }
      }
    }
  }

  // Moves every component of v by `ulps` ulps of its own type, up or down: bit i of pattern (0..7) set
  // means component i moves up. The 8 patterns reach every corner of the box around v, so the largest
  // change of a function over them bounds its first-order sensitivity to input errors of that size.
  template <class T> static Vec3<T> nudged(const Vec3<T>& v, int pattern, int ulps = 1) {
    Vec3<T> out = v;
    for (int i = 0; i < 3; ++i) {
      const T towards = ((pattern >> i) & 1) ? std::numeric_limits<T>::infinity() : -std::numeric_limits<T>::infinity();
      for (int k = 0; k < ulps; ++k) out[i] = std::nextafter(out[i], towards);
    }
    return out;
  }

  // |a - ref| in units of (eps |ref| + spread), spread = the largest change of the reference when its
  // inputs move by one ulp. 0 when a == ref.
  static double cond_ratio(double a, double ref, double eps, double spread, double tiny) {
    if (a == ref) return 0;
    const double scale = eps * std::abs(ref) + spread + tiny;
    return scale > 0 ? std::abs(a - ref) / scale : kInf;
  }

  void evaluate_sampler(std::size_t k, const SamplerInfo& s, StabilityRegime regime, const Config& cfg,
                        const GGX<double>& ggx_d, const Vec3<double>& wi_d, const GGX<float>& ggx_f,
                        const GGX<double>& ggx_ref, const Vec3<float>& wi_f, const Vec3<double>& wi_ref) {
    StabilityMetrics& r = row(k, regime);
    ++r.evaluations;
    // Double at the exact inputs: finiteness, unit length, claimed pdf.
    const SampleResult<double> rd = s.sample_double(ggx_d, wi_d, cfg.u);
    if (!rd) {
      ++r.empty_double;
    } else if (!rd->direction.allFinite() || !std::isfinite(rd->pdf)) {
      ++r.non_finite_double;
    } else {
      if (rd->pdf < 0) ++r.negative;
      r.norm_error_double = std::max(r.norm_error_double, std::abs(rd->direction.norm() - 1));
      // A reflected direction within 2^-20 of -wi determines no microfacet normal in double (m is
      // recovered from wi + wo): the claimed pdf cannot be evaluated there.
      if (s.domain == SampleDomain::reflected_direction && (wi_d + rd->direction).norm() < 0x1p-20)
      {
        ++r.claimed_unverifiable;
        if (!is_u_end(cfg.u.x()) && !is_u_end(cfg.u.y())) ++r.claimed_unverifiable_interior;
      } else
        compare_with_claimed(r, s, cfg, ggx_d, wi_d, *rd);
    }
    evaluate_sampler_float(r, s, cfg, ggx_f, ggx_ref, wi_f, wi_ref);
  }

  void compare_with_claimed(StabilityMetrics& r, const SamplerInfo& s, const Config& cfg, const GGX<double>& ggx_d,
                            const Vec3<double>& wi_d, const DirectionSample<double>& sample) {
    const double claimed = s.claimed_pdf(ggx_d, wi_d, sample.direction);
    // The sampled direction is accurate to a few ulps: spread of the claimed pdf over +-4 ulps.
    double spread = 0;
    for (int pattern = 0; pattern < 8; ++pattern) {
      const double c = s.claimed_pdf(ggx_d, wi_d, nudged(sample.direction, pattern, 4));
      if (std::isfinite(c)) spread = std::max(spread, std::abs(c - claimed));
    }
    auto describe = [&] {
      return fmt::format("{} x=({:.17g},{:.17g},{:.17g}) pdf={:.17g} claimed={:.17g}", cfg.describe(),
                         sample.direction.x(), sample.direction.y(), sample.direction.z(), sample.pdf, claimed);
    };
    r.rel_claimed = std::max(r.rel_claimed, nan_as_inf(symmetric_relative(sample.pdf, claimed)));
    raise(r.cond_claimed, r.worst_claimed_config,
          cond_ratio(sample.pdf, claimed, std::numeric_limits<double>::epsilon(), spread, 0.0), describe);
  }

  // Float, against double at the same (float) inputs.
  void evaluate_sampler_float(StabilityMetrics& r, const SamplerInfo& s, const Config& cfg, const GGX<float>& ggx_f,
                              const GGX<double>& ggx_ref, const Vec3<float>& wi_f, const Vec3<double>& wi_ref) {
    auto describe = [&] { return cfg.describe(); };
    const Vec2<float> u_rounded = to_float(cfg.u);
    const Vec2<float> u_f(clamp_unit(u_rounded.x()), clamp_unit(u_rounded.y()));
    const SampleResult<float> rf = s.sample_float(ggx_f, wi_f, u_f);
    const SampleResult<double> rr = s.sample_double(ggx_ref, wi_ref, u_f.cast<double>());
    if (!rf) ++r.empty_float;
    if (rf.has_value() != rr.has_value()) ++r.empty_mismatch;
    if (!rf) return;
    if (!rf->direction.allFinite() || !std::isfinite(rf->pdf)) {
      ++r.non_finite_float;
      return;
    }
    if (rf->pdf < 0) ++r.negative;
    r.norm_error_float = std::max(r.norm_error_float, double(std::abs(rf->direction.norm() - 1.0f)));
    if (!rr || !rr->direction.allFinite() || !std::isfinite(rr->pdf)) return;
    raise(r.angle_float_double, r.worst_angle_config, angle_between(rf->direction.cast<double>(), rr->direction),
          describe);
    raise(r.rel_float_double, r.worst_rel_config, symmetric_relative(double(rf->pdf), rr->pdf), describe);
  }

  // Sensitivity of fn (double, at the float inputs) to one-ulp errors of the view and of the second
  // argument, added (first order): the largest change over the 8 nudge patterns of each.
  static double nudge_spread(const AnalyticFunction& fn, const GGX<double>& ggx_ref, const Vec3<float>& wi_f,
                             const Vec3<float>& x_f, const Vec3<double>& wi_ref, double vr) {
    double spread_wi = 0, spread_x = 0;
    for (int pattern = 0; pattern < 8; ++pattern) {
      const double vw = fn.d(ggx_ref, nudged(wi_f, pattern).cast<double>(), x_f.cast<double>());
      if (std::isfinite(vw)) spread_wi = std::max(spread_wi, std::abs(vw - vr));
      if (fn.input == Input::view_only) continue;
      const double vx = fn.d(ggx_ref, wi_ref, nudged(x_f, pattern).cast<double>());
      if (std::isfinite(vx)) spread_x = std::max(spread_x, std::abs(vx - vr));
    }
    return spread_wi + spread_x;
  }

  void evaluate_function(std::size_t k, StabilityRegime regime, const Config& cfg, const GGX<double>& ggx_d,
                         const Vec3<double>& wi_d, const Vec3<double>& x_d, const GGX<float>& ggx_f,
                         const GGX<double>& ggx_ref, const Vec3<float>& wi_f, const Vec3<double>& wi_ref) {
    const AnalyticFunction& fn = kFunctions[k];
    StabilityMetrics& r = row(samplers_.size() + k, regime);
    ++r.evaluations;
    const Vec3<float> x_f = to_float(x_d);
    auto describe = [&] {
      return fn.input == Input::view_only
                 ? cfg.describe_view()
                 : fmt::format("{} x=({:.9g},{:.9g},{:.9g})", cfg.describe(), x_f.x(), x_f.y(), x_f.z());
    };
    // Lambda is +inf exactly on the horizon (its documented value); anything else must be finite.
    auto acceptable = [&](double v, double wz) {
      return std::isfinite(v) || (fn.input == Input::view_only && wz == 0 && v == kInf);
    };
    const double vd = fn.d(ggx_d, wi_d, x_d);
    if (!acceptable(vd, wi_d.z())) ++r.non_finite_double;
    else if (vd < 0) ++r.negative;
    const float vf = fn.f(ggx_f, wi_f, x_f);
    const double vr = fn.d(ggx_ref, wi_ref, x_f.cast<double>());
    if (!acceptable(vf, wi_f.z())) {
      ++r.non_finite_float;
      return;
    }
    if (vf < 0) ++r.negative;
    if (!acceptable(vr, wi_ref.z())) return;
    if (vr == kInf || vf == kInf) {  // Lambda on the horizon: both must be infinite
      if (vf != vr) raise(r.rel_float_double, r.worst_rel_config, kInf, describe);
      return;
    }
    raise(r.rel_float_double, r.worst_rel_config, symmetric_relative(double(vf), vr), describe);
    const double spread = nudge_spread(fn, ggx_ref, wi_f, x_f, wi_ref, vr);
    // Differences below float's smallest subnormal cannot be represented: an absolute term of 2^-149.
    const double ratio = cond_ratio(double(vf), vr, double(std::numeric_limits<float>::epsilon()), spread,
                                    double(std::numeric_limits<float>::denorm_min()));
    // A zero on one side only, beyond what the conditioning explains: the two precisions took different
    // sides of a threshold that is not at the same place in both (bounded2023's cap test has a rounding
    // slack proportional to the type's eps). Counted, not in the ratio.
    if ((vf == 0) != (vr == 0) && ratio > 1) {
      ++r.zero_flips;
      if (!is_u_end(cfg.u.x()) && !is_u_end(cfg.u.y())) ++r.zero_flips_interior;
      return;
    }
    raise(r.cond_float_double, r.worst_cond_config, ratio, [&] {
      return fmt::format("{} f={:.9g} d={:.17g} spread={:.3g}", describe(), vf, vr, spread);
    });
  }

  // Non-finite or degenerate inputs: samplers must return nullopt or a finite sample, functions a
  // finite value (0 by convention).
  inline static const std::vector<Vec3<double>> kBadVectors = {
      {kNaN, 0, 1}, {0, 0, kNaN}, {kInf, 0, 1}, {-kInf, 0.5, 0.5}, {0, 0, kInf}, {0, 0, -kInf},
      {0, 0, 0},  // zero vector: not a direction
  };
  void run_non_finite() {
    for (double alpha : {1e-4, 0.3, 10.0}) {
      const GGX<double> gd(alpha, alpha);
      const GGX<float> gf{float(alpha), float(alpha)};
      for (std::size_t k = 0; k < samplers_.size(); ++k) sampler_on_non_finite(k, gd, gf);
      for (std::size_t k = 0; k < std::size(kFunctions) && include_functions_; ++k) function_on_non_finite(k, gd, gf);
    }
  }

  void sampler_on_non_finite(std::size_t k, const GGX<double>& gd, const GGX<float>& gf) {
    const std::vector<Vec2<double>> bad_us = {{kNaN, 0.5}, {0.5, kNaN}, {kInf, 0.5}, {-kInf, 0.5}, {0.5, kInf}};
    StabilityMetrics& r = row(k, StabilityRegime::non_finite_input);
    const SamplerInfo& sampler = samplers_[k];
    auto check = [&](const Vec3<double>& w, const Vec2<double>& u) {
      ++r.evaluations;
      const auto sd = sampler.sample_double(gd, w, u);
      const auto sf = sampler.sample_float(gf, w.cast<float>(), u.cast<float>());
      if (!sd) ++r.empty_double;
      else if (!sd->direction.allFinite() || !std::isfinite(sd->pdf)) ++r.non_finite_double;
      if (!sf) ++r.empty_float;
      else if (!sf->direction.allFinite() || !std::isfinite(sf->pdf)) ++r.non_finite_float;
    };
    for (const Vec3<double>& w : kBadVectors) check(w, Vec2<double>(0.25, 0.75));
    for (const Vec2<double>& u : bad_us) check(view_direction(60, 30), u);
  }

  void function_on_non_finite(std::size_t k, const GGX<double>& gd, const GGX<float>& gf) {
    const AnalyticFunction& fn = kFunctions[k];
    StabilityMetrics& r = row(samplers_.size() + k, StabilityRegime::non_finite_input);
    auto check = [&](const Vec3<double>& w, const Vec3<double>& x) {
      ++r.evaluations;
      const double vd = fn.d(gd, w, x);
      const float vf = fn.f(gf, w.cast<float>(), x.cast<float>());
      if (!std::isfinite(vd)) ++r.non_finite_double;
      else if (vd < 0) ++r.negative;
      if (!std::isfinite(vf)) ++r.non_finite_float;
      else if (vf < 0) ++r.negative;
    };
    for (const Vec3<double>& bad : kBadVectors) {
      check(bad, fn.input == Input::slopes ? Vec3<double>(0.1, 0.2, 0) : view_direction(20, 200));
      if (fn.input != Input::view_only) check(view_direction(60, 30), bad);
    }
  }

  std::span<const SamplerInfo> samplers_;
  bool include_functions_;
  StabilityTable table_;
  std::vector<Subject> subjects_;
  std::vector<StabilityMetrics> rows_;
};

std::string format_figure(double v) {
  if (v == 0) return "0";
  if (std::isinf(v)) return "inf";
  return fmt::format("{:.1e}", v);
}

}  // namespace

const char* stability_regime_name(StabilityRegime r) {
  switch (r) {
    case StabilityRegime::moderate: return "moderate";
    case StabilityRegime::u_at_ends: return "u at an end";
    case StabilityRegime::small_alpha: return "alpha<=1e-3";
    case StabilityRegime::large_alpha: return "alpha>2";
    case StabilityRegime::anisotropic: return "aniso>=1:100";
    case StabilityRegime::grazing: return "grazing 85-90";
    case StabilityRegime::exactly_grazing: return "theta=90";
    case StabilityRegime::below_horizon: return "below horizon";
    case StabilityRegime::non_finite_input: return "non-finite in";
  }
  return "?";
}

StabilityGrid StabilityGrid::standard() {
  StabilityGrid g;
  for (double a : {1e-4, 1e-3, 0.01, 0.1, 0.5, 1.0, 2.0, 10.0}) g.alphas.emplace_back(a, a);
  // Anisotropy 1:1000 both ways, inside [1e-4, 10]; and a milder 1:10.
  for (double a : {1e-4, 1e-3, 0.01}) {
    g.alphas.emplace_back(a, a * 1000);
    g.alphas.emplace_back(a * 1000, a);
  }
  g.alphas.emplace_back(0.05, 0.5);
  g.alphas.emplace_back(1.0, 0.1);
  g.thetas_deg = {0, 0.001, 45, 80, 89, 89.9, 89.99, 89.999, 90, 95, 120, 179.9, 180};
  g.phis_deg = {0, 45, 90, 137};
  g.u_values = {0.0, 0.5, kOneMinus2m24, kOneMinus2m53};
  return g;
}

std::uint64_t StabilityTable::total_evaluations() const {
  std::uint64_t n = 0;
  for (const StabilityMetrics& r : rows) n += r.evaluations;
  return n;
}

std::size_t StabilityTable::violation_count() const {
  std::size_t n = 0;
  for (const StabilityMetrics& r : rows) n += stability_violations(r).empty() ? 0 : 1;
  return n;
}

std::uint64_t stability_blocks(const StabilityGrid& grid) {
  return grid.alphas.size() * grid.thetas_deg.size() * grid.phis_deg.size() + 1;
}

std::vector<StabilityMetrics> stability_rows(std::span<const SamplerInfo> samplers, bool include_functions) {
  return Sweep(StabilityGrid{}, samplers, include_functions).rows();
}

void merge_metrics(StabilityMetrics& into, const StabilityMetrics& later) {
  for (auto count : {&StabilityMetrics::evaluations, &StabilityMetrics::empty_double, &StabilityMetrics::empty_float,
                     &StabilityMetrics::empty_mismatch, &StabilityMetrics::non_finite_double,
                     &StabilityMetrics::non_finite_float, &StabilityMetrics::negative,
                     &StabilityMetrics::claimed_unverifiable, &StabilityMetrics::claimed_unverifiable_interior,
                     &StabilityMetrics::zero_flips, &StabilityMetrics::zero_flips_interior})
    into.*count += later.*count;
  // Maxima without a configuration (never NaN: std::max keeps the first of a NaN pair, nan_as_inf the rest).
  for (auto worst : {&StabilityMetrics::norm_error_double, &StabilityMetrics::norm_error_float, &StabilityMetrics::rel_claimed})
    into.*worst = std::max(into.*worst, later.*worst);
  // Maxima with the configuration that first reached them: a later block's only when strictly larger.
  const auto raise_to = [&](double StabilityMetrics::*worst, std::string StabilityMetrics::*where) {
    if (later.*worst > into.*worst) {
      into.*worst = later.*worst;
      into.*where = later.*where;
    }
  };
  raise_to(&StabilityMetrics::angle_float_double, &StabilityMetrics::worst_angle_config);
  raise_to(&StabilityMetrics::rel_float_double, &StabilityMetrics::worst_rel_config);
  raise_to(&StabilityMetrics::cond_float_double, &StabilityMetrics::worst_cond_config);
  raise_to(&StabilityMetrics::cond_claimed, &StabilityMetrics::worst_claimed_config);
}

StabilityTable run_stability_sweep(const StabilityGrid& grid, std::span<const SamplerInfo> samplers,
                                   bool include_functions, const StabilityRun& run) {
  const Sweep sweep(grid, samplers, include_functions);
  const BlockPlan plan{stability_blocks(grid), 1};
  std::vector<StabilityMetrics> rows = sweep.rows();
  // Each block on its own copy of the sweep, its rows reduced in block order: the table of the whole
  // sweep, or of a shard that merges with the others into it (merge_metrics).
  const BlockRunStatus status = for_each_block(
      selected_blocks(plan, run.blocks), run.run, BlockSchedule{"stability sweep", plan, 0},
      [&](std::uint64_t b) {
        Sweep block = sweep;
        block.run_block(b);
        return block.rows();
      },
      [&](std::vector<StabilityMetrics> block_rows, std::uint64_t) {
        for (std::size_t k = 0; k < rows.size(); ++k) merge_metrics(rows[k], block_rows[k]);
      });
  StabilityTable table;
  table.grid = grid;
  table.total_blocks = plan.blocks();
  table.blocks = status.done;
  table.partial = status.cancelled;
  for (StabilityMetrics& row : rows)
    if (row.evaluations > 0) table.rows.push_back(std::move(row));
  return table;
}

namespace {

// Bounds of a sampler's row (not the non-finite regime, not the negative control).
void sampler_bound(const StabilityMetrics& row, StabilityBound& b) {
  using R = StabilityRegime;
  const bool extreme_view = extreme_view_regime(row.regime);
  // Float against double at the same inputs. A few float ulps where nothing is extreme; a 1:1000
  // stretch or a grazing view amplifies absolute rounding errors of the hemisphere configuration
  // (section "bounds" of docs/reference/stability.md).
  b.angle_float_double = 2e-6;
  b.rel_float_double = 5e-6;
  if (row.regime == R::anisotropic) {
    b.angle_float_double = 2e-5;
    b.rel_float_double = 2e-5;
  }
  if (extreme_view) {
    b.angle_float_double = 2e-5;
    b.rel_float_double = 5e-5;
  }
  // Returned against claimed pdf (double): within 16 units of the claimed pdf's own conditioning
  // everywhere; plainly relative (1e-12) in the moderate regime, where nothing is ill-conditioned.
  b.cond_claimed = 16;
  b.rel_claimed = row.regime == R::moderate ? 1e-12 : kInf;
  if (row.returned_pdf_check == ReturnedPdfCheck::except_near_back_reflection && row.regime != R::moderate) {
    b.claimed_unverifiable_at_u_ends = true;
    b.note = "reflected directions within 2^-20 of -wi cannot be checked against the claimed pdf";
  }
}

// Bounds of an analytic function's row: float within 8 units of the conditioning at the input.
void function_bound(const StabilityMetrics& row, StabilityBound& b) {
  b.cond_float_double = 8;
  if (row.float_caveat == FloatAccuracyCaveat::cancelling_half_vector_at_grazing && extreme_view_regime(row.regime)) {
    b.cond_float_double = 64;
    b.note = "the generalised half vector -(wi + eta wo) cancels at grazing incidence";
  }
  if (row.float_caveat == FloatAccuracyCaveat::threshold_slack_of_eps) {
    b.zero_flips_at_u_ends = true;
    b.note = "the cap test's rounding slack is proportional to the type's eps";
  }
}

}  // namespace

StabilityBound stability_bound(const StabilityMetrics& row) {
  StabilityBound b;
  b.norm_double = 1e-15;  // a few ulps: every sampler normalises its result last
  b.norm_float = 1e-6;    // a few float ulps: 1e-6 is about 8 ulps of 1.0f
  if (row.regime == StabilityRegime::non_finite_input) {
    b.require_empty = row.is_sampler;  // non-finite or zero view, non-finite u: nullopt
  } else if (row.is_sampler && row.negative_control) {
    // The negative control is wrong in distribution: only finiteness and unit length are asserted.
    b.angle_float_double = b.rel_float_double = b.rel_claimed = b.cond_claimed = kInf;
    b.claimed_unverifiable_at_u_ends = true;
    b.allow_empty = true;
    b.note = "negative control: only NaN-free, non-negative, unit length";
  } else if (row.is_sampler) {
    sampler_bound(row, b);
  } else {
    function_bound(row, b);
  }
  return b;
}

std::string stability_violations(const StabilityMetrics& row) {
  const StabilityBound b = stability_bound(row);
  std::string out;
  auto add = [&](const std::string& s) { out += (out.empty() ? "" : "; ") + s; };
  if (row.non_finite_double) add(fmt::format("{} non-finite (double)", row.non_finite_double));
  if (row.non_finite_float) add(fmt::format("{} non-finite (float)", row.non_finite_float));
  if (row.negative) add(fmt::format("{} negative", row.negative));
  if (row.is_sampler) {
    if (b.require_empty && (row.empty_double != row.evaluations || row.empty_float != row.evaluations))
      add(fmt::format("only {}/{} of {} empty", row.empty_double, row.empty_float, row.evaluations));
    if (!b.require_empty && !b.allow_empty && (row.empty_double || row.empty_float))
      add(fmt::format("{}/{} empty", row.empty_double, row.empty_float));
    if (!b.allow_empty && row.empty_mismatch) add(fmt::format("{} empty mismatches", row.empty_mismatch));
    if (row.norm_error_double > b.norm_double)
      add(fmt::format("norm(d) {:.1e} > {:.0e}", row.norm_error_double, b.norm_double));
    if (row.norm_error_float > b.norm_float)
      add(fmt::format("norm(f) {:.1e} > {:.0e}", row.norm_error_float, b.norm_float));
    if (!(row.angle_float_double <= b.angle_float_double))
      add(fmt::format("angle {:.1e} > {:.0e}", row.angle_float_double, b.angle_float_double));
    if (!(row.rel_float_double <= b.rel_float_double))
      add(fmt::format("rel f-d {:.1e} > {:.0e}", row.rel_float_double, b.rel_float_double));
    if (!(row.rel_claimed <= b.rel_claimed))
      add(fmt::format("rel claimed {:.1e} > {:.0e}", row.rel_claimed, b.rel_claimed));
    if (!(row.cond_claimed <= b.cond_claimed))
      add(fmt::format("cond claimed {:.1f} > {:g}", row.cond_claimed, b.cond_claimed));
    if (row.claimed_unverifiable_interior || (row.claimed_unverifiable && !b.claimed_unverifiable_at_u_ends))
      add(fmt::format("{} unverifiable ({} at interior u)", row.claimed_unverifiable, row.claimed_unverifiable_interior));
  } else {
    if (!(row.cond_float_double <= b.cond_float_double))
      add(fmt::format("cond f-d {:.1f} > {:g}", row.cond_float_double, b.cond_float_double));
    if (row.zero_flips_interior || (row.zero_flips && !b.zero_flips_at_u_ends))
      add(fmt::format("{} zero flips ({} at interior u)", row.zero_flips, row.zero_flips_interior));
  }
  return out;
}

std::string stability_table_markdown(const StabilityTable& table) {
  std::string out;
  out += "| subject | regime | n | empty d/f | f/d mismatch | non-finite d/f | neg | norm err f | norm err d | "
         "angle f-d (rad) | rel f-d | f-d / cond | rel vs claimed | claimed / cond | status |\n";
  out += "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n";
  auto ratio = [](double v) { return v == 0 ? std::string("0") : std::isinf(v) ? std::string("inf") : fmt::format("{:.1f}", v); };
  for (const StabilityMetrics& r : table.rows) {
    const std::string violations = stability_violations(r);
    const bool nf = r.regime == StabilityRegime::non_finite_input;
    const bool sampler_figures = r.is_sampler && !nf;
    out += fmt::format("| {}{} | {} | {} | {} | {} | {}/{} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n", r.subject,
                       r.negative_control ? " (neg. control)" : "", stability_regime_name(r.regime), r.evaluations,
                       r.is_sampler ? fmt::format("{}/{}", r.empty_double, r.empty_float) : "-",
                       sampler_figures ? std::to_string(r.empty_mismatch) : "-", r.non_finite_double,
                       r.non_finite_float, r.negative, sampler_figures ? format_figure(r.norm_error_float) : "-",
                       sampler_figures ? format_figure(r.norm_error_double) : "-",
                       sampler_figures ? format_figure(r.angle_float_double) : "-",
                       nf ? "-" : format_figure(r.rel_float_double),
                       !r.is_sampler && !nf ? ratio(r.cond_float_double) +
                                                  (r.zero_flips ? fmt::format(" ({} flips)", r.zero_flips) : "")
                                            : "-",
                       sampler_figures ? format_figure(r.rel_claimed) +
                                             (r.claimed_unverifiable
                                                  ? fmt::format(" ({} unverifiable)", r.claimed_unverifiable)
                                                  : "")
                                       : "-",
                       sampler_figures ? ratio(r.cond_claimed) : "-",
                       violations.empty() ? "ok" : "FAIL: " + violations);
  }
  return out;
}

namespace {

nlohmann::json bound_json(const StabilityBound& b) {
  return {{"norm_double", finite_or_null(b.norm_double)},
          {"norm_float", finite_or_null(b.norm_float)},
          {"angle_float_double_rad", finite_or_null(b.angle_float_double)},
          {"rel_float_double", finite_or_null(b.rel_float_double)},
          {"cond_float_double", finite_or_null(b.cond_float_double)},
          {"rel_claimed", finite_or_null(b.rel_claimed)},
          {"cond_claimed", finite_or_null(b.cond_claimed)},
          {"claimed_unverifiable_at_u_ends", b.claimed_unverifiable_at_u_ends},
          {"zero_flips_at_u_ends", b.zero_flips_at_u_ends},
          {"allow_empty", b.allow_empty},
          {"require_empty", b.require_empty},
          {"note", b.note}};
}

nlohmann::json row_json(const StabilityMetrics& r) {
  const std::string violations = stability_violations(r);
  return {
      {"subject", r.subject},
      {"sampler", r.is_sampler},
      {"negative_control", r.negative_control},
      {"regime", stability_regime_name(r.regime)},
      {"evaluations", r.evaluations},
      {"empty_double", r.empty_double},
      {"empty_float", r.empty_float},
      {"empty_mismatch", r.empty_mismatch},
      {"non_finite_double", r.non_finite_double},
      {"non_finite_float", r.non_finite_float},
      {"negative", r.negative},
      {"norm_error_double", finite_or_null(r.norm_error_double)},
      {"norm_error_float", finite_or_null(r.norm_error_float)},
      {"angle_float_double_rad", finite_or_null(r.angle_float_double)},
      {"rel_float_double", finite_or_null(r.rel_float_double)},
      {"cond_float_double", finite_or_null(r.cond_float_double)},
      {"rel_claimed", finite_or_null(r.rel_claimed)},
      {"cond_claimed", finite_or_null(r.cond_claimed)},
      {"claimed_unverifiable", r.claimed_unverifiable},
      {"zero_flips", r.zero_flips},
      {"claimed_unverifiable_interior_u", r.claimed_unverifiable_interior},
      {"zero_flips_interior_u", r.zero_flips_interior},
      {"worst_angle_config", r.worst_angle_config},
      {"worst_rel_config", r.worst_rel_config},
      {"worst_cond_config", r.worst_cond_config},
      {"worst_claimed_config", r.worst_claimed_config},
      {"bound", bound_json(stability_bound(r))},
      {"status", violations.empty() ? "ok" : "fail"},
      {"violations", violations},
  };
}

}  // namespace

nlohmann::json stability_table_json(const StabilityTable& table) {
  nlohmann::json rows = nlohmann::json::array();
  for (const StabilityMetrics& r : table.rows) rows.push_back(row_json(r));
  return {{"total_evaluations", table.total_evaluations()},
          {"violations", table.violation_count()},
          {"grid",
           {{"alphas", table.grid.alphas},
            {"thetas_deg", table.grid.thetas_deg},
            {"phis_deg", table.grid.phis_deg},
            {"u_values", table.grid.u_values},
            {"random_u_per_view", table.grid.random_u_per_view},
            {"seed", table.grid.seed}}},
          {"rows", rows}};
}

}  // namespace microsim
