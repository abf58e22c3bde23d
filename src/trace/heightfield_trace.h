// microsim: ray tracing a periodic heightfield microsurface (microgeom::Heightfield) with Embree, and a
// small double-precision reference tracer for tests.
//
// Periodic tracing. Embree holds ONE copy of the tile plus a one-cell overlap strip on every side: cells
// -1 .. N in x and y, i.e. vertices -1 .. N+1 (heights wrapped), so the geometry covers
// [-h, L + h]^2 (h = cell size, L = tile size). A ray is traced in SEGMENTS: each segment starts inside the
// tile [0, L]^2 (in x, y) and is clipped (tfar) where the ray leaves the tile, plus half a cell, which the
// overlap strip covers, so a hit on a seam cannot slip between two segments. If the segment hits nothing,
// the ray is moved to its exit point, shifted by -+L on the axis (or axes) it left through (the coordinate
// is set exactly to 0 or L: no drift) and traced again. A ray stops when it hits, or when it is above the
// maximum height going up (it can never come back), or after kMaxSegments (reported as unresolved).
// Every segment origin is kept in double and only rounded to float for Embree, so wrapping accumulates no
// error. A downward ray that drops below the minimum height without hitting is a LEAK (reported; the
// estimators count leaks and the tests require zero).
//
// Self-hits. A ray that starts ON the surface (a shadow or masking ray, given its start triangle) starts
// at its point of the start triangle lifted along the facet normal by surface_offset() (8 float ulps of
// the coordinate scale: the rounding of the origin to float can then never put it below its own or a
// neighbouring facet's plane), AND skips the start triangle by primitive id, through an Embree
// intersection filter, in the first segment (before any wrap; closest-hit calls try without the filter
// first and repeat the call with it only when the closest hit is the start triangle, which gives the
// filtered call's hit). A ray leaving a planar facet upwards can
// never hit that facet's periodic copies from above, so skipping in the first segment is enough.
// The lift is 2^-20 of the coordinate scale: 0.4% of a cell at N = 4096 (L = 1); it changes a shadow
// ray's fate only for start points that close to an edge whose neighbour the ray grazes.
//
// Sides. A ray travels on one side of the surface (RaySide): outside, in the medium above it (every
// shadow, masking and primary ray from above), or inside, in the solid below it (a path refracted into a
// dielectric, scatter/surface_scatter.h). A ray that starts on a facet is lifted to ITS side: along the
// upward facet normal outside, against it inside (lifted()); lifted to the wrong side, the rounded origin
// can lie beyond a neighbouring facet's plane, and the ray then hits that facet from the wrong side (an
// inside ray starting within the lift of a valley line hits the other flank from above). Even on its own
// side, the lift can cross a neighbour's plane at an edge that is concave seen from the ray's side:
// trace_from_surface (the bounces of scattering paths) then moves the origin back to its side
// (surface_origin()). The outcomes
// keep their geometric meaning on both sides: `escaped` = above the maximum height going up (outside: it
// sees the sky; inside: it crossed the surface unseen, a loss), `leaked` = below the minimum height going
// down (outside: a loss; inside: it left the solid downward, into the lower medium).
//
// Convex-edge grazes (trace() only). A ray that starts above the surface must enter the solid before it
// can leave it, so its first hit faces it (dir . m < 0); a ray that starts below it (inside, z mirrored:
// the same rule for the edges that are convex seen from below) must leave the solid first (dir . m > 0). In float, a ray passing within about one ulp of
// the coordinates of a convex edge between a facet it nearly runs along (entering, at a grazing angle)
// and a steeper facet beyond (leaving) can be reported on the leaving facet: Embree is watertight, but
// its float distance to the nearly parallel facet is off by more than the two hits' separation. Measured
// (docs/records/heightfield-trade.md): ~6e-7 per primary ray at alpha 1, 85 deg, N = 1024, every case within
// 0.1-2.5 ulp(1) of an edge. For a ray that starts above the surface at its (x, y) (a primary ray, or a
// point lifted off its start facet; not one traced as outside but started inside the solid, which
// legitimately leaves it first; for RaySide::inside, a ray that starts below the surface at its (x, y)),
// trace() then takes the ray to pass over the edge: it continues from that hit
// with the leaving facet skipped (the same context filter), at most kMaxEdgeGrazes times, and counts it
// in edge_grazes. escapes() (rtcOccluded1, any hit) cannot tell and counts such a graze as blocked: a
// shadow ray within an ulp of a convex edge, of the same ~1e-6 frequency.
//
// Scale. Nothing depends on the absolute units: segment overlaps are in cells, the escape plane sits a
// relative 2^-20 of the height range (plus float ulps of the coordinates) above the maximum height, the
// surface offset is relative to max(L, |heights|).
//
// Geometry kinds (both with RTC_SCENE_FLAG_ROBUST, watertight across shared edges):
// - triangles: RTC_GEOMETRY_TYPE_TRIANGLE, 2 (N+2)^2 triangles in the heightfield's fixed split, primitive
//   id -> heightfield triangle id by arithmetic (exact).
// - grid: RTC_GEOMETRY_TYPE_GRID, one (N+3)^2 vertex grid (Embree's compact grid BVH). Embree splits a grid
//   quad along the diagonal v1-v3; the grid's u axis runs along -x so that this is the heightfield's
//   diagonal (i, j)-(i+1, j+1). The hit triangle is recovered from the grid's (u, v) hit coordinates.
// docs/records/heightfield-trade.md measures both (memory, build time, rays per second).
// - pyramid: no Embree at all; trace/heightfield_pyramid.h walks the cells over a min-max
//   height pyramid and intersects the same two triangles per cell exactly (double, watertight by shared
//   edge heights). The same lift and start-triangle skip; the segment loop, the overlap strip and the
//   convex-edge pass-over are Embree's and do not apply (a ray starting on its side cannot cross the
//   surface the wrong way first; edge_grazes stays 0). embree_scene() and trace_recording() need an
//   Embree geometry. tests/test_pyramid_trace.cpp requires the same hit triangles as the Embree geometry.
//
// Determinism: a ray's result depends on the ray only (single-ray rtcIntersect1 / rtcOccluded1 calls).
#pragma once

