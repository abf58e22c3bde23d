// Numerical stability at the extremes: the sweep of src/validate/stability.h over the
// whole grid must stay within its stated bounds (docs/reference/stability.md), the sweep must catch samplers that
// are broken in the ways it claims to detect, the conventions of docs/reference/conventions.md hold exactly, and
// the reformulated samplers agree with their own long-double evaluation where the claimed pdf is too
// ill-conditioned to check them.
#include "validate/stability.h"
#include "binary_path.h"

#include "microfacet/bsdf.h"
#include "microfacet/samplers.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_stability {

using namespace microsim;

namespace {

const StabilityTable& standard_table() {
  static const StabilityTable table = run_stability_sweep();
  return table;
}

const StabilityMetrics* find_row(const StabilityTable& t, std::string_view subject, StabilityRegime regime) {
  for (const StabilityMetrics& r : t.rows)
    if (r.subject == subject && r.regime == regime) return &r;
  return nullptr;
}

}  // namespace

TEST(StabilitySweep, EveryRowIsWithinItsBound) {
  const StabilityTable& t = standard_table();
  for (const StabilityMetrics& r : t.rows)
    EXPECT_EQ(stability_violations(r), "") << r.subject << " / " << stability_regime_name(r.regime)
                                           << " worst angle: " << r.worst_angle_config
                                           << " worst rel: " << r.worst_rel_config
                                           << " worst cond: " << r.worst_cond_config
                                           << " worst claimed: " << r.worst_claimed_config;
}

TEST(StabilitySweep, CoversEverySamplerAndFunctionInEveryRegime) {
  const StabilityTable& t = standard_table();
  const StabilityRegime regimes[] = {StabilityRegime::moderate,     StabilityRegime::u_at_ends,
                                     StabilityRegime::small_alpha,  StabilityRegime::large_alpha,
                                     StabilityRegime::anisotropic,  StabilityRegime::grazing,
                                     StabilityRegime::exactly_grazing, StabilityRegime::below_horizon,
                                     StabilityRegime::non_finite_input};
  for (const SamplerInfo& s : sampler_registry())
    for (StabilityRegime regime : regimes) {
      const StabilityMetrics* row = find_row(t, s.name, regime);
      ASSERT_NE(row, nullptr) << s.name << " " << stability_regime_name(regime);
      EXPECT_GT(row->evaluations, 30u) << s.name << " " << stability_regime_name(regime);
    }
  for (const char* f : {"GGX::D", "GGX::slope_pdf", "GGX::Lambda", "GGX::G1", "GGX::G2", "GGX::visible_normal_pdf",
                        "mirror_brdf", "conductor_brdf", "dielectric_bsdf(R)", "dielectric_bsdf(T)"})
    for (StabilityRegime regime : {StabilityRegime::moderate, StabilityRegime::small_alpha, StabilityRegime::grazing,
                                   StabilityRegime::below_horizon, StabilityRegime::non_finite_input})
      EXPECT_NE(find_row(t, f, regime), nullptr) << f << " " << stability_regime_name(regime);
  // The grid is the one of the issue: alpha 1e-4..10, 1:1000 both ways, theta up to 89.999, 90 and 180.
  const StabilityGrid& g = t.grid;
  EXPECT_NE(std::find(g.alphas.begin(), g.alphas.end(), std::pair(1e-4, 0.1)), g.alphas.end());
  EXPECT_NE(std::find(g.alphas.begin(), g.alphas.end(), std::pair(10.0, 0.01)), g.alphas.end());
  for (double theta : {0.0, 89.999, 90.0, 179.9, 180.0})
    EXPECT_NE(std::find(g.thetas_deg.begin(), g.thetas_deg.end(), theta), g.thetas_deg.end()) << theta;
}

