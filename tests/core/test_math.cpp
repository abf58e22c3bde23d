// Tests of the z-up frame helpers (src/core/math.h): trig at the poles and the horizon, spherical
// round trips, the orthonormal basis (including the n.z -> -1 branch), reflect, and the guards.
#include "core/math.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_math {

using namespace microsim;

namespace {

template <class T> bool all_finite(const Vec3<T>& v) { return v.allFinite(); }

template <class T> std::vector<Vec3<T>> test_directions() {
  std::vector<Vec3<T>> dirs = {
      {0, 0, 1},  {0, 0, -1}, {1, 0, T(-0.0)}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0},
      // near the poles, where sin theta is tiny (x, y keep precision, 1 - z^2 would not)
      Vec3<T>(T(1e-7), T(-2e-7), 1).normalized(), Vec3<T>(T(1e-7), T(2e-7), -1).normalized(),
      Vec3<T>(T(1e-20), 0, 1).normalized(), Vec3<T>(0, T(-1e-20), -1).normalized(),
  };
  std::mt19937_64 rng(11);
  std::normal_distribution<double> g;
  for (int i = 0; i < 2000; ++i) {
    Vec3<double> w(g(rng), g(rng), g(rng));
    if (i % 4 == 0) w.z() = (w.z() > 0 ? 1 : -1) * 1e4 * std::abs(w.z());  // close to a pole
    if (i % 4 == 1) w.z() *= 1e-4;                                           // close to the horizon
    dirs.push_back(w.normalized().cast<T>());
  }
  return dirs;
}

}  // namespace

template <class T> class MathTyped : public ::testing::Test {};
using FloatTypes = ::testing::Types<float, double>;
TYPED_TEST_SUITE(MathTyped, FloatTypes);

TYPED_TEST(MathTyped, TrigAtThePolesIsDefined) {
  using T = TypeParam;
  for (const Vec3<T>& w : {Vec3<T>(0, 0, 1), Vec3<T>(0, 0, -1), Vec3<T>(T(-0.0), T(-0.0), 1)}) {
    EXPECT_EQ(sin2_theta(w), T(0));
    EXPECT_EQ(sin_theta(w), T(0));
    EXPECT_EQ(tan2_theta(w), T(0));
    EXPECT_EQ(cos2_theta(w), T(1));
    EXPECT_EQ(std::abs(cos_theta(w)), T(1));
    EXPECT_EQ(cos_phi(w), T(1));  // phi of the pole is defined as 0
    EXPECT_EQ(sin_phi(w), T(0));
  }
  // sin^2 so small that it underflows: still phi = 0, not NaN.
  const Vec3<T> tiny(std::numeric_limits<T>::min(), std::numeric_limits<T>::min(), 1);
  EXPECT_FALSE(std::isnan(cos_phi(tiny)));
  EXPECT_FALSE(std::isnan(sin_phi(tiny)));
  EXPECT_NEAR(sqr(cos_phi(tiny)) + sqr(sin_phi(tiny)), T(1), T(4) * std::numeric_limits<T>::epsilon());
  // The horizon: tan^2 is +inf, phi is well defined.
  const Vec3<T> h(T(0.6), T(-0.8), 0);
  EXPECT_EQ(tan2_theta(h), std::numeric_limits<T>::infinity());
  EXPECT_NEAR(cos_phi(h), T(0.6), T(2) * std::numeric_limits<T>::epsilon());
  EXPECT_NEAR(sin_phi(h), T(-0.8), T(2) * std::numeric_limits<T>::epsilon());
}

TYPED_TEST(MathTyped, TrigHelpersAreFiniteAndConsistent) {
  using T = TypeParam;
  const T eps = std::numeric_limits<T>::epsilon();
  for (const Vec3<T>& w : test_directions<T>()) {
    const T c = cos_phi(w), s = sin_phi(w);
    ASSERT_TRUE(std::isfinite(c) && std::isfinite(s)) << w.transpose();
    EXPECT_NEAR(c * c + s * s, T(1), 8 * eps) << w.transpose();
    EXPECT_LE(std::abs(c), T(1));
    EXPECT_LE(std::abs(s), T(1));
    // Reconstruct w from (sin theta, cos theta, phi).
    const T st = sin_theta(w);
    const Vec3<T> back(st * c, st * s, cos_theta(w));
    EXPECT_LE((back - w).norm(), 8 * eps) << w.transpose();
    EXPECT_NEAR(sin2_theta(w) + cos2_theta(w), T(1), 8 * eps);
    if (w.z() != T(0)) {
      EXPECT_NEAR(tan2_theta(w), sin2_theta(w) / cos2_theta(w),
                  8 * eps * std::max(T(1), tan2_theta(w)));
    }
  }
}

TYPED_TEST(MathTyped, SphericalDirectionRoundTrips) {
  using T = TypeParam;
  const T eps = std::numeric_limits<T>::epsilon();
  for (double theta_deg : {0.0, 1e-3, 0.5, 10.0, 30.0, 45.0, 60.0, 80.0, 89.0, 89.999, 90.0, 120.0, 179.0, 180.0}) {
    for (double phi_deg : {0.0, 17.0, 90.0, 135.0, 180.0, 251.0, 359.0}) {
      const Vec3<T> w = direction_from_degrees(T(theta_deg), T(phi_deg));
      EXPECT_NEAR(w.norm(), T(1), 4 * eps);
      const T theta = T(theta_deg) * kPi<T> / 180, phi = T(phi_deg) * kPi<T> / 180;
      const Vec3<T> w2 = spherical_direction(theta, phi);
      EXPECT_LE((w - w2).norm(), 8 * eps);
      // theta back from the components; atan2 keeps precision at both poles.
      const T theta_back = std::atan2(sin_theta(w), cos_theta(w));
      EXPECT_NEAR(theta_back, theta, 8 * eps) << theta_deg << " " << phi_deg;
      // phi back where it is defined (not at the poles).
      if (sin_theta(w) > T(1e-3)) {
        const T dphi = std::remainder(std::atan2(sin_phi(w), cos_phi(w)) - phi, 2 * kPi<T>);
        EXPECT_NEAR(dphi, T(0), 16 * eps / sin_theta(w)) << theta_deg << " " << phi_deg;
      }
    }
  }
}

