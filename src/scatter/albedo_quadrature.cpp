// The quadratures of albedo_table.h: the analytic single-scattering albedo of one view (nested adaptive
// Gauss-Kronrod over the visible-normal sampler's unit square) and the Gauss-Legendre mu grid.
#include "scatter/albedo_table.h"

#include "microfacet/bsdf.h"
#include "microfacet/samplers.h"
#include "scatter/analytic_scatter.h"

#include <boost/math/quadrature/gauss.hpp>
#include <boost/math/quadrature/gauss_kronrod.hpp>
#include <boost/math/special_functions/legendre.hpp>
#include <boost/math/tools/minima.hpp>
#include <boost/math/tools/toms748_solve.hpp>
#include <fmt/core.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace microsim {

namespace {

// ---- adaptive Gauss-Kronrod for a few integrands at once ---------------------------------------------------

template <std::size_t K> using Values = std::array<double, K>;

template <std::size_t K> struct Integral {
  Values<K> value{}, error{};
  Values<K> l1{};  // integral of |f| by the Kronrod rule (the scale of rounding noise)
  long long evaluations = 0;
};

template <std::size_t K> void add_to(Values<K>& sum, const Values<K>& v, double weight = 1.0) {
  for (std::size_t i = 0; i < K; ++i) sum[i] += weight * v[i];
}

// The 15-point Kronrod rule with its embedded 7-point Gauss rule on [a, b] (Boost.Math's nodes and
// weights: Kronrod abscissa i even is a Gauss node, with Gauss weight i / 2). error = |Kronrod - Gauss|,
// scaled to [a, b] (Boost 1.74's own adaptive routine compares the unscaled [-1, 1] figure).
template <std::size_t K, class F> Integral<K> kronrod_rule(const F& f, double a, double b) {
  using Kronrod = boost::math::quadrature::gauss_kronrod<double, 15>;
  using Gauss = boost::math::quadrature::gauss<double, 7>;
  const double mid = (a + b) / 2, half = (b - a) / 2;
  Values<K> kronrod{}, gauss{}, l1{};
  Integral<K> r;
  for (std::size_t i = 0; i < Kronrod::abscissa().size(); ++i) {
    const double x = Kronrod::abscissa()[i];
    Values<K> s = f(mid + half * x);
    Values<K> a = s;
    for (double& v : a) v = std::abs(v);
    if (i > 0) {
      const Values<K> other = f(mid - half * x);
      add_to(s, other);
      for (std::size_t k = 0; k < K; ++k) a[k] += std::abs(other[k]);
    }
    r.evaluations += i > 0 ? 2 : 1;
    add_to(kronrod, s, Kronrod::weights()[i]);
    add_to(l1, a, Kronrod::weights()[i]);
    if (i % 2 == 0) add_to(gauss, s, Gauss::weights()[i / 2]);
  }
  for (std::size_t k = 0; k < K; ++k) {
    r.value[k] = half * kronrod[k];
    r.error[k] = half * std::abs(kronrod[k] - gauss[k]);
    r.l1[k] = half * l1[k];
  }
  return r;
}

// Global adaptive integration (as QUADPACK's QAG, Piessens et al. 1983): the interval with the largest
// error estimate (over the first `Checked` components) is bisected until, for each of them, the summed
// estimate is below abs_tol or below kNoiseFloor of the integral of |f| (the integrand's rounding noise,
// which no bisection removes), or `max_intervals` intervals exist. The result's error is the sum of the
// final intervals' estimates, whatever stopped it: a budget that ran out shows as a larger error.
constexpr double kNoiseFloor = 1e-12;
constexpr double kMinInterval = 1e-15;  // narrower intervals are not split

template <std::size_t K> void add_integral(Integral<K>& sum, const Integral<K>& r, double sign = 1.0) {
  add_to(sum.value, r.value, sign);
  add_to(sum.error, r.error, sign);
  add_to(sum.l1, r.l1, sign);
}

template <std::size_t K, std::size_t Checked, class F>
Integral<K> adaptive_kronrod(const F& f, double a, double b, double abs_tol, std::size_t max_intervals) {
  static_assert(Checked <= K);
  struct Span {
    double a, b;
    Integral<K> r;
    double priority() const {
      double p = 0;
      for (std::size_t k = 0; k < Checked; ++k) p = std::max(p, r.error[k]);
      return b - a > kMinInterval ? p : -1.0;
    }
    bool operator<(const Span& o) const { return priority() < o.priority(); }
  };
  std::vector<Span> heap{{a, b, kronrod_rule<K>(f, a, b)}};
  long long evaluations = heap.front().r.evaluations;
  Integral<K> total = heap.front().r;
  const auto converged = [&] {
    for (std::size_t k = 0; k < Checked; ++k)
      if (total.error[k] > std::max(abs_tol, kNoiseFloor * total.l1[k])) return false;
    return true;
  };
  while (!converged() && heap.size() < max_intervals && heap.front().priority() > 0) {
    std::pop_heap(heap.begin(), heap.end());
    const Span worst = heap.back();
    heap.pop_back();
    add_integral(total, worst.r, -1.0);
    const double mid = (worst.a + worst.b) / 2;
    for (const auto& [lo, hi] : {std::pair{worst.a, mid}, std::pair{mid, worst.b}}) {
      heap.push_back({lo, hi, kronrod_rule<K>(f, lo, hi)});
      add_integral(total, heap.back().r);
      evaluations += heap.back().r.evaluations;
      std::push_heap(heap.begin(), heap.end());
    }
  }
  total = {};  // summed afresh: the running sum's cancellations are not part of the result
  for (const Span& span : heap) add_integral(total, span.r);
  total.evaluations = evaluations;
  return total;
}

constexpr std::size_t kMaxInnerIntervals = 256;  // per piece of an inner line
constexpr std::size_t kMaxOuterIntervals = 512;

// ---- the integrand in the visible normals ------------------------------------------------------------------


// f |cos o| dwo / du of the reflection and of the refraction through the visible normal m(u) of wi:
// dwo/dm (Walter et al. 2007, eq. 14 and 17) times dm/du = 1 / D_wi(m). Each lobe counts only on its own
// side (a reflection that dives below the macrosurface, a refraction that comes back, carry nothing).
template <class Ndf>
Values<2> lobe_densities(const Ndf& ndf, const Material& material, int channel, const Vec3<double>& wi,
                         const Vec2<double>& u, RefractionMasking masking) {
  const SampleResult<double> s = sample_visible_normal(ndf, wi, u);
  if (!s || !(s->pdf > 0) || !std::isfinite(s->pdf)) return {0.0, 0.0};
  const Vec3<double>& m = s->direction;
  const double im = wi.dot(m);
  Values<2> d{0.0, 0.0};
  const Vec3<double> wr = reflect(wi, m);
  if (wr.z() * wi.z() > 0) d[0] = single_scattering_flux(ndf, material, channel, wi, wr) * 4 * im / s->pdf;
  if (!material.transmits()) return d;
  const bool inside = wi.z() < 0;
  const double eta_i = inside ? material.eta() : 1.0, eta_o = inside ? 1.0 : material.eta();
  Vec3<double> wt;
  if (!refract(wi, m, eta_o / eta_i, wt) || !(wt.z() * wi.z() < 0)) return d;
  const double om = wt.dot(m);
  const double jacobian = sqr(eta_i * im + eta_o * om) / (sqr(eta_o) * std::abs(om));
  const double flux = masking == RefractionMasking::smith_microsurface
                          ? single_scattering_flux(ndf, material, channel, wi, wt)
                          : dielectric_bsdf(ndf, material.eta(), wi, wt) * std::abs(wt.z());
  if (std::isfinite(jacobian)) d[1] = flux * jacobian / s->pdf;
  return d;
}

void check_view(const Material& material, const Vec3<double>& wi, double tolerance) {
  if (material.kind() == MaterialKind::lambertian)
    throw std::invalid_argument("single-scattering albedo: a Lambertian facet has no closed-form single scattering");
  if (!wi.allFinite() || std::abs(wi.norm() - 1.0) > 1e-9 || wi.z() == 0.0)
    throw std::invalid_argument(
        fmt::format("single-scattering albedo: wi ({}, {}, {}) must be a unit direction off the horizon", wi.x(), wi.y(), wi.z()));
  if (wi.z() < 0 && !material.transmits())
    throw std::invalid_argument(fmt::format("single-scattering albedo: light from inside reaches an opaque {} surface",
                                            material.describe()));
  if (!(tolerance > 0) || !std::isfinite(tolerance))
    throw std::invalid_argument(fmt::format("single-scattering albedo: tolerance {} must be positive", tolerance));
}

// u = S(t) = 3t^2 - 2t^3, du = 6t(1 - t) dt: square-root ends of an interval become smooth.
double smoothstep(double t) { return t * t * (3 - 2 * t); }
double smoothstep_slope(double t) { return 6 * t * (1 - t); }

// Where the integrand is not smooth, as zeros of functions of the visible normal m: a reflection crossing
// the horizon (G2 -> 0 there, a kink), and for a dielectric the facet's critical angle (1 - F has a
// square-root point) and the refraction crossing the horizon (the refracted direction continued through
// total internal reflection with cos_t = 0, so that it stays continuous).
Values<3> break_values(const Material& material, const Vec3<double>& wi, const Vec3<double>& m) {
  const double im = wi.dot(m);
  Values<3> b{(2 * im * m - wi).z() * wi.z(), 1.0, 1.0};
  if (!material.transmits()) return b;
  const bool inside = wi.z() < 0;
  const double eta_rel = inside ? 1 / material.eta() : material.eta();  // n_transmitted / n_incident
  const double cos2_t = 1 - (1 - im * im) / (eta_rel * eta_rel);
  b[1] = cos2_t;
  const double cos_t = std::sqrt(std::max(0.0, cos2_t));
  b[2] = -((-wi / eta_rel + (im / eta_rel - cos_t) * m).z()) * wi.z();
  return b;
}

constexpr int kBreakGrid = 32;  // points of u2 scanned for the roots of each break function

// The root of g in [lo, hi] where it changes sign (values glo, ghi): TOMS 748 (Alefeld, Potra & Shi 1995;
// Boost.Math's toms748_solve) to a bracket of 1e-14.
template <class G> double root_between(const G& g, double lo, double hi, double glo, double ghi) {
  std::uintmax_t iterations = 60;
  const auto small = [](double a, double b) { return b - a <= 1e-14; };
  const auto [a, b] = boost::math::tools::toms748_solve(g, lo, hi, glo, ghi, small, iterations);
  return (a + b) / 2;
}

// The roots of g on [0, 1] from its values on the grid: one between neighbours of opposite signs, and a
// pair wherever |g| has a grid minimum that, refined (Brent's minimiser, Boost.Math brent_find_minima),
// changes sign: a break curve that crosses the line twice between two grid points.
// A line along which g is constant to rounding (at normal incidence every break function is) has no
// break inside it: nothing is added.
template <class G> void add_roots(const G& g, const std::vector<double>& values, std::vector<double>& roots) {
  const double h = 1.0 / (values.size() - 1);
  const auto [lowest, highest] = std::minmax_element(values.begin(), values.end());
  if (!(*highest - *lowest > 1e-12 * std::max(std::abs(*lowest), std::abs(*highest)))) return;
  for (std::size_t i = 1; i < values.size(); ++i)
    if (values[i - 1] * values[i] < 0) roots.push_back(root_between(g, (i - 1) * h, i * h, values[i - 1], values[i]));
  const std::size_t last = values.size() - 1;
  for (std::size_t i = 0; i <= last; ++i) {  // the ends too: a pair of roots between an end and its neighbour
    const double v = values[i];
    const auto closer = [&](std::size_t j) { return v * values[j] > 0 && std::abs(v) < std::abs(values[j]); };
    if (!((i == 0 || closer(i - 1)) && (i == last || closer(i + 1)))) continue;
    const double sign = v > 0 ? 1.0 : -1.0;  // minimise g toward zero from v's side
    const double lo = i == 0 ? 0.0 : (i - 1) * h, hi = i == last ? 1.0 : (i + 1) * h;
    const auto [at, least] = boost::math::tools::brent_find_minima([&](double u) { return sign * g(u); }, lo, hi, 40);
    if (!(least < 0)) continue;
    const double g_at = g(at);
    roots.push_back(root_between(g, lo, at, g(lo), g_at));
    roots.push_back(root_between(g, at, hi, g_at, g(hi)));
  }
}

// Break function k at u = (u1, u2); NaN where the sampler has no normal.
template <class Ndf>
double break_at(const Ndf& ndf, const Material& material, const Vec3<double>& wi, std::size_t k, double u1, double u2) {
  const SampleResult<double> s = sample_visible_normal(ndf, wi, Vec2<double>(u1, u2));
  return s ? break_values(material, wi, s->direction)[k] : std::nan("");
}

std::size_t break_functions(const Material& material) { return material.transmits() ? 3 : 1; }

template <class G> std::vector<double> grid_values(const G& g, int n) {
  std::vector<double> values(std::size_t(n) + 1);
  for (int i = 0; i <= n; ++i) values[std::size_t(i)] = g(double(i) / n);
  return values;
}

// The cuts of the line u1 = const in u2: 0, the roots of the break functions, 1.
template <class Ndf>
std::vector<double> line_cuts(const Ndf& ndf, const Material& material, const Vec3<double>& wi, double u1) {
  std::vector<double> cuts{0.0, 1.0};
  for (std::size_t k = 0; k < break_functions(material); ++k) {
    const auto g = [&](double u2) { return break_at(ndf, material, wi, k, u1, u2); };
    add_roots(g, grid_values(g, kBreakGrid), cuts);
  }
  std::sort(cuts.begin(), cuts.end());
  return cuts;
}

// The least value of g on [0, 1]: the grid's least, refined by Brent's minimiser around it.
template <class G> double line_minimum(const G& g) {
  const std::vector<double> values = grid_values(g, kBreakGrid);
  std::size_t best = 0;
  for (std::size_t i = 1; i < values.size(); ++i)
    if (values[i] < values[best] || std::isnan(values[best])) best = i;
  const double h = 1.0 / kBreakGrid;
  const double lo = std::max(0.0, (double(best) - 1) * h), hi = std::min(1.0, (double(best) + 1) * h);
  const auto [at, least] = boost::math::tools::brent_find_minima(g, lo, hi, 40);
  return std::fmin(values[best], least);
}

constexpr int kOuterBreakGrid = 64;  // points of u1 scanned for the outer integrand's kinks

// The cuts in u1: 0, 1 and where a break curve touches a line u1 = const (its least or greatest value along
// the line crosses zero: the outer integrand, the inner integral, has a kink there).
template <class Ndf> std::vector<double> outer_cuts(const Ndf& ndf, const Material& material, const Vec3<double>& wi) {
  std::vector<double> cuts{0.0, 1.0};
  for (std::size_t k = 0; k < break_functions(material); ++k)
    for (const double sign : {1.0, -1.0}) {
      const auto extreme = [&](double u1) {
        return line_minimum([&](double u2) { return sign * break_at(ndf, material, wi, k, u1, u2); });
      };
      add_roots(extreme, grid_values(extreme, kOuterBreakGrid), cuts);
    }
  std::sort(cuts.begin(), cuts.end());
  return cuts;
}

// The integral of f over [0, 1] piece by piece between the cuts, each through the smoothstep (its ends may
// be kinks or square-root points), each piece's error target its share of abs_tol.
template <std::size_t K, std::size_t Checked, class F>
Integral<K> piecewise_integral(const F& f, const std::vector<double>& cuts, double abs_tol, std::size_t max_intervals) {
  Integral<K> sum;
  for (std::size_t p = 0; p + 1 < cuts.size(); ++p) {
    const double a = cuts[p], width = cuts[p + 1] - cuts[p];
    if (!(width > 0)) continue;
    const auto piece = [&](double t) {
      Values<K> v = f(a + width * smoothstep(t));
      for (double& x : v) x *= width * smoothstep_slope(t);
      return v;
    };
    const Integral<K> in = adaptive_kronrod<K, Checked>(piece, 0.0, 1.0, abs_tol * width, max_intervals);
    add_integral(sum, in);
    sum.evaluations += in.evaluations;
  }
  return sum;
}

// Two densities over the visible normals' unit square (density(u) -> Values<2>, with the kinks of
// `material`'s lobes), integrated: the outer integral over u1 of [inner 0, inner 1, inner 0 error, inner 1
// error]; the last two integrate the inner error estimates, so that each total error is the outer estimate
// plus their integral. Returns {value, error} per density and adds the inner evaluations to `evaluations`.
template <class Ndf, class Density>
std::array<Estimate, 2> visible_normal_integrals(const Ndf& ndf, const Material& material, const Vec3<double>& wi,
                                                 double tolerance, const Density& density, long long& evaluations) {
  const auto outer = [&](double u1) -> Values<4> {
    const auto inner = [&](double u2) { return density(Vec2<double>(u1, u2)); };
    const Integral<2> in =
        piecewise_integral<2, 2>(inner, line_cuts(ndf, material, wi, u1), tolerance / 2, kMaxInnerIntervals);
    evaluations += in.evaluations;
    return {in.value[0], in.value[1], in.error[0], in.error[1]};
  };
  const Integral<4> out = piecewise_integral<4, 2>(outer, outer_cuts(ndf, material, wi), tolerance / 2, kMaxOuterIntervals);
  return {Estimate{out.value[0], out.error[0] + std::abs(out.value[2]) + out.error[2]},
          Estimate{out.value[1], out.error[1] + std::abs(out.value[3]) + out.error[3]}};
}

template <class Ndf>
SingleScatteringAlbedo albedo_of(const Ndf& ndf, const Material& material, int channel, const Vec3<double>& wi,
                                 double tolerance, RefractionMasking masking) {
  check_view(material, wi, tolerance);
  SingleScatteringAlbedo a;
  const auto density = [&](const Vec2<double>& u) { return lobe_densities(ndf, material, channel, wi, u, masking); };
  const std::array<Estimate, 2> r = visible_normal_integrals(ndf, material, wi, tolerance, density, a.evaluations);
  a.reflected = r[0];
  a.transmitted = r[1];
  return a;
}

}  // namespace