TEST(StabilitySweep, IsReproducible) {
  StabilityGrid g = StabilityGrid::standard();
  g.alphas = {{1e-3, 1.0}};
  g.thetas_deg = {45, 89.99};
  const StabilityTable a = run_stability_sweep(g), b = run_stability_sweep(g);
  ASSERT_EQ(a.rows.size(), b.rows.size());
  for (std::size_t i = 0; i < a.rows.size(); ++i) {
    EXPECT_EQ(a.rows[i].evaluations, b.rows[i].evaluations);
    EXPECT_EQ(a.rows[i].angle_float_double, b.rows[i].angle_float_double);
    EXPECT_EQ(a.rows[i].cond_float_double, b.rows[i].cond_float_double);
  }
}

// A function's bound follows its trait (FloatAccuracyCaveat, set where the function is listed), not its
// name: a row named like the dielectric transmission but without the trait has the default bound, and the
// traits loosen the bound whatever the row is called.
TEST(StabilityBound, FollowsTheFunctionsTraitNotItsName) {
  StabilityMetrics row;
  row.is_sampler = false;
  row.regime = StabilityRegime::grazing;
  row.subject = "dielectric_bsdf(T)";
  EXPECT_EQ(stability_bound(row).cond_float_double, 8);
  row.subject = "some_function";
  row.float_caveat = FloatAccuracyCaveat::cancelling_half_vector_at_grazing;
  EXPECT_EQ(stability_bound(row).cond_float_double, 64);
  row.regime = StabilityRegime::moderate;
  EXPECT_EQ(stability_bound(row).cond_float_double, 8);
  row.subject = "bounded2023_reflection_pdf";
  row.float_caveat = FloatAccuracyCaveat::none;
  EXPECT_FALSE(stability_bound(row).zero_flips_at_u_ends);
  row.float_caveat = FloatAccuracyCaveat::threshold_slack_of_eps;
  EXPECT_TRUE(stability_bound(row).zero_flips_at_u_ends);
  // The sweep gives the listed functions their traits.
  const StabilityMetrics* t = find_row(standard_table(), "dielectric_bsdf(T)", StabilityRegime::grazing);
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->float_caveat, FloatAccuracyCaveat::cancelling_half_vector_at_grazing);
  const StabilityMetrics* b = find_row(standard_table(), "bounded2023_reflection_pdf", StabilityRegime::moderate);
  ASSERT_NE(b, nullptr);
  EXPECT_EQ(b->float_caveat, FloatAccuracyCaveat::threshold_slack_of_eps);
}

// ---- the sweep catches what it claims to catch --------------------------------------------------------

