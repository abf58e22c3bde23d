// The binning kernel (stats/direction_binner.h): bin_floats' vector pass 1 (Highway, every target this
// CPU runs) against the scalar reference loop and against DirectionBinning::bin_of, on random directions
// and on directions placed in and around the guard bands of every row and column edge, the poles, the rim
// of a lobe's parameter space and degenerate inputs (zero, denormal, huge, infinite, NaN).
#include "stats/direction_binner.h"

#include "trace/embree.h"  // FlushDenormalsScope: the tracer bins with FTZ/DAZ set

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace microsim {
namespace {

struct Directions {
  std::vector<float> x, y, z;
  void add(const Vec3<double>& d) {
    x.push_back(float(d.x()));
    y.push_back(float(d.y()));
    z.push_back(float(d.z()));
  }
  int size() const { return int(x.size()); }
  Vec3<double> at(int i) const { return Vec3<double>(x[std::size_t(i)], y[std::size_t(i)], z[std::size_t(i)]); }
};

// The binnings of the test: sphere bins of several sizes, isotropic, anisotropic, narrow and wide lobes
// seen from several views.
std::vector<DirectionBinning> test_binnings() {
  std::vector<DirectionBinning> b;
  for (const int rows : {5, 15, 31, 101, 501}) b.push_back(DirectionBinning::sphere(rows));
  const struct {
    double ax, ay, theta, phi;
    int rows;
  } lobes[] = {{0.5, 0.5, 45, 30, 31}, {0.01, 0.01, 60, 20, 31}, {0.1, 0.8, 60, 20, 15}, {1.5, 1.5, 80, 200, 101},
               {0.3, 0.05, 89, -40, 31}, {0.2, 0.2, 0, 0, 7}};
  for (const auto& l : lobes) {
    b.push_back(DirectionBinning::lobe(GGX<double>(l.ax, l.ay), direction_from_degrees(l.theta, l.phi),
                                       SampleDomain::microfacet_normal, l.rows));
  }
  return b;
}

// Random directions: a uniform cube (any length), unit vectors, and unit vectors of the upper half.
void add_random(Directions& d, std::mt19937_64& rng, int count) {
  std::uniform_real_distribution<double> cube(-1.0, 1.0);
  std::normal_distribution<double> normal;
  for (int i = 0; i < count; ++i) d.add(Vec3<double>(cube(rng), cube(rng), cube(rng)));
  for (int i = 0; i < count; ++i) d.add(Vec3<double>(normal(rng), normal(rng), normal(rng)).normalized());
  for (int i = 0; i < count; ++i) {
    const Vec3<double> v = Vec3<double>(normal(rng), normal(rng), normal(rng)).normalized();
    d.add(Vec3<double>(v.x(), v.y(), std::abs(v.z())));
  }
}

// Offsets, in bin widths, from an edge: on it, within float round-off, in the guard band (1e-5 x rows or
// cols bin widths wide), at its border and just beyond.
constexpr double kEdgeOffsets[] = {0.0, 1e-9, -1e-9, 1e-7, -1e-7, 1e-6, -1e-6, 3e-6, -3e-6, 1e-5, -1e-5,
                                   3e-5, -3e-5, 1e-4, -1e-4, 1e-3, -1e-3, 0.5};

// Directions at and around every row edge and every column edge of the binning (in its parameter space,
// mapped back), at a few azimuths and heights.
void add_edges(Directions& d, const DirectionBinning& b) {
  const double dz = (b.z_max() - b.z_min()) / b.rows(), dphi = 2 * kPi<double> / b.cols();
  const auto add_param = [&](double z, double phi) {
    const double zz = std::clamp(z, -1.0, 1.0), s = std::sqrt(1 - zz * zz);
    d.add(b.from_param(Vec3<double>(s * std::cos(phi), s * std::sin(phi), zz)));
  };
  for (int k = 0; k <= b.rows(); ++k)
    for (const double offset : kEdgeOffsets)
      for (const double phi : {0.0, 0.3, 2.0, 4.0, 5.9}) add_param(b.z_max() - (k + offset) * dz, phi);
  for (int j = 0; j < b.cols(); ++j)
    for (const double offset : kEdgeOffsets)
      for (const double height : {0.02, 0.3, 0.7, 0.97}) add_param(b.z_max() - height * (b.z_max() - b.z_min()), (j + offset) * dphi);
}

// Degenerate and extreme inputs: axes, poles, signed zeros, denormals, tiny, huge, infinite, NaN.
void add_special(Directions& d) {
  const float inf = INFINITY, nan = std::nanf(""), tiny = 1e-40f, huge = 3e38f;
  const float values[] = {0.0f, -0.0f, 1.0f, -1.0f, 0.5f, tiny, -tiny, 1e-20f, 1e-16f, huge, -huge, inf, -inf, nan};
  for (const float a : values)
    for (const float b : values)
      for (const float c : values) {
        d.x.push_back(a);
        d.y.push_back(b);
        d.z.push_back(c);
      }
}

// The whole set for one binning; its size is not a multiple of any vector width (a scalar tail remains).
Directions directions_for(const DirectionBinning& b, std::uint64_t seed) {
  Directions d;
  std::mt19937_64 rng(seed);
  add_random(d, rng, 30'000);
  add_edges(d, b);
  add_special(d);
  if (d.size() % 64 == 0) d.add(Vec3<double>(0.1, 0.2, 0.3));
  d.add(Vec3<double>(0.1, -0.2, 0.3));
  return d;
}

std::vector<int> expected_bins(const DirectionBinning& b, const Directions& d) {
  std::vector<int> e(std::size_t(d.size()));
  for (int i = 0; i < d.size(); ++i) e[std::size_t(i)] = b.bin_of(d.at(i)).value_or(-1);
  return e;
}

// Restores the best target whatever a test does.
struct TargetScope {
  explicit TargetScope(const std::string& name) { use_direction_binner_target(name); }
  ~TargetScope() { use_direction_binner_target(""); }
};

// Pass 1's fractional row and column indices of a direction, in double (what the float code approximates).
struct Fractions {
  double row, col;
};
std::optional<Fractions> exact_fractions(const DirectionBinning& b, const Vec3<double>& w) {
  if (!w.allFinite() || !(w.squaredNorm() > 1e-30)) return std::nullopt;
  const std::optional<Vec3<double>> param = b.to_param(w);
  if (!param) return std::nullopt;
  const Vec3<double>& u = *param;
  double phi = std::atan2(u.y(), u.x());
  if (phi < 0) phi += 2 * kPi<double>;
  return Fractions{(b.z_max() - u.z()) / (b.z_max() - b.z_min()) * b.rows(), phi / (2 * kPi<double>) * b.cols()};
}

}  // namespace

TEST(DirectionBinner, EveryTargetIsListedAndCanBeChosen) {
  const std::vector<std::string> targets = direction_binner_targets();
  ASSERT_FALSE(targets.empty());
  std::string names;
  for (const std::string& t : targets) names += (names.empty() ? "" : " ") + t;
  RecordProperty("targets", names);
  std::cout << "SIMD targets of this CPU (best first): " << names << "\n";
  EXPECT_EQ(direction_binner_target(), targets.front());  // the best by default
  for (const std::string& t : targets) {
    TargetScope scope(t);
    EXPECT_EQ(direction_binner_target(), t);
    EXPECT_EQ(direction_binner_targets(), targets);  // the list is the CPU's, not the forced one
  }
  EXPECT_EQ(direction_binner_target(), targets.front());
  EXPECT_THROW(use_direction_binner_target("NO_SUCH_TARGET"), std::invalid_argument);
  EXPECT_EQ(direction_binner_target(), targets.front());
}

// The final bins: every target's vector pass, and the scalar reference, give bin_of's bins exactly, in one
// call and in batches of every length from 1 to 37 (whole vectors plus every possible tail), with and
// without FTZ/DAZ.
TEST(DirectionBinner, VectorPathEqualsScalarReferenceAndBinOf) {
  const std::vector<DirectionBinning> binnings = test_binnings();
  std::uint64_t seed = 100;
  for (const DirectionBinning& b : binnings) {
    const FastDirectionBinner fast(b);
    ASSERT_TRUE(fast.specialised_for_floats()) << b.name() << " " << b.rows();
    const Directions d = directions_for(b, ++seed);
    for (const bool flush_denormals : {false, true}) {
      std::optional<embree::FlushDenormalsScope> ftz;
      if (flush_denormals) ftz.emplace();
      const std::vector<int> expected = expected_bins(b, d);  // in the same environment (DAZ reads denormals as 0)
      std::vector<int> bins(std::size_t(d.size()), -7);
      fast.bin_floats_scalar(d.x.data(), d.y.data(), d.z.data(), d.size(), bins.data());
      for (int i = 0; i < d.size(); ++i) {
        ASSERT_EQ(bins[std::size_t(i)], expected[std::size_t(i)])
            << "scalar reference, " << b.name() << " rows " << b.rows() << " d " << d.at(i).transpose() << " ftz " << flush_denormals;
      }
      for (const std::string& target : direction_binner_targets()) {
        TargetScope scope(target);
        for (const int chunk : {d.size(), 1, 7, 8, 15, 16, 17, 37, 256}) {
          std::fill(bins.begin(), bins.end(), -7);
          for (int first = 0; first < d.size(); first += chunk) {
            const int n = std::min(chunk, d.size() - first);
            fast.bin_floats(d.x.data() + first, d.y.data() + first, d.z.data() + first, n, bins.data() + first);
          }
          for (int i = 0; i < d.size(); ++i) {
            ASSERT_EQ(bins[std::size_t(i)], expected[std::size_t(i)])
                << target << ", chunks of " << chunk << ", " << b.name() << " rows " << b.rows() << " d "
                << d.at(i).transpose() << " ftz " << flush_denormals;
          }
        }
      }
    }
  }
}

// Pass 1 alone: where the vector code and the scalar reference are both certain they agree (and agree
// with bin_of); a direction within half a guard band of a row or column edge (in double) is never certain
// in either (it goes to bin_of); and the fallback is taken, but rarely, on random directions.
TEST(DirectionBinner, GuardBandsSendEdgeDirectionsToBinOf) {
  constexpr int kNeedsExact = FastDirectionBinner::kNeedsExact;
  std::uint64_t seed = 200;
  for (const DirectionBinning& b : test_binnings()) {
    const FastDirectionBinner fast(b);
    const Directions d = directions_for(b, ++seed);
    const std::vector<int> expected = expected_bins(b, d);
    const double row_band = 0.5e-5 * b.rows(), col_band = 0.5e-5 * b.cols();
    std::vector<int> scalar(std::size_t(d.size())), vector(std::size_t(d.size()));
    const int scalar_exact = fast.classify_floats(d.x.data(), d.y.data(), d.z.data(), d.size(), scalar.data(), false);
    int near_edges = 0;
    for (const std::string& target : direction_binner_targets()) {
      TargetScope scope(target);
      const int vector_exact = fast.classify_floats(d.x.data(), d.y.data(), d.z.data(), d.size(), vector.data(), true);
      EXPECT_GT(vector_exact, 0) << target << " " << b.name();
      EXPECT_NEAR(vector_exact, scalar_exact, 0.01 * d.size() + 20) << target << " " << b.name();
      near_edges = 0;
      for (int i = 0; i < d.size(); ++i) {
        const std::size_t k = std::size_t(i);
        const auto where = [&] { return target + " " + b.name() + " rows " + std::to_string(b.rows()) + " i " + std::to_string(i); };
        if (vector[k] != kNeedsExact) {
          ASSERT_EQ(vector[k], expected[k]) << where();
        }
        if (scalar[k] != kNeedsExact) {
          ASSERT_EQ(scalar[k], expected[k]) << where();
        }
        const std::optional<Fractions> f = exact_fractions(b, d.at(i));
        if (!f) continue;
        const double row_distance = std::abs(f->row - std::round(f->row)), col_distance = std::abs(f->col - std::round(f->col));
        const bool in_space = f->row > -0.5 && f->row < b.rows() + 0.5;
        if (in_space && (row_distance < row_band || col_distance < col_band)) {
          ++near_edges;
          EXPECT_EQ(vector[k], kNeedsExact) << where() << " row " << f->row << " col " << f->col;
          EXPECT_EQ(scalar[k], kNeedsExact) << where() << " row " << f->row << " col " << f->col;
        }
      }
    }
    EXPECT_GT(near_edges, 8 * (b.rows() + b.cols())) << b.name() << ": too few directions in the guard bands";
    // Random directions: the fallback stays rare (about 2e-5 (rows + cols) of them, plus degenerate ones).
    Directions random;
    std::mt19937_64 rng(seed);
    add_random(random, rng, 20'000);
    std::vector<int> bins(std::size_t(random.size()));
    const int exact = fast.classify_floats(random.x.data(), random.y.data(), random.z.data(), random.size(), bins.data(), true);
    EXPECT_LT(exact, 10 * 2e-5 * (b.rows() + b.cols()) * random.size() + 10) << b.name();
  }
}

// Binnings pass 1 does not specialise (fewer than 8 columns, reflected-direction lobes): bin_floats is
// bin_of for every direction, and pass 1 alone is refused.
TEST(DirectionBinner, UnspecialisedBinningsUseBinOf) {
  const std::vector<DirectionBinning> binnings{
      DirectionBinning::sphere(3), DirectionBinning::sphere(1),
      DirectionBinning::lobe(GGX<double>(0.3), direction_from_degrees(40.0, 10.0), SampleDomain::microfacet_normal, 3),
      DirectionBinning::lobe(GGX<double>(0.3), direction_from_degrees(40.0, 10.0), SampleDomain::reflected_direction, 31)};
  for (const DirectionBinning& b : binnings) {
    const FastDirectionBinner fast(b);
    EXPECT_FALSE(fast.specialised_for_floats()) << b.name() << " " << b.rows();
    const Directions d = directions_for(b, 300);
    const std::vector<int> expected = expected_bins(b, d);
    std::vector<int> bins(std::size_t(d.size()));
    fast.bin_floats(d.x.data(), d.y.data(), d.z.data(), d.size(), bins.data());
    EXPECT_EQ(bins, expected) << b.name();
    EXPECT_THROW(fast.classify_floats(d.x.data(), d.y.data(), d.z.data(), d.size(), bins.data(), true), std::logic_error);
  }
}

}  // namespace microsim
