// scatter: one light path on an explicit periodic heightfield, bounce by bounce, followed to
// its escape and histogrammed by its order. scatter/surface_scatter.h runs many of them into a per-order histogram; this header is the
// single path, for that loop, for tests that look at every event, and for benchmarks.
//
// A path starts at a uniform point (x, y) = L (u0, u1) of the tile and travels along -wi: from above the
// maximum height (HeightfieldScene::start_height()) when wi.z > 0, or, for a dielectric lit from inside
// (wi.z < 0), from below the minimum height inside the solid (floor_start_height()). Each trace finds the
// next facet (HeightfieldScene::trace for the primary ray, trace_from_surface for every bounce: periodic
// wrapping, the start triangle skipped, the origin kept on the path's own side, convex-edge grazes passed
// over); the facet event is scatter_on_facet (microfacet/material.h) with the facet normal oriented to
// the path's side, and a refraction moves the path to the other side. The path ends when it leaves the
// slab of heights: upward outside (it left after `order` events into the upper hemisphere) or downward
// inside (into the lower medium, the lower hemisphere); or when it meets a facet after max_order events
// (unfinished: the weight it still carries is reported, never dropped); or when the tracer loses it
// (lost, with the cause).
//
// Weights: one per material channel, the product of the facet events' factors (a conductor's per-channel
// Fresnel reflectance, a Lambertian albedo; 1 for a mirror and a dielectric, whose choice between
// reflection and refraction is made with probability F: Walter, Marschner, Li, Torrance 2007,
// "Microfacet Models for Refraction through Rough Surfaces", EGSR, section 5.3; Heitz, Hanika, d'Eon,
// Dachsbacher 2016, "Multiple-Scattering Microfacet BSDFs with the Smith Model", SIGGRAPH, section 5).
//
// Variates (path_event_stream): path i of a block b of `block_size` paths takes its origin from draws
// 2i and 2i + 1 of CounterRng(seed, b) (exactly the origin of trace_vndf_heightfield's ray i of block b
// for the same seed), and its facet events, two uniforms each whether the material uses them or not, from
// the draws 2 block_size + 2 i kMaxPathEvents on, so that a path is a pure function of (seed, b, i),
// whatever order the paths of a block are traced in.
#pragma once

#include "core/random.h"
#include "microfacet/material.h"
#include "trace/heightfield_trace.h"

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

namespace microsim {

enum class PathEnd {
  reflected,    // left upward above the maximum height (the upper hemisphere)
  transmitted,  // left downward below the minimum height, inside the solid (the lower hemisphere)
  unfinished,   // met a facet after max_order events
  lost,         // lost by the tracer (see PathLoss)
};

enum class PathLoss {
  none,
  leaked,          // went below the minimum height outside the solid (through the surface)
  crossed_unseen,  // rose above the maximum height inside the solid (through the surface)
  unresolved,      // still wrapping after kMaxSegments segments
  wrong_side,      // hit a facet from the side opposite to the path's (an inconsistency of the tracer)
};

inline constexpr std::uint64_t kMaxPathEvents = 100000;  // the largest order cap (scatter_setup.h kMaxOrderCap)

// The facet-event stream of path i of a block of block_size paths (see above).
inline CounterRng path_event_stream(std::uint64_t seed, std::uint64_t block, std::uint64_t i, std::uint64_t block_size) {
  CounterRng rng(seed, block);
  rng.seek(2 * block_size + 2 * i * kMaxPathEvents);
  return rng;
}

// One facet event.
struct SurfacePathEvent {
  std::uint32_t triangle = 0;                 // the facet hit
  Vec3<double> point = Vec3<double>::Zero();  // the hit point (x, y wrapped into the tile)
  Vec3<double> wo = Vec3<double>::Zero();     // the direction leaving the facet
  bool refracted = false;
};

struct SurfacePath {
  PathEnd end = PathEnd::lost;
  PathLoss loss = PathLoss::none;
  int order = 0;                                    // facet events
  Vec3<double> direction = Vec3<double>::Zero();  // the direction it left in (reflected, transmitted)
  std::array<double, Material::kMaxChannels> weight{};  // per channel (the material's channels())
  int traced = 0;       // HeightfieldScene::trace calls (the primary ray and one per event)
  int segments = 0;     // Embree calls
  int edge_grazes = 0;  // convex-edge grazes passed over
};

// A path between two traces: where its next ray starts, where it goes, its event stream.
struct PathState {
  Vec3<double> point = Vec3<double>::Zero(), dir = Vec3<double>::Zero();
  std::optional<std::uint32_t> start;  // the facet the ray leaves (none: the primary ray)
  Vec3<double> start_up = Vec3<double>::Zero();  // its unit upward normal
  RaySide side = RaySide::outside;
  CounterRng rng{0, 0};
};

class SurfacePathTracer {
public:
  // Throws std::invalid_argument for a wi that is not a finite unit direction off the horizon, for light
  // from inside (wi.z < 0) on a material that does not transmit, or for max_order outside
  // [1, kMaxPathEvents].
  SurfacePathTracer(const HeightfieldScene& scene, const Material& material, const Vec3<double>& wi, int max_order);