namespace {

// Heitz 2018 evaluated the naive way (cos/sin of a rounded 2 pi u, height above the disk as
// sqrt(1 - p1^2 - p2^2), Nh.z by a plain dot product): right in distribution, unstable in float at the
// rim of the disk and at grazing views, where 1 - p1^2 - p2^2 cancels.
template <class T> SampleResult<T> naive_heitz2018(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u) {
  if (!wi.allFinite() || !u.allFinite() || !(wi.squaredNorm() > T(0))) return std::nullopt;
  const T sign = wi.z() < T(0) ? T(-1) : T(1);
  const Vec3<T> w = sign * wi;
  const Vec3<T> vh = Vec3<T>(ggx.alpha_x() * w.x(), ggx.alpha_y() * w.y(), w.z()).normalized();
  const T lensq = vh.x() * vh.x() + vh.y() * vh.y();
  const Vec3<T> t1 = lensq > T(0) ? Vec3<T>(Vec3<T>(-vh.y(), vh.x(), T(0)) / std::sqrt(lensq)) : Vec3<T>(1, 0, 0);
  const Vec3<T> t2 = vh.cross(t1);
  const T r = std::sqrt(clamp_unit(u.x())), phi = T(2) * kPi<T> * clamp_unit(u.y());
  const T p1 = r * std::cos(phi);
  const T s = T(0.5) * (T(1) + vh.z());
  const T p2 = (T(1) - s) * std::sqrt(std::max(T(1) - p1 * p1, T(0))) + s * r * std::sin(phi);
  const Vec3<T> nh = p1 * t1 + p2 * t2 + std::sqrt(std::max(T(1) - p1 * p1 - p2 * p2, T(0))) * vh;
  const Vec3<T> m = Vec3<T>(ggx.alpha_x() * nh.x(), ggx.alpha_y() * nh.y(), std::max(nh.z(), T(0))).normalized();
  return DirectionSample<T>{sign * m, ggx.visible_normal_pdf(w, m)};
}

// The library's sampler with a 0/0 at u.x == 0 (an unguarded division).
template <class T> SampleResult<T> nan_at_u0(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u) {
  SampleResult<T> s = sample_heitz2018(ggx, wi, u);
  if (s) s->pdf *= u.x() / u.x();
  return s;
}

// The library's sampler claiming a pdf 1e-6 too large.
template <class T> SampleResult<T> pdf_off_by_1e6(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u) {
  SampleResult<T> s = sample_heitz2018(ggx, wi, u);
  if (s) s->pdf *= T(1) + T(1e-6);
  return s;
}

double claimed_vndf(const GGX<double>& g, const Vec3<double>& wi, const Vec3<double>& m) {
  return g.visible_normal_pdf(wi, m);
}

// Broken copies of a VNDF sampler (registry traits: those of an ordinary VNDF sampler).
constexpr SamplerInfo broken(std::string_view name, decltype(SamplerInfo::sample_float) f,
                             decltype(SamplerInfo::sample_double) d) {
  return {.name = name, .description = "", .domain = SampleDomain::microfacet_normal, .negative_control = false,
          .claims = ClaimedPdf::visible_normals, .reference = false, .returned_pdf_check = ReturnedPdfCheck::everywhere,
          .sample_float = f, .sample_double = d, .claimed_pdf = &claimed_vndf, .claimed_pdf_jump = nullptr};
}

constexpr SamplerInfo kBroken[] = {
    broken("naive-heitz2018", &naive_heitz2018<float>, &naive_heitz2018<double>),
    broken("nan-at-u0", &nan_at_u0<float>, &nan_at_u0<double>),
    broken("pdf-off-by-1e-6", &pdf_off_by_1e6<float>, &pdf_off_by_1e6<double>),
};

}  // namespace

TEST(StabilitySweep, CatchesBrokenSamplers) {
  StabilityGrid g = StabilityGrid::standard();
  g.alphas = {{1e-3, 1e-3}, {0.3, 0.3}, {1e-4, 0.1}};
  g.thetas_deg = {0, 45, 89.99, 90, 120};
  g.phis_deg = {30};
  g.random_u_per_view = 16;
  const StabilityTable t = run_stability_sweep(g, kBroken, /*include_functions=*/false);
  auto violations_of = [&](std::string_view subject) {
    std::string all;
    for (const StabilityMetrics& r : t.rows)
      if (r.subject == subject) all += stability_violations(r) + " | ";
    return all;
  };
  const std::string naive = violations_of("naive-heitz2018");
  EXPECT_NE(naive.find("angle"), std::string::npos) << naive;
  EXPECT_NE(naive.find("rel f-d"), std::string::npos) << naive;
  const std::string nan = violations_of("nan-at-u0");
  EXPECT_NE(nan.find("non-finite (double)"), std::string::npos) << nan;
  EXPECT_NE(nan.find("non-finite (float)"), std::string::npos) << nan;
  const std::string off = violations_of("pdf-off-by-1e-6");
  EXPECT_NE(off.find("rel claimed"), std::string::npos) << off;
  EXPECT_NE(off.find("cond claimed"), std::string::npos) << off;
}

// ---- conventions (docs/reference/conventions.md) -----------------------------------------------------------------

namespace {
const Vec2<double> kCornerUs[] = {{0, 0}, {0, 0.5}, {0.5, 0}, {0.5, 0.5}, {1 - 0x1p-53, 0.25}, {0.75, 1 - 0x1p-53},
                                  {1 - 0x1p-53, 1 - 0x1p-53}, {0.3, 0.7}};
}