#include "microgeom/heightfield.h"
#include "trace/embree.h"
#include "trace/heightfield_pyramid.h"
#include "core/math.h"

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace microsim {

enum class HeightfieldGeometry { triangles, grid, pyramid };
std::string to_string(HeightfieldGeometry g);
// "triangles", "grid" or "pyramid"; throws std::invalid_argument otherwise.
HeightfieldGeometry heightfield_geometry_from_string(const std::string& s);
// The geometry of every heightfield scene not given one (trace vndf, scatter and trace masking --geometry,
// albedo tables, experiments): the pyramid, exact in double and watertight, with no BVH (its memory is near
// the heights', so the largest tiles trace) and faster than Embree's BVH on large tiles
// (docs/records/heightfield-tracers.md). Embree's triangles stay selectable; the two give the same hits except
// on rays within Embree's float rounding of an edge (tests/test_pyramid_trace.cpp).
inline constexpr HeightfieldGeometry kDefaultHeightfieldGeometry = HeightfieldGeometry::pyramid;

inline constexpr int kMaxSegments = 1 << 20;  // per ray; beyond, the ray is reported unresolved
inline constexpr int kMaxEdgeGrazes = 8;       // per ray; beyond, the exiting hit is returned as it is

enum class RayOutcome {
  hit,         // hit a triangle
  escaped,     // rose above the maximum height going up: sees the sky
  leaked,      // went below the minimum height without a hit (a tracer bug if it ever happens)
  unresolved,  // still wrapping after kMaxSegments segments (a nearly horizontal ray)
};

// The side of the surface a ray travels on (see "Sides" above).
enum class RaySide { outside, inside };

// One Embree call made by trace() (trace_recording(), for benchmarks that replay the same calls raw).
struct EmbreeCall {
  Vec3<float> origin, dir;
  float tnear = 0, tfar = 0;
};

struct HeightfieldHit {
  RayOutcome outcome = RayOutcome::escaped;
  std::uint32_t triangle = 0;                     // heightfield triangle id (when hit)
  double t = 0;                                   // distance along the unit direction, through all wraps
  Vec3<double> point = Vec3<double>::Zero();      // hit point, x and y wrapped into [0, L)
  int segments = 0;                               // Embree calls made
  int edge_grazes = 0;                            // first hits on a facet the ray leaves the solid through,
                                                  // passed over (convex-edge grazes, trace() only; see above)
  bool is_hit() const { return outcome == RayOutcome::hit; }
};

// A heightfield in an Embree scene. Thread-safe for tracing after construction.
class HeightfieldScene {
public:
  explicit HeightfieldScene(const microgeom::Heightfield& field,
                            HeightfieldGeometry geometry = kDefaultHeightfieldGeometry,
                            embree::BuildQuality quality = embree::BuildQuality::high);
  ~HeightfieldScene();
  HeightfieldScene(const HeightfieldScene&) = delete;
  HeightfieldScene& operator=(const HeightfieldScene&) = delete;

  const microgeom::Heightfield& field() const { return field_; }
  HeightfieldGeometry geometry() const { return geometry_; }
  double build_seconds() const { return build_seconds_; }
  // Peak bytes Embree allocated for this scene (its memory monitor; our own buffers are not included;
  // 0 for the pyramid).
  std::int64_t embree_peak_bytes() const { return embree_peak_bytes_.load(); }
  // Bytes of the pyramid tracer's own structure (0 for the Embree geometries).
  std::size_t pyramid_bytes() const { return pyramid_ ? pyramid_->bytes() : 0; }
  // Height of the escape plane: above it, a ray going up can hit nothing.
  double escape_height() const { return escape_height_; }
  // A height from which downward rays start (above escape_height()).
  double start_height() const { return start_height_; }
  // Height of the floor plane: below it, a ray going down can hit nothing.
  double floor_height() const { return floor_height_; }
  // A height from which upward rays inside the solid start (below floor_height(), as far below the
  // minimum height as start_height() is above the maximum).
  double floor_start_height() const { return floor_start_height_; }

  // Closest hit of the ray origin + t dir, t >= 0 (dir: unit; origin: any x, y, wrapped first), for a ray
  // on `side` of the surface. skip_triangle: the heightfield triangle the ray starts on; the origin is
  // then lifted to that side (lifted()) and the triangle skipped in the first segment.
  HeightfieldHit trace(const Vec3<double>& origin, const Vec3<double>& dir,
                       std::optional<std::uint32_t> skip_triangle = std::nullopt,
                       RaySide side = RaySide::outside) const;
  // trace() of the rays origins[i] along dir (no start triangle, outside) into out[i], each result trace()'s
  // to the bit; the pyramid walks them in SIMD lanes (PyramidTracer::trace_batch), the Embree geometries
  // trace them one by one.
  void trace_batch(std::span<const Vec3<double>> origins, const Vec3<double>& dir, std::span<HeightfieldHit> out) const;
  // A ray of trace_rays: trace(point, dir, none, side) without a start facet, else
  // trace_from_surface(point, dir, *start, up, side).
  struct SurfaceRay {
    Vec3<double> point, dir;
    std::optional<std::uint32_t> start;
    Vec3<double> up;
    RaySide side = RaySide::outside;
  };
  // Each ray of `rays` traced into out[i], each result that call's to the bit; the pyramid walks them in
  // SIMD lanes (PyramidTracer::trace_batch), the Embree geometries trace them one by one.
  void trace_rays(std::span<const SurfaceRay> rays, std::span<HeightfieldHit> out) const;
  // A ray leaving the point p of `triangle` (unit upward normal `up`, field().triangle_normal) on `side`
  // (a bounce of a scattering path): trace() from surface_origin() instead of lifted(), the triangle
  // skipped in the first segment.
  HeightfieldHit trace_from_surface(const Vec3<double>& p, const Vec3<double>& dir, std::uint32_t triangle,
                                    const Vec3<double>& up, RaySide side) const;
  // trace_from_surface() (given a skip_triangle) or trace() (without), appending every Embree call it makes
  // to `calls` (benchmarks: the raw rate of the same calls).
  HeightfieldHit trace_recording(const Vec3<double>& origin, const Vec3<double>& dir,
                                 std::optional<std::uint32_t> skip_triangle, RaySide side,
                                 std::vector<EmbreeCall>& calls) const;
  // Whether the ray escapes to the sky (no hit). Uses rtcOccluded1 (any hit); leaked and unresolved rays
  // are returned through `outcome` if non-null (as escaped = visible they would bias; callers count them).
  bool escapes(const Vec3<double>& origin, const Vec3<double>& dir, std::optional<std::uint32_t> skip_triangle,
               RayOutcome* outcome = nullptr) const;
  // escapes()'s outcome of each ray into out[i], that call's to the bit; the pyramid walks them in SIMD lanes
  // (PyramidTracer::trace_batch), the Embree geometries trace them one by one.
  struct ShadowRay {
    Vec3<double> origin, dir;
    std::uint32_t start = 0;  // the triangle the ray leaves (escapes()'s skip_triangle)
  };
  void escape_outcomes(std::span<const ShadowRay> rays, std::span<RayOutcome> out) const;

  // Distance by which surface points are lifted along their facet normal before tracing from them.
  double surface_offset() const { return surface_offset_; }
  // The origin actually traced from p on `triangle` for a ray on `side`: p + surface_offset() * m outside,
  // p - surface_offset() * m inside (m: the triangle's unit upward normal).
  Vec3<double> lifted(const Vec3<double>& p, std::uint32_t triangle, RaySide side = RaySide::outside) const;
  // lifted(), then, if that origin is not at least surface_offset() / 2 on `side` of the surface at its
  // own (x, y), moved vertically to surface_offset() there. Near an edge that is concave seen from `side`
  // (a valley seen from above, a ridge from below), the lift along the start facet's normal can cross the
  // neighbouring facet's plane into the solid (outside) or out of it (inside): a ray from there misses the
  // facet it may immediately meet, and meets the surface from the wrong side later (about 5e-7 of the
  // paths of a rough dielectric, tests/scatter/test_surface_scatter.cpp). The vertical move keeps the origin on
  // its side; inside a facet (the lift's vertical extent is surface_offset() / m_z there) it never acts.
  // `up`: the triangle's unit upward normal (field().triangle_normal).
  Vec3<double> surface_origin(const Vec3<double>& p, std::uint32_t triangle, const Vec3<double>& up,
                              RaySide side) const;

  // The Embree scene (for benchmarks comparing against raw rtcIntersect1 calls). Throws std::logic_error
  // for the pyramid geometry (no Embree scene).
  const embree::Scene& embree_scene() const;

  // The Embree primitive that is the given heightfield triangle in the tile proper (not an overlap copy).
  unsigned int embree_primitive(std::uint32_t triangle) const;

private:
  struct Walk;           // one ray's state along its segments (heightfield_trace.cpp)
  struct SegmentBounds;  // where the current segment ends
  // The scene's construction, step by step.
  void place_planes();
  void create_scene(embree::BuildQuality quality);
  void attach_heightfield_geometry();
  // trace() and escapes(): the segment loop, and its steps. from_surface: `origin` is a surface_origin()
  // already (else a start on skip_triangle is lifted()). kRecord: append the Embree calls to `calls`.
  template <bool kOcclusionOnly, bool kRecord = false>
  HeightfieldHit trace_impl(const Vec3<double>& origin, const Vec3<double>& dir,
                            std::optional<std::uint32_t> skip_triangle, RaySide side, bool from_surface,
                            std::vector<EmbreeCall>* calls = nullptr) const;
  template <bool kOcclusionOnly>
  void start_walk(Walk& w, const Vec3<double>& origin, const Vec3<double>& dir,
                  std::optional<std::uint32_t> skip_triangle, RaySide side, bool from_surface) const;
  SegmentBounds segment_bounds(const Walk& w) const;
  template <bool kOcclusionOnly, bool kRecord>
  bool intersect_segment(Walk& w, int segment, double tfar, HeightfieldHit& out, std::vector<EmbreeCall>* calls) const;
  void record_hit(const Walk& w, const RTCRayHit& rh, HeightfieldHit& out) const;
  void wrap_to_next_tile(Walk& w, const SegmentBounds& s) const;
  std::uint32_t hit_triangle(unsigned int prim_id, float u, float v) const;
  unsigned int extended_primitive(unsigned int prim_id, float u, float v) const;
  static bool on_memory(void* user, ssize_t bytes, bool post);

  const microgeom::Heightfield& field_;
  HeightfieldGeometry geometry_;
  double tile_ = 0, cell_ = 0, inv_cell_ = 0;
  double surface_offset_ = 0;
  double escape_height_ = 0, start_height_ = 0, floor_height_ = 0, floor_start_height_ = 0;
  double build_seconds_ = 0;
  int grid_resolution_ = 0;  // user data of the grid geometry (read by the skip filter)
  std::atomic<std::int64_t> embree_bytes_{0}, embree_peak_bytes_{0};
  std::unique_ptr<embree::Device> device_;
  std::unique_ptr<embree::Scene> scene_;
  std::unique_ptr<PyramidTracer> pyramid_;  // the pyramid geometry's tracer (else null)
};

// ---- double-precision reference (tests) -----------------------------------------------------------------
// 2D grid traversal (DDA) over the cells in unwrapped coordinates; in each cell, the exact intersection
// with both triangle planes in double, kept if it lies in the cell's part of the ray and in the triangle
// (points on the diagonal belong to triangle 0, as in Heightfield::triangle_at). skip_triangle is skipped
// in the start cell only. Slow (one cell at a time); meant for small surfaces in tests.
HeightfieldHit reference_trace(const microgeom::Heightfield& field, const Vec3<double>& origin,
                               const Vec3<double>& dir, std::optional<std::uint32_t> skip_triangle = std::nullopt,
                               long max_cells = 1L << 24);

}  // namespace microsim
