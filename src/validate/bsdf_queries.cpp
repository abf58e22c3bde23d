// The query set of `microsim bsdf-queries` (bsdf_queries.h).
#include "validate/bsdf_queries.h"

#include "core/random.h"
#include "microfacet/samplers.h"

#include <cmath>
#include <stdexcept>

namespace microsim {

namespace {

constexpr double kViewThetas[] = {0, 30, 60, 80, 89.9};
constexpr double kViewPhis[] = {0, 45};
constexpr double kGrazing = 89.9;

Vec3<double> from_degrees(double theta, double phi) {
  const double t = theta * kPi<double> / 180, p = phi * kPi<double> / 180;
  return {std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t)};
}

// `count` directions jittered in equal-area cells (z uniform, phi uniform) of z in [z_min, 1].
void stratified(std::vector<BsdfQuery>& out, const Vec3<double>& wi, int count, double z_min, CounterRng& rng) {
  const int rows = std::max(1, int(std::lround(std::sqrt(count / 2.0)))), cols = std::max(1, count / rows);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const double z = z_min + (1 - z_min) * (r + rng.uniform()) / rows, phi = 2 * kPi<double> * (c + rng.uniform()) / cols;
      const double s = std::sqrt(std::max(0.0, 1 - z * z));
      out.push_back({wi, Vec3<double>(s * std::cos(phi), s * std::sin(phi), z)});
    }
}

// The edge cases of one view (wi on either side).
void edge_cases(std::vector<BsdfQuery>& out, const Vec3<double>& wi, const Material& bsdf) {
  const double side = wi.z() < 0 ? -1 : 1;
  out.push_back({wi, Vec3<double>(-wi.x(), -wi.y(), wi.z())});  // the mirror direction
  out.push_back({wi, wi});
  out.push_back({wi, -wi});
  for (int k = 0; k < 8; ++k) {
    const Vec3<double> g = from_degrees(kGrazing, 45.0 * k);
    out.push_back({wi, Vec3<double>(g.x(), g.y(), side * g.z())});
    if (bsdf.transmits()) out.push_back({wi, Vec3<double>(g.x(), g.y(), -side * g.z())});
  }
  Vec3<double> t;
  const double eta = side > 0 ? bsdf.eta() : 1 / bsdf.eta();
  if (bsdf.transmits() && refract(wi, Vec3<double>(0, 0, side), eta, t)) out.push_back({wi, t});
}

// per_view / 4 wo about normals drawn from the visible normals of `ggx` (seen from wi's side).
void in_the_lobe(std::vector<BsdfQuery>& out, const Vec3<double>& wi, const Material& bsdf, const GGX<double>& ggx,
                 int count, CounterRng& rng) {
  const double side = wi.z() < 0 ? -1 : 1;
  const Vec3<double> up(wi.x(), wi.y(), side * wi.z());
  for (int i = 0; i < count; ++i) {
    const auto m = sample_heitz2018(ggx, up, Vec2<double>(rng.uniform(), rng.uniform()));
    if (!m) continue;
    Vec3<double> wo = reflect(up, m->direction);
    if (bsdf.transmits() && i % 2 == 1 && !refract(up, m->direction, side > 0 ? bsdf.eta() : 1 / bsdf.eta(), wo)) continue;
    out.push_back({wi, Vec3<double>(wo.x(), wo.y(), side * wo.z())});
  }
}

}  // namespace

std::vector<BsdfQuery> bsdf_queries(const Material& bsdf, int per_view, std::uint64_t seed,
                                    const std::optional<GGX<double>>& ggx) {
  if (per_view < 2) throw std::invalid_argument("bsdf queries: at least 2 directions per view");
  std::vector<BsdfQuery> out;
  std::uint64_t view = 0;
  for (const double side : {1.0, -1.0}) {
    if (side < 0 && !bsdf.transmits()) break;
    for (const double theta : kViewThetas)
      for (const double phi : kViewPhis) {
        if (theta == 0 && phi != 0) continue;
        const Vec3<double> v = from_degrees(theta, phi), wi(v.x(), v.y(), side * v.z());
        CounterRng rng(seed, view++);
        stratified(out, wi, per_view, bsdf.transmits() ? -1.0 : 0.0, rng);
        edge_cases(out, wi, bsdf);
        if (ggx) in_the_lobe(out, wi, bsdf, *ggx, per_view / 4, rng);
      }
  }
  return out;
}

}  // namespace microsim