TEST(SamplerConventions, BelowHorizonSamplesTheBackSide) {
  for (const SamplerInfo& s : sampler_registry())
    for (double alpha : {1e-4, 0.3, 2.0})
      for (double theta : {0.0, 45.0, 89.9, 90.0}) {
        const GGX<double> ggx(alpha, alpha * 0.5);
        const Vec3<double> wi = direction_from_degrees(theta, 30.0);
        for (const Vec2<double>& u : kCornerUs) {
          const auto up = s.sample_double(ggx, wi, u), down = s.sample_double(ggx, Vec3<double>(-wi), u);
          ASSERT_EQ(up.has_value(), down.has_value()) << s.name;
          if (!up) continue;
          EXPECT_EQ(down->direction, Vec3<double>(-up->direction)) << s.name << " theta " << theta;
          EXPECT_EQ(down->pdf, up->pdf) << s.name;
          if (!s.negative_control) {  // the claimed pdf follows the same rule
            EXPECT_EQ(s.claimed_pdf(ggx, Vec3<double>(-wi), down->direction), s.claimed_pdf(ggx, wi, up->direction));
          }
        }
      }
}

TEST(SamplerConventions, UOfOneActsAsTheLargestValueBelowOne) {
  const GGX<double> gd(0.3, 0.1);
  const GGX<float> gf(0.3f, 0.1f);
  const Vec3<double> wi = direction_from_degrees(60.0, 20.0);
  for (const SamplerInfo& s : sampler_registry()) {
    const auto at_one = s.sample_double(gd, wi, Vec2<double>(1, 1));
    const auto below = s.sample_double(gd, wi, Vec2<double>(kOneMinusEpsilon<double>, kOneMinusEpsilon<double>));
    ASSERT_EQ(at_one.has_value(), below.has_value()) << s.name;
    if (at_one) {
      EXPECT_EQ(at_one->direction, below->direction) << s.name;
    }
    // In float, 1 - 2^-53 rounds to 1 and behaves as 1 - 2^-24.
    const Vec3<float> wf(float(wi.x()), float(wi.y()), float(wi.z()));
    const auto f_one = s.sample_float(gf, wf, Vec2<float>(float(1 - 0x1p-53), 1.0f));
    const auto f_below = s.sample_float(gf, wf, Vec2<float>(1.0f - 0x1p-24f, 1.0f - 0x1p-24f));
    ASSERT_EQ(f_one.has_value(), f_below.has_value()) << s.name;
    if (f_one) {
      EXPECT_EQ(f_one->direction, f_below->direction) << s.name;
    }
  }
}

TEST(SamplerConventions, NonFiniteOrZeroInputGivesNoSample) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  const GGX<double> ggx(0.3);
  for (const SamplerInfo& s : sampler_registry()) {
    EXPECT_FALSE(s.sample_double(ggx, Vec3<double>(nan, 0, 1), Vec2<double>(0.5, 0.5))) << s.name;
    EXPECT_FALSE(s.sample_double(ggx, Vec3<double>(0, 0, inf), Vec2<double>(0.5, 0.5))) << s.name;
    EXPECT_FALSE(s.sample_double(ggx, Vec3<double>(0, 0, 0), Vec2<double>(0.5, 0.5))) << s.name;
    EXPECT_FALSE(s.sample_double(ggx, Vec3<double>(0, 0, 1), Vec2<double>(nan, 0.5))) << s.name;
    EXPECT_FALSE(s.sample_double(ggx, Vec3<double>(0, 0, 1), Vec2<double>(0.5, inf))) << s.name;
  }
  // Analytic functions: 0, never NaN.
  const Vec3<double> bad(inf, 0, 1), m(0, 0, 1);
  EXPECT_EQ(ggx.D(bad), 0);
  EXPECT_EQ(ggx.Lambda(Vec3<double>(nan, 0, 1)), 0);
  EXPECT_EQ(ggx.G1(Vec3<double>(0, 0, inf)), 0);
  EXPECT_EQ(ggx.visible_normal_pdf(bad, m), 0);
  EXPECT_EQ(ggx.slope_pdf(nan, 0), 0);
}

