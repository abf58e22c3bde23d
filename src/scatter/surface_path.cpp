// scatter: one light path on an explicit heightfield (see surface_path.h).
#include "scatter/surface_path.h"

#include <fmt/core.h>

#include <array>
#include <cmath>
#include <optional>
#include <span>
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
  if (max_order < 1 || std::uint64_t(max_order) > kMaxPathEvents) {
    throw std::invalid_argument(fmt::format("surface scatter: order cap {} (1 to {})", max_order, kMaxPathEvents));
  }
}

void SurfacePathTracer::begin(const Vec3<double>& origin, CounterRng rng, PathState& state, SurfacePath& path) const {
  path.end = PathEnd::lost;
  path.loss = PathLoss::none;
  path.order = path.traced = path.segments = path.edge_grazes = 0;
  for (int c = 0; c < material_.channels(); ++c) path.weight[std::size_t(c)] = 1.0;
  state.point = origin;
  state.dir = -wi_;
  state.start.reset();
  state.side = start_side_;
  state.rng = rng;
}

// The primary ray (no start facet) or a bounce from the start facet.
HeightfieldHit SurfacePathTracer::trace_ray(const PathState& s, std::vector<EmbreeCall>* calls) const {
  if (calls) return scene_.trace_recording(s.point, s.dir, s.start, s.side, *calls);
  if (s.start) return scene_.trace_from_surface(s.point, s.dir, *s.start, s.start_up, s.side);
  return scene_.trace(s.point, s.dir, std::nullopt, s.side);
}

bool SurfacePathTracer::advance(PathState& s, SurfacePath& path, const HeightfieldHit& hit,
                                std::vector<SurfacePathEvent>* events) const {
  ++path.traced;
  path.segments += hit.segments;
  path.edge_grazes += hit.edge_grazes;
  if (!hit.is_hit()) {
    end_without_hit(hit.outcome, s, path);
    return false;
  }
  // The upward facet normal; the path must meet the facet from its own side.
  const Vec3<double> up = scene_.field().triangle_normal(hit.triangle);
  const double cos_up = s.dir.dot(up);
  if (s.side == RaySide::outside ? !(cos_up < 0.0) : !(cos_up > 0.0)) {
    path.loss = PathLoss::wrong_side;
    return false;
  }
  if (path.order == max_order_) {
    path.end = PathEnd::unfinished;
    return false;
  }
  const int channels = material_.channels();
  std::array<double, Material::kMaxChannels> factors;
  const Vec3<double> m = s.side == RaySide::outside ? up : Vec3<double>(-up);
  const Vec2<double> u(s.rng.uniform(), s.rng.uniform());
  const FacetEvent event = scatter_on_facet(material_, -s.dir, m, s.side == RaySide::inside, u,
                                            std::span<double>(factors.data(), std::size_t(channels)));
  for (int c = 0; c < channels; ++c) path.weight[std::size_t(c)] *= factors[std::size_t(c)];
  ++path.order;
  if (event.refracted) s.side = other_side(s.side);
  if (events) events->push_back({hit.triangle, hit.point, event.wo, event.refracted});
  s.point = hit.point;
  s.dir = event.wo;
  s.start = hit.triangle;
  s.start_up = up;
  return true;
}

void SurfacePathTracer::trace(const Vec3<double>& origin, CounterRng rng, SurfacePath& path,
                              std::vector<SurfacePathEvent>* events, std::vector<EmbreeCall>* calls) const {
  PathState s;
  begin(origin, rng, s, path);
  while (advance(s, path, trace_ray(s, calls), events)) {
  }
}

void SurfacePathTracer::trace_block(std::uint64_t seed, std::uint64_t block, std::uint64_t n, std::uint64_t block_size,
                                    const std::function<void(std::uint64_t, const SurfacePath&)>& done,
                                    std::vector<EmbreeCall>* calls) const {
  if (calls || scene_.geometry() != HeightfieldGeometry::pyramid) return trace_block_in_pairs(seed, block, n, block_size, done, calls);
  CounterRng origins(seed, block);
  std::vector<PathState> state(n);
  std::vector<SurfacePath> path(n);
  std::vector<std::uint64_t> live(n);
  for (std::uint64_t i = 0; i < n; ++i) {
    const double u0 = origins.uniform(), u1 = origins.uniform();
    begin(origin(u0, u1), path_event_stream(seed, block, i, block_size), state[i], path[i]);
    live[i] = i;
  }
  // Bounce by bounce: the current rays of the paths still going, traced together
  // (HeightfieldScene::trace_rays: each result trace_ray()'s), then each path advanced. Each path has its
  // own variates and done() is called in path order, so the result is that of tracing them one by one.
  std::vector<HeightfieldScene::SurfaceRay> rays;
  std::vector<HeightfieldHit> hits;
  while (!live.empty()) {
    rays.clear();
    for (const std::uint64_t i : live) {
      const PathState& s = state[i];
      rays.push_back({s.point, s.dir, s.start, s.start_up, s.side});
    }
    hits.resize(rays.size());
    scene_.trace_rays(rays, hits);
    std::size_t kept = 0;
    for (std::size_t q = 0; q < live.size(); ++q)
      if (advance(state[live[q]], path[live[q]], hits[q])) live[kept++] = live[q];
    live.resize(kept);
  }
  for (std::uint64_t i = 0; i < n; ++i) done(i, path[i]);
}

void SurfacePathTracer::trace_block_in_pairs(std::uint64_t seed, std::uint64_t block, std::uint64_t n,
                                             std::uint64_t block_size,
                                             const std::function<void(std::uint64_t, const SurfacePath&)>& done,
                                             std::vector<EmbreeCall>* calls) const {
  CounterRng origins(seed, block);
  const auto start = [&](std::uint64_t i, PathState& state, SurfacePath& path) {
    const double u0 = origins.uniform(), u1 = origins.uniform();
    begin(origin(u0, u1), path_event_stream(seed, block, i, block_size), state, path);
  };
  // Paths in pairs, their rays traced alternately: the hit facet's heights (far from Embree's data, read
  // for its normal) are prefetched while the other path's ray is traced.
  std::array<PathState, 2> state;
  std::array<SurfacePath, 2> path;
  std::array<HeightfieldHit, 2> hit;
  for (std::uint64_t first = 0; first < n; first += 2) {
    const int lanes = n - first >= 2 ? 2 : 1;
    std::array<bool, 2> live{true, lanes == 2};
    for (int k = 0; k < lanes; ++k) start(first + std::uint64_t(k), state[std::size_t(k)], path[std::size_t(k)]);
    while (live[0] || live[1]) {
      for (std::size_t k = 0; k < 2; ++k) {
        if (!live[k]) continue;
        hit[k] = trace_ray(state[k], calls);
        if (hit[k].is_hit()) scene_.field().prefetch_triangle(hit[k].triangle);
      }
      for (std::size_t k = 0; k < 2; ++k)
        if (live[k]) live[k] = advance(state[k], path[k], hit[k]);
    }
    for (int k = 0; k < lanes; ++k) done(first + std::uint64_t(k), path[std::size_t(k)]);
  }
}

// The ray left the slab of heights without a hit: escaped upward or downward on its side, or lost.
void SurfacePathTracer::end_without_hit(RayOutcome outcome, const PathState& state, SurfacePath& path) const {
  const RaySide side = state.side;
  path.direction = state.dir;
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