Estimate SingleScatteringAlbedo::total() const {
  return {reflected.value + transmitted.value, reflected.standard_error + transmitted.standard_error};
}

SingleScatteringAlbedo single_scattering_albedo(const GGX<double>& ggx, const Material& material, int channel,
                                                const Vec3<double>& wi, double tolerance, RefractionMasking masking) {
  return albedo_of(ggx, material, channel, wi, tolerance, masking);
}
SingleScatteringAlbedo single_scattering_albedo(const Beckmann<double>& beckmann, const Material& material,
                                                int channel, const Vec3<double>& wi, double tolerance,
                                                RefractionMasking masking) {
  return albedo_of(beckmann, material, channel, wi, tolerance, masking);
}

SchlickSplitAlbedo schlick_split_albedo(const GGX<double>& ggx, const Vec3<double>& wi, double tolerance) {
  const Material mirror = Material::mirror();
  check_view(mirror, wi, tolerance);
  // The mirror's reflection density through the visible normal m(u), and the same weighted by the
  // grazing term of Schlick's Fresnel (1 - wi . m)^5 (wi . m = wo . m for a reflection).
  const auto density = [&](const Vec2<double>& u) -> Values<2> {
    const double d = lobe_densities(ggx, mirror, 0, wi, u, RefractionMasking::smith_microsurface)[0];
    if (d == 0) return {0.0, 0.0};
    const SampleResult<double> s = sample_visible_normal(ggx, wi, u);
    const double c = 1 - std::clamp(wi.dot(s->direction), 0.0, 1.0);
    return {d, d * sqr(sqr(c)) * c};
  };
  SchlickSplitAlbedo a;
  const std::array<Estimate, 2> r = visible_normal_integrals(ggx, mirror, wi, tolerance, density, a.evaluations);
  a.unit = r[0];
  a.grazing = r[1];
  return a;
}