TEST(SamplerConventions, AlphaBelowTheMinimumIsClamped) {
  const GGX<double> tiny(1e-7, 0.0), clamped(kMinAlpha, kMinAlpha);
  EXPECT_EQ(tiny.alpha_x(), kMinAlpha);
  EXPECT_EQ(tiny.alpha_y(), kMinAlpha);
  const Vec3<double> wi = direction_from_degrees(70.0, 10.0);
  for (const SamplerInfo& s : sampler_registry())
    for (const Vec2<double>& u : kCornerUs) {
      const auto a = s.sample_double(tiny, wi, u), b = s.sample_double(clamped, wi, u);
      ASSERT_EQ(a.has_value(), b.has_value());
      if (a) {
        EXPECT_EQ(a->direction, b->direction) << s.name;
      }
    }
}

TEST(SamplerConventions, ExactlyGrazingViewIsSampled) {
  const Vec3<double> wi(std::sqrt(0.5), std::sqrt(0.5), 0.0);  // wi.z == 0 exactly
  for (const SamplerInfo& s : sampler_registry()) {
    if (s.negative_control) continue;
    for (double alpha : {1e-4, 0.3, 10.0}) {
      const GGX<double> ggx(alpha);
      int positive = 0;
      for (const Vec2<double>& u : kCornerUs) {
        const auto r = s.sample_double(ggx, wi, u);
        ASSERT_TRUE(r.has_value()) << s.name;
        EXPECT_TRUE(r->direction.allFinite() && std::isfinite(r->pdf) && r->pdf >= 0) << s.name;
        positive += r->pdf > 0;
      }
      EXPECT_GE(positive, 4) << s.name << " alpha " << alpha;
    }
  }
}

TEST(SamplerConventions, HorizonNormalsHaveZeroDensity) {
  const GGX<double> ggx(0.5, 0.2);
  const Vec3<double> wi = direction_from_degrees(40.0, 0.0);
  const Vec3<double> horizontal(-1, 0, 0);
  EXPECT_EQ(ggx.D(horizontal), 0);
  EXPECT_EQ(ggx.visible_normal_pdf(wi, horizontal), 0);
  EXPECT_GT(ggx.D(Vec3<double>(-1, 0, 1e-9).normalized()), 0);  // the limit from above is not 0
  // heitz2014 at u.x == 0 lands exactly on the horizon: it returns that normal with pdf 0, as D_v says.
  const auto s = sample_heitz2014(ggx, wi, Vec2<double>(0.0, 0.3));
  ASSERT_TRUE(s.has_value());
  EXPECT_EQ(s->direction.z(), 0);
  EXPECT_EQ(s->pdf, 0);
  EXPECT_EQ(ggx.visible_normal_pdf(wi, s->direction), 0);
}

TEST(SamplerConventions, BoundedPdfIsZeroOutsideItsCap) {
  // A cap direction c in the band -Vh.z <= c.z < -k Vh.z: inside the VNDF's cap, outside the bounded one.
  const GGX<double> ggx(0.2);
  const Vec3<double> wi = direction_from_degrees(60.0, 0.0);
  const Vec3<double> vh = Vec3<double>(0.2 * wi.x(), 0.2 * wi.y(), wi.z()).normalized();
  const double k = bounded2023_k(ggx, wi);
  ASSERT_LT(k, 0.99);
  const double cz = -0.5 * (1 + k) * vh.z();
  const Vec3<double> c(-std::sqrt(1 - cz * cz), 0, cz);
  const Vec3<double> nh = (vh + c).normalized();
  const Vec3<double> m = Vec3<double>(0.2 * nh.x(), 0.2 * nh.y(), nh.z()).normalized();
  const Vec3<double> wo = reflect(wi, m);
  EXPECT_GT(ggx.visible_reflection_pdf(wi, wo), 0);
  EXPECT_EQ(bounded2023_reflection_pdf(ggx, wi, wo), 0);
  // ... while a direction inside the cap gets D / (2 (k wi.z + t)).
  const auto inside = sample_bounded2023(ggx, wi, Vec2<double>(0.4, 0.6));
  ASSERT_TRUE(inside.has_value());
  EXPECT_NEAR(bounded2023_reflection_pdf(ggx, wi, inside->direction), inside->pdf, 1e-12 * inside->pdf);
}