  const HeightfieldScene& scene() const { return scene_; }
  const Material& material() const { return material_; }
  const Vec3<double>& wi() const { return wi_; }
  RaySide start_side() const { return start_side_; }

  // The start of the path of the uniforms (u0, u1): (L u0, L u1) at the start height of its side.
  Vec3<double> origin(double u0, double u1) const {
    return {tile_ * u0, tile_ * u1, start_side_ == RaySide::outside ? scene_.start_height() : scene_.floor_start_height()};
  }
  // Follows one path from `origin` along -wi, facet events from `rng` (its event stream), into `path`;
  // every facet event is appended to `events` if given, and every Embree call of its rays to `calls`.
  void trace(const Vec3<double>& origin, CounterRng rng, SurfacePath& path,
             std::vector<SurfacePathEvent>* events = nullptr, std::vector<EmbreeCall>* calls = nullptr) const;
  // The paths [0, n) of block `block` of block_size paths, with their variates (path_event_stream), in
  // order; done(i, path) is called for i = 0, 1, ... in order. The pyramid geometry traces the paths'
  // rays bounce by bounce, together (HeightfieldScene::trace_rays); the Embree geometries trace the paths
  // in pairs, their rays alternately (the faster way for them, measured), every Embree call appended to
  // `calls` if given.
  void trace_block(std::uint64_t seed, std::uint64_t block, std::uint64_t n, std::uint64_t block_size,
                   const std::function<void(std::uint64_t, const SurfacePath&)>& done,
                   std::vector<EmbreeCall>* calls = nullptr) const;

  // The steps of a path: begin it, trace its current ray, apply the result (returns whether the path
  // goes on: a facet event happened and a new ray leaves the facet).
  void begin(const Vec3<double>& origin, CounterRng rng, PathState& state, SurfacePath& path) const;
  HeightfieldHit trace_ray(const PathState& state, std::vector<EmbreeCall>* calls = nullptr) const;
  bool advance(PathState& state, SurfacePath& path, const HeightfieldHit& hit,
               std::vector<SurfacePathEvent>* events = nullptr) const;

private:
  void trace_block_in_pairs(std::uint64_t seed, std::uint64_t block, std::uint64_t n, std::uint64_t block_size,
                            const std::function<void(std::uint64_t, const SurfacePath&)>& done,
                            std::vector<EmbreeCall>* calls) const;
  void end_without_hit(RayOutcome outcome, const PathState& state, SurfacePath& path) const;

  const HeightfieldScene& scene_;
  Material material_;
  Vec3<double> wi_;
  int max_order_;
  RaySide start_side_;
  double tile_;
};

}  // namespace microsim
