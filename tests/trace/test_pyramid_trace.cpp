// The pyramid tracer (trace/heightfield_pyramid.h) against Embree's triangles on the same rays: the same
// outcome and the same hit triangle for every ray, primary rays from above at angles up to 88 deg and every
// bounce of explicit scattering paths (a mirror, and a dielectric whose refracted rays travel inside the
// solid), on rough `smith` tiles. A disagreement is accepted only as the one named edge case: the ray
// passes within kEdgeBand of an edge or diagonal of the surface before either hit (|z - surface height| at
// that crossing; Embree traces in float, with its origin rounded to float, so its choice there is float
// rounding: heightfield_trace.h, "Convex-edge grazes"). Such cases must stay rare (at most 1e-4 of the
// rays), and a bounce ray starting that close to an edge counts too (its first crossing is an edge at once).
// Negative control: a pyramid tracer on heights shifted by 1e-3 (a wrong surface) disagrees on many rays
// that are not edge cases.
#include "scatter/surface_path.h"

#include "core/random.h"
#include "microgeom/assembly.h"
#include "trace/heightfield_pyramid_lanes.h"
#include "stats/direction_binner.h"
#include "trace/heightfield_trace.h"
#include "trace/trace_vndf.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

namespace microsim {
namespace {

constexpr double kEdgeBand = 1.0 / 65536;  // of max(L, height range): 2^-16, 512 float ulps of 1

microgeom::Heightfield smith(int res, double alpha, std::uint64_t seed) {
  microgeom::AssemblyParams p;
  p.assembly = "smith";
  p.alpha_x = p.alpha_y = alpha;
  p.resolution = res;
  p.seed = seed;
  return microgeom::build_assembly(p);
}

// The least |z - surface height| of the ray at the cell edges and cell diagonals it crosses for t in
// (0, t_max] (a grid walk in unwrapped cells, as reference_trace's).
double closest_edge_approach(const microgeom::Heightfield& f, const Vec3<double>& o, const Vec3<double>& d,
                             double t_max) {
  const double h = f.cell_size();
  long ci = long(std::floor(o.x() / h)), cj = long(std::floor(o.y() / h));
  const int sx = d.x() > 0 ? 1 : -1, sy = d.y() > 0 ? 1 : -1;
  const auto edge_t = [&](long c, int s, double oc, double dc) {
    return dc == 0 ? INFINITY : ((s > 0 ? c + 1 : c) * h - oc) / dc;
  };
  const auto gap = [&](double t) {
    const Vec3<double> p = o + t * d;
    return std::abs(p.z() - f.height_at(p.x(), p.y()));
  };
  double best = INFINITY, t_in = 0;
  for (int step = 0; step < 4'000'000 && t_in <= t_max; ++step) {
    const double tx = edge_t(ci, sx, o.x(), d.x()), ty = edge_t(cj, sy, o.y(), d.y());
    const double t_out = std::min(tx, ty);
    // The diagonal x - ci h = y - cj h of this cell.
    const double denom = d.x() - d.y();
    if (denom != 0) {
      const double td = ((ci - cj) * h - (o.x() - o.y())) / denom;
      if (td > t_in && td < t_out && td <= t_max) best = std::min(best, gap(td));
    }
    if (t_out > t_max || !std::isfinite(t_out)) break;
    best = std::min(best, gap(t_out));
    if (tx <= ty) ci += sx;
    if (ty <= tx) cj += sy;
    t_in = t_out;
  }
  return best;
}

struct Tally {
  long rays = 0, same = 0, edge_cases = 0, other = 0;
};

// Compares one ray traced both ways; `embree` is the Embree scene's result (already traced).
void compare(const HeightfieldScene& pyramid, const HeightfieldHit& embree, const HeightfieldHit& pyr,
             const Vec3<double>& origin, const Vec3<double>& dir, double band, Tally& tally) {
  ++tally.rays;
  const bool same = embree.outcome == pyr.outcome && (!embree.is_hit() || embree.triangle == pyr.triangle);
  if (same) {
    ++tally.same;
    return;
  }
  const double t_max = std::max(embree.is_hit() ? embree.t : 0.0, pyr.is_hit() ? pyr.t : 0.0);
  const double approach = t_max > 0 ? closest_edge_approach(pyramid.field(), origin, dir, t_max) : INFINITY;
  if (approach < band) {
    ++tally.edge_cases;
  } else {
    ++tally.other;
    ADD_FAILURE() << "ray " << origin.transpose() << " dir " << dir.transpose() << ": embree "
                  << int(embree.outcome) << " triangle " << embree.triangle << " t " << embree.t << ", pyramid "
                  << int(pyr.outcome) << " triangle " << pyr.triangle << " t " << pyr.t << ", closest edge approach " << approach
                  << ", reference " << reference_trace(pyramid.field(), origin, dir).triangle;
  }
}

double band_of(const microgeom::Heightfield& f) {
  return kEdgeBand * std::max(f.tile_size(), double(f.max_height()) - double(f.min_height()));
}

// Primary rays from above (uniform origins, directions uniform in azimuth and in theta up to 88 deg).
Tally primary_rays(const HeightfieldScene& embree, const HeightfieldScene& pyramid, int rays, std::uint64_t seed) {
  Tally tally;
  CounterRng rng(seed, 0);
  const double tile = embree.field().tile_size(), band = band_of(embree.field());
  embree::FlushDenormalsScope ftz;
  for (int i = 0; i < rays; ++i) {
    const Vec3<double> o(tile * rng.uniform(), tile * rng.uniform(), embree.start_height());
    const Vec3<double> d = -direction_from_degrees(88.0 * rng.uniform(), 360.0 * rng.uniform());
    compare(pyramid, embree.trace(o, d), pyramid.trace(o, d), o, d, band, tally);
  }
  return tally;
}

// Every ray of explicit scattering paths traced by Embree (SurfacePathTracer), each traced again by the
// pyramid from the same origin, start facet and side.
Tally path_rays(const HeightfieldScene& embree, const HeightfieldScene& pyramid, const Material& material,
                double theta, int paths, std::uint64_t seed) {
  Tally tally;
  const Vec3<double> wi = direction_from_degrees(theta, 25.0);
  const SurfacePathTracer tracer(embree, material, wi, 64);
  const double band = band_of(embree.field());
  CounterRng origins(seed, 0);
  SurfacePath path;
  std::vector<SurfacePathEvent> events;
  embree::FlushDenormalsScope ftz;
  for (int i = 0; i < paths; ++i) {
    const Vec3<double> o = tracer.origin(origins.uniform(), origins.uniform());
    events.clear();
    tracer.trace(o, path_event_stream(seed, 1, std::uint64_t(i), std::uint64_t(paths)), path, &events);
    // The primary ray, then one ray per event (the last one leaves the surface unless the path was cut).
    compare(pyramid, embree.trace(o, -wi), pyramid.trace(o, -wi), o, -wi, band, tally);
    RaySide side = RaySide::outside;
    for (std::size_t k = 0; k < events.size(); ++k) {
      const SurfacePathEvent& e = events[k];
      if (e.refracted) side = side == RaySide::outside ? RaySide::inside : RaySide::outside;
      const Vec3<double> up = embree.field().triangle_normal(e.triangle);
      const HeightfieldHit a = embree.trace_from_surface(e.point, e.wo, e.triangle, up, side);
      const HeightfieldHit b = pyramid.trace_from_surface(e.point, e.wo, e.triangle, up, side);
      if (k + 1 < events.size()) {
        EXPECT_TRUE(a.is_hit() && a.triangle == events[k + 1].triangle);
      }
      compare(pyramid, a, b, embree.surface_origin(e.point, e.triangle, up, side), e.wo, band, tally);
    }
  }
  return tally;
}

void expect_equivalent(const Tally& t, const char* what) {
  EXPECT_EQ(t.other, 0) << what;
  EXPECT_LE(double(t.edge_cases), 1e-4 * double(t.rays)) << what;
  EXPECT_GT(t.rays, 0) << what;
  std::printf("[ pyramid ] %s: %ld rays, %ld same hit, %ld edge cases\n", what, t.rays, t.same, t.edge_cases);
}

TEST(PyramidTrace, SameHitsAsEmbreeForPrimaryRays) {
  for (const double alpha : {0.3, 1.0}) {
    const auto field = smith(256, alpha, 3);
    const HeightfieldScene embree(field, HeightfieldGeometry::triangles), pyramid(field, HeightfieldGeometry::pyramid);
    expect_equivalent(primary_rays(embree, pyramid, 200'000, 11), alpha < 0.5 ? "primary, alpha 0.3" : "primary, alpha 1");
  }
}

TEST(PyramidTrace, SameHitsAsEmbreeAtEveryBounce) {
  const auto field = smith(128, 0.8, 5);
  const HeightfieldScene embree(field, HeightfieldGeometry::triangles), pyramid(field, HeightfieldGeometry::pyramid);
  expect_equivalent(path_rays(embree, pyramid, Material::mirror(), 60.0, 40'000, 7), "mirror paths, theta 60");
  expect_equivalent(path_rays(embree, pyramid, Material::dielectric(1.5), 30.0, 40'000, 8), "dielectric paths, theta 30");
}

// A resolution that is not a power of two (the pyramid's last node of a row is cut at the tile edge).
TEST(PyramidTrace, SameHitsOnATileOfResolution100) {
  const auto square = smith(128, 0.6, 9);
  std::vector<float> cropped;  // its first 100 x 100 vertices, a periodic tile of its own (with a seam)
  for (int j = 0; j < 100; ++j)
    for (int i = 0; i < 100; ++i) cropped.push_back(square.height_unchecked(i, j));
  const microgeom::Heightfield field(100, 100.0 / 128, std::move(cropped));
  const HeightfieldScene embree(field, HeightfieldGeometry::triangles), pyramid(field, HeightfieldGeometry::pyramid);
  expect_equivalent(primary_rays(embree, pyramid, 100'000, 12), "primary, 100^2");
  expect_equivalent(path_rays(embree, pyramid, Material::dielectric(1.5), 50.0, 20'000, 13), "dielectric paths, 100^2");
}

// Embree's grid geometry as the other side.
TEST(PyramidTrace, SameHitsAsEmbreesGrid) {
  const auto field = smith(128, 0.6, 9);
  const HeightfieldScene grid(field, HeightfieldGeometry::grid), pyramid(field, HeightfieldGeometry::pyramid);
  expect_equivalent(primary_rays(grid, pyramid, 100'000, 14), "primary, grid");
  expect_equivalent(path_rays(grid, pyramid, Material::mirror(), 70.0, 20'000, 15), "mirror paths, grid");
}

// The rays of the regression pin `heightfield` (tests/test_regression_pins.cpp: `surface build --assembly
// smith --res 256 --alpha 0.3 --seed 1`, `trace vndf --theta 30 --phi 10 --rays 200000 --seed 3`; the
// origins of trace_vndf_heightfield): the ones whose hit differs are edge cases, listed.
TEST(PyramidTrace, ThePinnedVndfRaysDifferOnlyOnEdgeCases) {
  const auto field = smith(256, 0.3, 1);
  const HeightfieldScene embree(field, HeightfieldGeometry::triangles), pyramid(field, HeightfieldGeometry::pyramid);
  const Vec3<double> d = -direction_from_degrees(30.0, 10.0);
  Tally t;
  embree::FlushDenormalsScope ftz;
  for (std::uint64_t block = 0; block * kRaysPerBlock < 200'000; ++block) {
    CounterRng rng(3, block);
    for (std::uint64_t i = block * kRaysPerBlock; i < std::min<std::uint64_t>(200'000, (block + 1) * kRaysPerBlock); ++i) {
      const Vec3<double> o(rng.uniform(), rng.uniform(), embree.start_height());
      const HeightfieldHit a = embree.trace(o, d), b = pyramid.trace(o, d);
      const long before = t.edge_cases;
      compare(pyramid, a, b, o, d, band_of(field), t);
      if (t.edge_cases > before)
        std::printf("[ pyramid ] pinned ray %llu: embree triangle %u (t %.17g, %d grazes), pyramid %u (t %.17g), "
                    "closest edge approach %.3g\n", (unsigned long long)i, a.triangle, a.t, a.edge_grazes, b.triangle,
                    b.t, closest_edge_approach(field, o, d, std::max(a.t, b.t)));
    }
  }
  expect_equivalent(t, "the pinned VNDF rays");
}

TEST(PyramidTrace, NegativeControlAShiftedSurfaceDisagrees) {
  const auto field = smith(128, 0.8, 5);
  std::vector<float> shifted = field.heights();
  for (std::size_t k = 0; k < shifted.size(); k += 7) shifted[k] += 1e-3f;  // a wrong surface
  const microgeom::Heightfield wrong(field.resolution(), field.tile_size(), std::move(shifted));
  const HeightfieldScene embree(field, HeightfieldGeometry::triangles), pyramid(wrong, HeightfieldGeometry::pyramid);
  Tally t;
  CounterRng rng(21, 0);
  embree::FlushDenormalsScope ftz;
  for (int i = 0; i < 20'000; ++i) {
    const Vec3<double> o(rng.uniform(), rng.uniform(), embree.start_height() + 0.01);
    const Vec3<double> d = -direction_from_degrees(80.0 * rng.uniform(), 360.0 * rng.uniform());
    const HeightfieldHit a = embree.trace(o, d), b = pyramid.trace(o, d);
    ++t.rays;
    if (a.outcome == b.outcome && (!a.is_hit() || a.triangle == b.triangle)) continue;
    const double t_max = std::max(a.is_hit() ? a.t : 0.0, b.is_hit() ? b.t : 0.0);
    if (closest_edge_approach(field, o, d, t_max) >= band_of(field)) ++t.other;
  }
  EXPECT_GT(t.other, 100);
}

// ---- PyramidTracer::trace_batch (walks in SIMD lanes) against trace(), ray by ray -------------------------

// Rays whose batch result differs from trace()'s in any field (outcome, triangle, segments, t and the hit
// point, bit for bit).
long batch_differences(const PyramidTracer& batch_tracer, const PyramidTracer& tracer,
                       const std::vector<PyramidTracer::Ray>& rays) {
  std::vector<HeightfieldHit> out(rays.size());
  batch_tracer.trace_batch(rays, out);
  const auto same_bits = [](const auto& a, const auto& b) { return std::memcmp(&a, &b, sizeof(a)) == 0; };
  long differ = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const HeightfieldHit a = tracer.trace(rays[i].origin, rays[i].dir, rays[i].skip_triangle), &b = out[i];
    const bool same = a.outcome == b.outcome && a.triangle == b.triangle && a.segments == b.segments &&
                      same_bits(a.t, b.t) && same_bits(a.point.x(), b.point.x()) &&
                      same_bits(a.point.y(), b.point.y()) && same_bits(a.point.z(), b.point.z());
    differ += !same;
  }
  return differ;
}

// Primary rays from above: directions at theta 0 (vertical) and uniform in [0, 88] deg, any azimuth, each
// along with `per_direction` uniform origins (one direction per run of rays, as trace vndf's batches).
std::vector<PyramidTracer::Ray> primary_batch(const HeightfieldScene& scene, int directions, int per_direction,
                                              std::uint64_t seed) {
  std::vector<PyramidTracer::Ray> rays;
  CounterRng rng(seed, 0);
  const double tile = scene.field().tile_size();
  for (int k = 0; k < directions; ++k) {
    const Vec3<double> d = -direction_from_degrees(k == 0 ? 0.0 : 88.0 * rng.uniform(), 360.0 * rng.uniform());
    for (int i = 0; i < per_direction; ++i) {
      const double x = tile * rng.uniform(), y = tile * rng.uniform();
      rays.push_back({Vec3<double>(x, y, scene.start_height()), d, std::nullopt});
    }
  }
  return rays;
}

// Every bounce ray of explicit scattering paths on the pyramid scene, as trace_from_surface passes it to
// the tracer (from surface_origin, its start triangle skipped); the primary rays too.
std::vector<PyramidTracer::Ray> path_batch(const HeightfieldScene& scene, const Material& material, double theta,
                                           int paths, std::uint64_t seed) {
  std::vector<PyramidTracer::Ray> rays;
  const Vec3<double> wi = direction_from_degrees(theta, 25.0);
  const SurfacePathTracer tracer(scene, material, wi, 64);
  CounterRng origins(seed, 0);
  SurfacePath path;
  std::vector<SurfacePathEvent> events;
  for (int i = 0; i < paths; ++i) {
    const Vec3<double> o = tracer.origin(origins.uniform(), origins.uniform());
    events.clear();
    tracer.trace(o, path_event_stream(seed, 1, std::uint64_t(i), std::uint64_t(paths)), path, &events);
    rays.push_back({o, -wi, std::nullopt});
    RaySide side = RaySide::outside;
    for (const SurfacePathEvent& e : events) {
      if (e.refracted) side = side == RaySide::outside ? RaySide::inside : RaySide::outside;
      const Vec3<double> up = scene.field().triangle_normal(e.triangle);
      rays.push_back({scene.surface_origin(e.point, e.triangle, up, side), e.wo, e.triangle});
    }
  }
  return rays;
}

// The batch walk gives every ray trace()'s result to the bit: primary rays at 0-88 deg on 256^2 tiles
// (alpha 0.3 and 1) and a 100^2 tile (not a power of two), and every ray of mirror and dielectric paths
// (the rays of SameHitsAsEmbreeAtEveryBounce), with the default lanes and with one SIMD vector's worth
// (and software prefetch).
// Negative control: the batch of a tracer on heights shifted at every 7th vertex differs on many rays.
TEST(PyramidTrace, BatchWalkIsTraceToTheBit) {
  embree::FlushDenormalsScope ftz;
  const auto check = [](const microgeom::Heightfield& field, const std::vector<PyramidTracer::Ray>& rays, const char* what) {
    const HeightfieldScene scene(field, HeightfieldGeometry::pyramid);
    PyramidTracer tracer(field, scene.escape_height(), scene.floor_height());
    EXPECT_EQ(batch_differences(tracer, tracer, rays), 0) << what;
    tracer.set_batch_lanes(1);  // rounded up to one vector
    tracer.set_batch_prefetch(true);  // the default from 2048^2 on
    EXPECT_EQ(batch_differences(tracer, tracer, rays), 0) << what << ", one vector of lanes, prefetching";
  };
  for (const double alpha : {0.3, 1.0}) {
    const auto field = smith(256, alpha, 3);
    check(field, primary_batch(HeightfieldScene(field, HeightfieldGeometry::pyramid), 30, 1000, 31), "primary rays");
  }
  const auto square = smith(128, 0.6, 9);
  std::vector<float> cropped;
  for (int j = 0; j < 100; ++j)
    for (int i = 0; i < 100; ++i) cropped.push_back(square.height_unchecked(i, j));
  const microgeom::Heightfield field100(100, 100.0 / 128, std::move(cropped));
  check(field100, primary_batch(HeightfieldScene(field100, HeightfieldGeometry::pyramid), 20, 1000, 32), "primary, 100^2");
  const auto field = smith(128, 0.8, 5);
  const HeightfieldScene scene(field, HeightfieldGeometry::pyramid);
  const auto mirror = path_batch(scene, Material::mirror(), 60.0, 10'000, 7);
  const auto glass = path_batch(scene, Material::dielectric(1.5), 30.0, 10'000, 8);
  EXPECT_GT(glass.size(), 20'000u);
  check(field, mirror, "mirror paths");
  check(field, glass, "dielectric paths");
  std::vector<float> shifted = field.heights();
  for (std::size_t k = 0; k < shifted.size(); k += 7) shifted[k] += 1e-3f;
  const microgeom::Heightfield wrong(field.resolution(), field.tile_size(), std::move(shifted));
  const PyramidTracer right_tracer(field, scene.escape_height(), scene.floor_height());
  const PyramidTracer wrong_tracer(wrong, scene.escape_height(), scene.floor_height());
  EXPECT_GT(batch_differences(wrong_tracer, right_tracer, mirror), 500);
}

// The same on every SIMD target this CPU runs (the kernel is compiled once per target; the machine that
// runs the tests picks its best), on fewer rays.
TEST(PyramidTrace, BatchWalkIsTraceToTheBitOnEverySimdTarget) {
  embree::FlushDenormalsScope ftz;
  const auto field = smith(128, 0.8, 5);
  const HeightfieldScene scene(field, HeightfieldGeometry::pyramid);
  const PyramidTracer tracer(field, scene.escape_height(), scene.floor_height());
  const auto primary = primary_batch(scene, 10, 1000, 33);
  const auto paths = path_batch(scene, Material::dielectric(1.5), 40.0, 3000, 9);
  const std::vector<std::string> targets = direction_binner_targets();
  EXPECT_FALSE(targets.empty());
  for (const std::string& target : targets) {
    use_direction_binner_target(target);
    EXPECT_EQ(pyramid_lanes::target_name(), target);
    EXPECT_EQ(batch_differences(tracer, tracer, primary), 0) << target;
    EXPECT_EQ(batch_differences(tracer, tracer, paths), 0) << target;
    std::printf("[ pyramid ] target %s: %zu primary and %zu path rays\n", target.c_str(), primary.size(), paths.size());
  }
  use_direction_binner_target("");
}

}  // namespace
}  // namespace microsim