// ---- where the claimed pdf is too ill-conditioned, the reformulated samplers agree with long double ----

namespace {
std::string fmt_sci(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2e", v);
  return buf;
}

template <class T> SampleResult<T> sample_by_name(std::string_view name, const GGX<T>& g, const Vec3<T>& wi, Vec2<T> u) {
  if (name == "ndf") return sample_ndf(g, wi, u);
  if (name == "heitz2014") return sample_heitz2014(g, wi, u);
  if (name == "heitz2018") return sample_heitz2018(g, wi, u);
  if (name == "dupuy2023") return sample_dupuy2023(g, wi, u);
  return sample_bounded2023(g, wi, u);
}
}  // namespace

TEST(LongDoubleAgreement, SamplersAtTheEndsOfTheirDomain) {
  for (const char* name : {"ndf", "heitz2014", "heitz2018", "dupuy2023", "bounded2023"}) {
    double worst_rel = 0, worst_angle = 0;
    for (auto [ax, ay] : {std::pair(1e-4, 1e-4), std::pair(1e-4, 0.1), std::pair(0.5, 0.5), std::pair(10.0, 0.01)})
      for (double theta : {0.0, 0.001, 80.0, 89.999, 90.0})
        for (double phi : {0.0, 137.0}) {
          const Vec3<double> wi = theta == 90.0 ? Vec3<double>(std::cos(phi * kPi<double> / 180),
                                                               std::sin(phi * kPi<double> / 180), 0)
                                                : direction_from_degrees(theta, phi);
          for (double u0 : {0.0, 0.5, 1 - 0x1p-24, 1 - 0x1p-53})
            for (double u1 : {0.0, 0.5, 1 - 0x1p-24, 1 - 0x1p-53}) {
              const auto d = sample_by_name<double>(name, GGX<double>(ax, ay), wi, Vec2<double>(u0, u1));
              const auto l = sample_by_name<long double>(name, GGX<long double>(ax, ay), wi.cast<long double>(),
                                                         Vec2<long double>(u0, u1));
              ASSERT_EQ(d.has_value(), l.has_value()) << name;
              if (!d) continue;
              const Vec3<long double> dl = d->direction.cast<long double>();
              const double angle = double(std::atan2(dl.cross(l->direction).norm(), dl.dot(l->direction)));
              const long double denom = std::max(std::abs(l->pdf), std::abs((long double)d->pdf));
              const double rel = denom > 0 ? double(std::abs(d->pdf - l->pdf) / denom) : 0.0;
              worst_angle = std::max(worst_angle, angle);
              worst_rel = std::max(worst_rel, rel);
              EXPECT_LT(angle, 1e-13) << name << " alpha " << ax << "," << ay << " theta " << theta << " u " << u0
                                      << "," << u1;
              EXPECT_LT(rel, 1e-13) << name << " alpha " << ax << "," << ay << " theta " << theta << " u " << u0
                                    << "," << u1;
            }
        }
    RecordProperty(std::string(name) + "_worst_rel", fmt_sci(worst_rel));
    RecordProperty(std::string(name) + "_worst_angle", fmt_sci(worst_angle));
  }
}