// ---- an isotropic Beckmann mirror in its view's visible slopes ---------------------------------------------

namespace {

// The Gaussian tails beyond a standard slope L are left out, L the first of 3, 3.5, ..., 9 where the weight
// left out (BeckmannMirrorSlopes::tail_weight) is below a tenth of the tolerance; it is added to the error.
constexpr double kMaxSlopeTail = 9.0;

// The view of beckmann_mirror_split in its visible slopes (albedo_table.h): the outer weight
// w(x) = (a - x) exp(-x^2) / N, the half-width Y(x) of the reflecting disk at x, and the two integrands
// G2 / G1(wi) and G2 / G1(wi) (1 - wi.m)^5.
struct BeckmannMirrorSlopes {
  Beckmann<double> ndf;
  Vec3<double> wi;
  double alpha = 0, tan_i = 0, sec_i = 0;
  double inv_a = 0;      // 1 / a = alpha tan(theta_i): 0 at normal incidence (a = inf)
  double scale = 0;      // N / a = exp(-a^2) / (2 a) + sqrt(pi) erfc(-a) / 2
  double lambda_i1 = 0;  // 1 + Lambda(wi)

  double tail = kMaxSlopeTail;  // L: |x|, y beyond are left out

  BeckmannMirrorSlopes(double alpha_in, double mu) : ndf(alpha_in), wi(albedo_view(mu, false)) {
    alpha = ndf.alpha_x();
    tan_i = wi.x() / wi.z();
    sec_i = 1 / wi.z();
    inv_a = alpha * tan_i;
    const double a = inv_a > 0 ? 1 / inv_a : std::numeric_limits<double>::infinity();
    scale = (std::isfinite(a) ? std::exp(-a * a) * inv_a / 2 : 0.0) + std::sqrt(std::numbers::pi) / 2 * std::erfc(-a);
    lambda_i1 = 1 + ndf.masked_area(wi) / wi.z();
  }
  double weight(double x) const { return (1 - x * inv_a) * std::exp(-x * x) / scale; }
  // An upper bound on the weight beyond L (both integrands are at most 1): the outer tails, int_{x<-L} w <=
  // (exp(-L^2) / (2 a) + sqrt(pi) erfc(L) / 2) / (N / a) and int_{x>L} w <= that, plus the inner tail,
  // 2 int_L^inf exp(-y^2) / sqrt(pi) dy = erfc(L).
  double tail_weight(double l) const {
    const double e = std::erfc(l);
    return 2 * (std::exp(-l * l) * inv_a / 2 + std::sqrt(std::numbers::pi) / 2 * e) / scale + e;
  }
  // Y(x) from (alpha x + tan)^2 + (alpha y)^2 < sec^2, the difference of squares factored (no cancellation at
  // the disk's ends).
  double half_width(double x) const {
    const double c = alpha * x + tan_i;
    return std::sqrt(std::max(0.0, (sec_i - c) * (sec_i + c))) / alpha;
  }
  double x_low() const { return std::max(-tail, (-tan_i - sec_i) / alpha); }
  double x_high() const { return std::min(tail, (sec_i - tan_i) / alpha); }
  // G2 / G1(wi) = (1 + Lambda_i) / (1 + Lambda_i + Lambda_o) (Heitz 2014 eq. 99), as
  // (1 + Lambda_i) wo.z / ((1 + Lambda_i) wo.z + |wo.z| Lambda_o): 0 on the horizon; and the same times
  // Schlick's grazing term (1 - wi.m)^5.
  Values<2> integrands(double x, double y) const {
    const Vec3<double> m = Vec3<double>(-alpha * x, -alpha * y, 1.0).normalized();
    const double im = wi.dot(m);
    const Vec3<double> wo = 2 * im * m - wi;
    if (!(wo.z() > 0)) return {0.0, 0.0};
    const double seen = lambda_i1 * wo.z();
    const double h = seen / (seen + ndf.masked_area(wo));
    const double c = 1 - std::clamp(im, 0.0, 1.0);
    return {h, h * sqr(sqr(c)) * c};
  }
};

}  // namespace