TYPED_TEST(MathTyped, OrthonormalBasisIsOrthonormalAndRightHanded) {
  using T = TypeParam;
  const T tol = 8 * std::numeric_limits<T>::epsilon();
  std::vector<Vec3<T>> normals = test_directions<T>();
  // The branch of Duff et al. 2017 flips at n.z = 0 (sign of z): probe both sides and the pole n = -z
  // where the original Frisvad 2012 construction broke down.
  for (double e : {0.0, 1e-30, 1e-12, 1e-8, 1e-6, 1e-4, 1e-2}) {
    normals.push_back(Vec3<double>(e, 0, -1).normalized().cast<T>());
    normals.push_back(Vec3<double>(-e, e, -1).normalized().cast<T>());
    normals.push_back(Vec3<double>(e, -e, 1).normalized().cast<T>());
    normals.push_back(Vec3<double>(1, e, 1e-7).normalized().cast<T>());
    normals.push_back(Vec3<double>(1, e, -1e-7).normalized().cast<T>());
  }
  for (const Vec3<T>& n : normals) {
    Vec3<T> b1, b2;
    orthonormal_basis(n, b1, b2);
    ASSERT_TRUE(all_finite(b1) && all_finite(b2)) << n.transpose();
    EXPECT_NEAR(b1.norm(), T(1), tol) << n.transpose();
    EXPECT_NEAR(b2.norm(), T(1), tol) << n.transpose();
    EXPECT_NEAR(b1.dot(b2), T(0), tol) << n.transpose();
    EXPECT_NEAR(b1.dot(n), T(0), tol) << n.transpose();
    EXPECT_NEAR(b2.dot(n), T(0), tol) << n.transpose();
    EXPECT_LE((b1.cross(b2) - n).norm(), 2 * tol) << n.transpose();  // (b1, b2, n) right-handed
  }
  Vec3<T> b1, b2;
  orthonormal_basis(Vec3<T>(0, 0, 1), b1, b2);
  EXPECT_EQ(b1, Vec3<T>(1, 0, 0));
  EXPECT_EQ(b2, Vec3<T>(0, 1, 0));
}

TYPED_TEST(MathTyped, ReflectMirrorsAboutTheNormal) {
  using T = TypeParam;
  const T tol = 16 * std::numeric_limits<T>::epsilon();
  const auto dirs = test_directions<T>();
  for (std::size_t i = 0; i + 1 < dirs.size(); i += 2) {
    const Vec3<T>& w = dirs[i];
    const Vec3<T>& n = dirs[i + 1];
    const Vec3<T> r = reflect(w, n);
    EXPECT_NEAR(r.norm(), T(1), tol);
    EXPECT_NEAR(r.dot(n), w.dot(n), tol);                          // same angle with n
    EXPECT_LE((r + w - 2 * w.dot(n) * n).norm(), tol);             // r + w along n
    EXPECT_LE(std::abs((r - w).dot(n.cross(w))), tol);             // in the plane of w and n
    EXPECT_LE((reflect(r, n) - w).norm(), 2 * tol);                // an involution
  }
  EXPECT_EQ(reflect(Vec3<T>(T(0.6), 0, T(0.8)), Vec3<T>(0, 0, 1)), Vec3<T>(T(-0.6), 0, T(0.8)));
}

TYPED_TEST(MathTyped, GuardsNeverReturnNaN) {
  using T = TypeParam;
  const T inf = std::numeric_limits<T>::infinity();
  const T nan = std::numeric_limits<T>::quiet_NaN();
  EXPECT_EQ(safe_sqrt(T(-1e-30)), T(0));
  EXPECT_EQ(safe_sqrt(T(4)), T(2));
  EXPECT_EQ(safe_acos(T(1) + 4 * std::numeric_limits<T>::epsilon()), T(0));
  EXPECT_EQ(safe_acos(T(-1) - 4 * std::numeric_limits<T>::epsilon()), kPi<T>);
  EXPECT_EQ(safe_asin(T(1.5)), kPi<T> / 2);
  EXPECT_LT(clamp_unit(T(1)), T(1));
  EXPECT_LT(clamp_unit(T(1) - T(std::ldexp(1.0, -53))), T(1));  // 1 - 2^-53 rounds to 1 in float
  EXPECT_EQ(clamp_unit(T(-0.25)), T(0));
  EXPECT_EQ(clamp_unit(T(0.5)), T(0.5));
  EXPECT_EQ(normalized_or_zero(Vec3<T>(0, 0, 0)), Vec3<T>::Zero());
  EXPECT_EQ(normalized_or_zero(Vec3<T>(inf, 0, 0)), Vec3<T>::Zero());
  EXPECT_EQ(normalized_or_zero(Vec3<T>(nan, 0, 1)), Vec3<T>::Zero());
  EXPECT_NEAR((normalized_or_zero(Vec3<T>(3, 0, 4)) - Vec3<T>(T(0.6), 0, T(0.8))).norm(), T(0),
              2 * std::numeric_limits<T>::epsilon());
}

}  // namespace test_math