// heitz2014's inverse CDF in y: both root solvers reach a residual of a few ulps over their whole range,
// and the (cos b, sin b) they give agree with long double.
template <class T> void check_cos2_inverse_cdf(double tol, double rel) {
  for (int i = 0; i <= 2000; ++i) {
    const T u = T(i) / T(2000);
    const Vec2<T> cs = microsim::detail::cos_sin_of_cos2_inverse_cdf(clamp_unit(u));
    const long double b = std::atan2((long double)cs.y(), (long double)cs.x());
    const long double residual = b + std::sin(b) * std::cos(b) - kPi<long double> * ((long double)clamp_unit(u) - 0.5L);
    EXPECT_LT(double(std::abs(residual)), tol) << "u " << u;
    EXPECT_NEAR(double(cs.squaredNorm()), 1.0, 4 * tol);
    const Vec2<long double> ref = microsim::detail::cos_sin_of_cos2_inverse_cdf((long double)clamp_unit(u));
    EXPECT_LE(double(std::abs(ref.x() - cs.x())), rel * double(std::abs(ref.x()))) << "u " << u;  // cos b keeps relative precision at the ends
  }
}

TEST(HeitzDEon2014, InverseCdfOfCos2IsAccurate) {
  check_cos2_inverse_cdf<double>(1e-15, 1e-14);
  check_cos2_inverse_cdf<float>(1e-6, 5e-7);
}

TEST(CosSin2Pi, ExactAtQuarterTurns) {
  EXPECT_EQ(microsim::detail::cos_sin_2pi(0.5), Vec2<double>(-1, 0));
  EXPECT_EQ(microsim::detail::cos_sin_2pi(0.25), Vec2<double>(0, 1));
  EXPECT_EQ(microsim::detail::cos_sin_2pi(0.75f), Vec2<float>(0, -1));
  EXPECT_EQ(microsim::detail::cos_sin_2pi(0.0), Vec2<double>(1, 0));
  for (double u : {0.1, 0.3, 0.6, 0.9, 1 - 0x1p-53}) {
    const Vec2<double> cs = microsim::detail::cos_sin_2pi(u);
    EXPECT_NEAR(cs.x(), std::cos(2 * kPi<double> * u), 1e-15);
    EXPECT_NEAR(cs.y(), std::sin(2 * kPi<double> * u), 1e-15);
  }
}

// ---- the command line -----------------------------------------------------------------------------------

TEST(StabilityCli, PrintsTheTableWritesJsonAndRejectsBadPaths) {
  const std::string json = ::testing::TempDir() + "microsim_stability_test.json";
  std::remove(json.c_str());
  const std::string out = ::testing::TempDir() + "microsim_stability_test.md";
  const std::string cmd = microsim::test::microsim_binary() + " stability --random-u 4 --json " + json + " > " + out + " 2>/dev/null";
  const int rc = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(rc));
  EXPECT_EQ(WEXITSTATUS(rc), 0);
  std::ifstream in(json);
  ASSERT_TRUE(in.good());
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j.at("violations").get<int>(), 0);
  EXPECT_GT(j.at("rows").size(), 100u);
  EXPECT_EQ(j.at("grid").at("random_u_per_view").get<int>(), 4);
  std::ifstream table(out);
  const std::string text((std::istreambuf_iterator<char>(table)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("| heitz2018 | grazing 85-90 |"), std::string::npos);
  EXPECT_NE(text.find("PASS"), std::string::npos);
  // A --json path in a missing directory: exit 2 before any work, nothing written.
  const std::string bad = "/nonexistent-microsim-dir/x.json";
  const int rc2 = std::system((microsim::test::microsim_binary() + " stability --json " + bad + " > /dev/null 2>&1").c_str());
  ASSERT_TRUE(WIFEXITED(rc2));
  EXPECT_EQ(WEXITSTATUS(rc2), 2);
  std::remove(json.c_str());
  std::remove(out.c_str());
}

}  // namespace test_stability
