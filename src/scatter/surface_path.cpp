// scatter: one light path on an explicit heightfield (see surface_path.h).
#include "scatter/surface_path.h"

#include <fmt/core.h>

#include <cmath>
#include <optional>
#include <stdexcept>

namespace microsim {

namespace {

RaySide other_side(RaySide s) { return s == RaySide::outside ? RaySide::inside : RaySide::outside; }

}  // namespace

SurfacePathTracer::SurfacePathTracer(const HeightfieldScene& scene, const Material& material, const Vec3<double>& wi,
                                     int max_order)
    : scene_(scene), material_(material), wi_(wi), max_order_(max_order),
      start_side_(wi.z() > 0 ? RaySide::outside : RaySide::inside), tile_(scene.field().tile_size()) {
  if (!wi.allFinite() || std::abs(wi.norm() - 1.0) > 1e-9 || wi.z() == 0.0) {
    throw std::invalid_argument(
        fmt::format("surface scatter: wi ({}, {}, {}) must be a unit direction off the horizon", wi.x(), wi.y(), wi.z()));
  }
  if (wi.z() < 0 && !material.transmits()) {
    throw std::invalid_argument(fmt::format("surface scatter: light from inside the solid (wi.z {}) needs a dielectric, "
                                            "not {}",
                                            wi.z(), material.describe()));
  }
  if (max_order < 1) throw std::invalid_argument(fmt::format("surface scatter: order cap {} (at least 1)", max_order));
}

// The primary ray (start: none) or a bounce from the facet `start`.
HeightfieldHit SurfacePathTracer::trace_ray(const Vec3<double>& p, const Vec3<double>& d,
                                            std::optional<std::uint32_t> start, RaySide side,
                                            std::vector<EmbreeCall>* calls) const {
  if (calls) return scene_.trace_recording(p, d, start, side, *calls);
  return start ? scene_.trace_from_surface(p, d, *start, side) : scene_.trace(p, d, std::nullopt, side);
}

void SurfacePathTracer::trace(const Vec3<double>& origin, CounterRng& rng, SurfacePath& path,
                              std::vector<SurfacePathEvent>* events, std::vector<EmbreeCall>* calls) const {
  const int channels = material_.channels();
  path.end = PathEnd::lost;
  path.loss = PathLoss::none;
  path.order = path.traced = path.segments = path.edge_grazes = 0;
  for (int c = 0; c < channels; ++c) path.weight[std::size_t(c)] = 1.0;
  std::array<double, Material::kMaxChannels> factors;
  const std::span<double> factor_span(factors.data(), std::size_t(channels));
  Vec3<double> p = origin, d = -wi_;
  std::optional<std::uint32_t> start;
  RaySide side = start_side_;
  for (;;) {
    const HeightfieldHit hit = trace_ray(p, d, start, side, calls);
    ++path.traced;
    path.segments += hit.segments;
    path.edge_grazes += hit.edge_grazes;
    if (!hit.is_hit()) return end_without_hit(hit.outcome, side, d, path);
    // The upward facet normal; the path must meet the facet from its own side.
    const Vec3<double> up = scene_.field().triangle_normal(hit.triangle);
    const double cos_up = d.dot(up);
    if (side == RaySide::outside ? !(cos_up < 0.0) : !(cos_up > 0.0)) {
      path.loss = PathLoss::wrong_side;
      return;
    }
    if (path.order == max_order_) {
      path.end = PathEnd::unfinished;
      return;
    }
    const Vec3<double> m = side == RaySide::outside ? up : Vec3<double>(-up);
    const Vec2<double> u(rng.uniform(), rng.uniform());
    const FacetEvent event = scatter_on_facet(material_, -d, m, side == RaySide::inside, u, factor_span);
    for (int c = 0; c < channels; ++c) path.weight[std::size_t(c)] *= factors[std::size_t(c)];
    ++path.order;
    if (event.refracted) side = other_side(side);
    if (events) events->push_back({hit.triangle, hit.point, event.wo, event.refracted});
    p = hit.point;
    d = event.wo;
    start = hit.triangle;
  }
}

// The ray left the slab of heights without a hit: escaped upward or downward on its side, or lost.
void SurfacePathTracer::end_without_hit(RayOutcome outcome, RaySide side, const Vec3<double>& dir,
                                        SurfacePath& path) const {
  path.direction = dir;
  if (path.order > 0 && side == RaySide::outside && outcome == RayOutcome::escaped) {
    path.end = PathEnd::reflected;
  } else if (path.order > 0 && side == RaySide::inside && outcome == RayOutcome::leaked) {
    path.end = PathEnd::transmitted;
  } else {
    path.end = PathEnd::lost;
    path.loss = outcome == RayOutcome::unresolved ? PathLoss::unresolved
                : outcome == RayOutcome::leaked   ? PathLoss::leaked
                                                  : PathLoss::crossed_unseen;
  }
}

}  // namespace microsim