SchlickSplitAlbedo beckmann_mirror_split(double alpha, double mu, double tolerance) {
  if (!std::isfinite(alpha) || !(mu > 0 && mu <= 1))
    throw std::invalid_argument(
        fmt::format("Beckmann mirror albedo: alpha {} must be finite and mu {} in (0, 1]", alpha, mu));
  check_view(Material::mirror(), albedo_view(mu, false), tolerance);
  BeckmannMirrorSlopes s(alpha, mu);
  for (double l = 3; l < kMaxSlopeTail; l += 0.5)
    if (s.tail_weight(l) < tolerance / 10) {
      s.tail = l;
      break;
    }
  const double left_out = s.tail_weight(s.tail);
  const double x0 = s.x_low(), dx = s.x_high() - x0;
  SchlickSplitAlbedo r;
  if (!(dx > 0)) {
    r.unit.standard_error = r.grazing.standard_error = left_out;
    return r;
  }
  const std::vector<double> whole{0.0, 1.0};
  // Outer, over x = x0 + dx v: the two inner integrals 2 int_0^Y exp(-y^2) / sqrt(pi) (...) dy, over y = Y t,
  // times w(x), and their error estimates.
  const auto outer = [&](double v) -> Values<4> {
    const double x = x0 + dx * v, width = std::min(s.half_width(x), s.tail);
    if (!(width > 0)) return {0.0, 0.0, 0.0, 0.0};
    const double gauss = 2 * width / std::sqrt(std::numbers::pi);
    const auto inner = [&](double t) -> Values<2> {
      const double y = width * t, g = gauss * std::exp(-y * y);
      const Values<2> h = s.integrands(x, y);
      return {g * h[0], g * h[1]};
    };
    const Integral<2> in = piecewise_integral<2, 2>(inner, whole, tolerance / 2, kMaxInnerIntervals);
    r.evaluations += in.evaluations;
    const double w = dx * s.weight(x);
    return {w * in.value[0], w * in.value[1], w * in.error[0], w * in.error[1]};
  };
  const Integral<4> out = piecewise_integral<4, 2>(outer, whole, tolerance / 2, kMaxOuterIntervals);
  r.unit = {out.value[0], out.error[0] + std::abs(out.value[2]) + out.error[2] + left_out};
  r.grazing = {out.value[1], out.error[1] + std::abs(out.value[3]) + out.error[3] + left_out};
  return r;
}

MuGrid gauss_legendre_mus(int n) {
  if (n < 1) throw std::invalid_argument(fmt::format("Gauss-Legendre grid: {} nodes (at least 1)", n));
  MuGrid g;
  for (const double x : boost::math::legendre_p_zeros<double>(n)) {
    const double w = 2 / ((1 - x * x) * sqr(boost::math::legendre_p_prime(n, x)));
    g.mus.push_back((1 + x) / 2);
    g.weights.push_back(w / 2);
    if (x > 0) {
      g.mus.push_back((1 - x) / 2);
      g.weights.push_back(w / 2);
    }
  }
  std::vector<std::size_t> order(g.mus.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return g.mus[a] < g.mus[b]; });
  MuGrid sorted;
  for (const std::size_t i : order) {
    sorted.mus.push_back(g.mus[i]);
    sorted.weights.push_back(g.weights[i]);
  }
  return sorted;
}

}  // namespace microsim
