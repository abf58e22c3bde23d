// The two root solvers of heitz2014's inverse CDF (samplers_impl.h): d - sin d cos d = q and
// b + sin b cos b = c on [0, pi/4], over their whole range as the sampler reaches it (q = pi min(u, 1 - u)
// for u down to one ulp of 1/2, 2^-53 in double, 2^-24 in float), against a long double reference found
// by 200 bisection steps. The hand-written Halley iteration they replaced stopped early on a predicted
// error: in double it was 1.4e3 ulps off at q = 5.2e-15 (d = 1.98e-5) and 96 ulps off at q = 2.9e-12;
// Boost.Math's halley_iterate stays within 2 ulps everywhere (measured: 1.57 and 1.21 ulps in double, 1.36
// and 1.46 in float). Boundary values return the bracket's ends; at q = DBL_MIN the old iteration gave
// 7.1e-13 for the root 3.2e-103.
#include "microfacet/samplers_impl.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_root_solvers {

using namespace microsim;

namespace {

// d - sin d cos d (dmode) or b + sin b cos b, increasing on [0, pi/4]: its root for the right side y.
long double bisect(long double y, bool dmode) {
  long double lo = 0, hi = kPi<long double> / 4;
  for (int i = 0; i < 200; ++i) {
    const long double m = (lo + hi) / 2, s = std::sin(m), c = std::cos(m);
    const long double g = dmode ? microsim::detail::d_minus_sin_cos(m, s, c) : m + s * c;
    (g > y ? hi : lo) = m;
  }
  return (lo + hi) / 2;
}

// Worst relative error, in units of T's epsilon, of both solvers for u log-spaced in [u_min, 1/2] and
// linear in [0, 1/2].
template <class T> std::pair<double, double> worst_errors(double u_min) {
  double worst_d = 0, worst_b = 0;
  const T top_d = T(kPi<long double> / 4 - 0.5L), top_b = T(kPi<long double> / 4 + 0.5L);
  for (int i = 0; i <= 4000; ++i) {
    const double u = i < 2000 ? u_min * std::pow(0.5 / u_min, i / 2000.0) : 0.5 * (i - 2000) / 2000.0;
    const T y = T(kPi<double> * u);
    if (!(y > 0)) continue;
    constexpr double eps = std::numeric_limits<T>::epsilon();
    if (y < top_d) {
      const long double ref = bisect(y, true);
      worst_d = std::max(worst_d, double(std::abs(microsim::detail::solve_d_minus_sin_cos(y) - ref) / ref) / eps);
    }
    if (y < top_b) {
      const long double ref = bisect(y, false);
      worst_b = std::max(worst_b, double(std::abs(microsim::detail::solve_b_plus_sin_cos(y) - ref) / ref) / eps);
    }
  }
  return {worst_d, worst_b};
}

}  // namespace

TEST(HeitzDEon2014Roots, WithinTwoUlpsOverTheSamplersRange) {
  const auto [d_double, b_double] = worst_errors<double>(0x1p-53);
  const auto [d_float, b_float] = worst_errors<float>(0x1p-24);
  RecordProperty("d_double_ulps", std::to_string(d_double));
  RecordProperty("b_double_ulps", std::to_string(b_double));
  RecordProperty("d_float_ulps", std::to_string(d_float));
  RecordProperty("b_float_ulps", std::to_string(b_float));
  EXPECT_LE(d_double, 2.0);
  EXPECT_LE(b_double, 2.0);
  EXPECT_LE(d_float, 2.0);
  EXPECT_LE(b_float, 2.0);
}

template <class T> void check_boundaries() {
  const T quarter = kPi<T> / T(4);
  EXPECT_EQ(microsim::detail::solve_d_minus_sin_cos(T(0)), T(0));
  EXPECT_EQ(microsim::detail::solve_b_plus_sin_cos(T(0)), T(0));
  EXPECT_EQ(microsim::detail::solve_d_minus_sin_cos(std::numeric_limits<T>::quiet_NaN()), T(0));
  // The top of the range and just above it (rounding of pi min(u, 1 - u) at the branch point).
  for (T y : {std::nextafter(quarter - T(0.5), T(0)), quarter - T(0.5), std::nextafter(quarter - T(0.5), T(1)), T(1)})
    EXPECT_NEAR(double(microsim::detail::solve_d_minus_sin_cos(y)), double(quarter), 1e-3) << y;
  for (T y : {std::nextafter(quarter + T(0.5), T(0)), quarter + T(0.5), std::nextafter(quarter + T(0.5), T(2)), T(2)})
    EXPECT_NEAR(double(microsim::detail::solve_b_plus_sin_cos(y)), double(quarter), 1e-3) << y;
  // The smallest positive inputs.
  const T tiny = std::numeric_limits<T>::min();
  EXPECT_NEAR(double(microsim::detail::solve_d_minus_sin_cos(tiny)), double(std::cbrt(1.5L * tiny)), 1e-6 * double(std::cbrt(1.5L * tiny)));
  EXPECT_NEAR(double(microsim::detail::solve_b_plus_sin_cos(tiny)), double(tiny) / 2, 1e-6 * double(tiny));
}

TEST(HeitzDEon2014Roots, BoundaryValues) {
  check_boundaries<float>();
  check_boundaries<double>();
  check_boundaries<long double>();
}

}  // namespace test_root_solvers
