// microsim: periodic heightfield tracing with Embree, and the double-precision reference (see
// heightfield_trace.h for the scheme).
#include "trace/heightfield_trace.h"

#include <fmt/core.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace microsim {

std::string to_string(HeightfieldGeometry g) {
  return g == HeightfieldGeometry::triangles ? "triangles" : (g == HeightfieldGeometry::grid ? "grid" : "pyramid");
}

HeightfieldGeometry heightfield_geometry_from_string(const std::string& s) {
  if (s == "triangles") return HeightfieldGeometry::triangles;
  if (s == "grid") return HeightfieldGeometry::grid;
  if (s == "pyramid") return HeightfieldGeometry::pyramid;
  throw std::invalid_argument(
      fmt::format("unknown heightfield geometry '{}' (expected 'pyramid', 'triangles' or 'grid')", s));
}

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr unsigned int kNoSkip = RTC_INVALID_GEOMETRY_ID;

// The intersect context handed to rtcIntersect1/rtcOccluded1, extended with the primitive to skip.
// Embree passes the context pointer through to the filter, which casts it back (the Embree-documented way
// of giving per-ray data to filter functions); `base` must stay the first member. The filter is a CONTEXT
// filter (RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION), set only on the calls that skip a primitive: plain
// calls on the same scene (benchmarks, tests) never run it, so it never reads past a plain context.
struct SkipContext {
  RTCIntersectContext base;
  unsigned int skip_primitive = kNoSkip;  // the start primitive: extended primitive index (see below) or kNoSkip
  unsigned int skip_grazed = kNoSkip;     // a primitive just passed over at a convex edge (trace_impl)
};

// Extended primitive index e = 2 (b M + a) + t of triangle t of the cell (a, b) of the overlapped grid,
// a, b in [0, M), M = N + 2 (cell a covers x in [(a-1) h, a h]). For the triangle geometry this IS
// Embree's primID; for the grid geometry it is computed from the grid (u, v).
struct ExtendedGrid {
  int n;  // heightfield resolution N
  int cells() const { return n + 2; }
  int vertices() const { return n + 3; }
  unsigned int primitive(int a, int b, int t) const { return unsigned(2 * (std::size_t(b) * cells() + a) + t); }
  // Grid (u, v) in [0, 1]^2 over the whole vertex grid -> extended primitive. The grid's u axis runs
  // along -x (see the header): quad k lies between vertex columns k, k+1, i.e. cell a = M - 1 - k, and
  // the local x fraction is 1 - (u M - k).
  unsigned int grid_primitive(float u, float v) const {
    const int m = cells();
    const double gu = double(u) * m, gv = double(v) * m;
    const int k = std::clamp(int(std::floor(gu)), 0, m - 1);
    const int b = std::clamp(int(std::floor(gv)), 0, m - 1);
    const double local_x = 1.0 - (gu - k), local_y = gv - b;
    return primitive(m - 1 - k, b, local_x >= local_y ? 0 : 1);
  }
};

// Embree context filter (intersect and occluded): rejects hits on the skipped primitive.
void skip_filter(const RTCFilterFunctionNArguments* args) {
  const auto* ctx = reinterpret_cast<const SkipContext*>(args->context);
  if (ctx->skip_primitive == kNoSkip && ctx->skip_grazed == kNoSkip) return;
  // The grid geometry's user data is the heightfield resolution (triangles: null, primID is exact).
  const auto* grid_n = static_cast<const int*>(args->geometryUserPtr);
  for (unsigned int i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    const unsigned int prim = grid_n ? ExtendedGrid{*grid_n}.grid_primitive(RTCHitN_u(args->hit, args->N, i), RTCHitN_v(args->hit, args->N, i))
                                   : RTCHitN_primID(args->hit, args->N, i);
    if (prim == ctx->skip_primitive || prim == ctx->skip_grazed) args->valid[i] = 0;
  }
}

// x mod L into [0, L).
inline double wrap_coordinate(double x, double tile) {
  double r = x - tile * std::floor(x / tile);
  if (!(r < tile)) r = 0.0;  // x / tile rounding can give exactly tile
  if (r < 0.0) r = 0.0;
  return r;
}

// A new buffer of the geometry; on failure the geometry is released and Embree's error (or ours) thrown.
void* new_geometry_buffer(const embree::Device& device, RTCGeometry geom, RTCBufferType type, RTCFormat format,
                          std::size_t stride, std::size_t count, const char* what) {
  void* buffer = rtcSetNewGeometryBuffer(geom, type, 0, format, stride, count);
  if (!buffer) {
    rtcReleaseGeometry(geom);
    device.check(what);
    throw embree::EmbreeError(fmt::format("{} returned no buffer", what));
  }
  return buffer;
}

// Vertex (c, r), c, r in [0, W): the heightfield vertex (c - 1, r - 1), wrapped, at x = (c - 1) h.
// Triangles: stored at c + r W. Grid: row r holds columns c = W - 1 - k at position k (u along -x).
void fill_vertices(float* vb, const microgeom::Heightfield& field, int w, double h, bool is_grid) {
  tbb::parallel_for(0, w, [&](int r) {
    for (int k = 0; k < w; ++k) {
      const int c = is_grid ? w - 1 - k : k;
      float* p = vb + 3 * (std::size_t(r) * w + k);
      p[0] = float((c - 1) * h);
      p[1] = float((r - 1) * h);
      p[2] = field.height(long(c) - 1, long(r) - 1);
    }
  });
}

// The two triangles of every cell of the overlapped grid, at their extended primitive indices.
void fill_triangle_indices(std::uint32_t* ib, const ExtendedGrid& grid) {
  const int w = grid.vertices(), m = grid.cells();
  tbb::parallel_for(0, m, [&](int b) {
    for (int a = 0; a < m; ++a) {
      const std::uint32_t v00 = std::uint32_t(std::size_t(b) * w + a), v10 = v00 + 1, v01 = v00 + std::uint32_t(w),
                          v11 = v01 + 1;
      std::uint32_t* t0p = ib + 3 * std::size_t(grid.primitive(a, b, 0));
      std::uint32_t* t1p = ib + 3 * std::size_t(grid.primitive(a, b, 1));
      t0p[0] = v00, t0p[1] = v10, t0p[2] = v11;  // (i, j), (i+1, j), (i+1, j+1)
      t1p[0] = v00, t1p[1] = v11, t1p[2] = v01;  // (i, j), (i+1, j+1), (i, j+1)
    }
  });
}

}  // namespace

// ---- the Embree scene ------------------------------------------------------------------------------------

bool HeightfieldScene::on_memory(void* user, ssize_t bytes, bool /*post*/) {
  auto* self = static_cast<HeightfieldScene*>(user);
  const std::int64_t now = self->embree_bytes_.fetch_add(bytes) + bytes;
  std::int64_t peak = self->embree_peak_bytes_.load();
  while (now > peak && !self->embree_peak_bytes_.compare_exchange_weak(peak, now)) {
  }
  return true;  // never refuse an allocation
}

HeightfieldScene::HeightfieldScene(const microgeom::Heightfield& field, HeightfieldGeometry geometry,
                                   embree::BuildQuality quality)
    : field_(field), geometry_(geometry) {
  const int n = field.resolution();
  if (n < 2) throw std::invalid_argument("HeightfieldScene: empty heightfield");
  if (geometry == HeightfieldGeometry::grid && n + 3 > 32767) {
    throw std::invalid_argument(fmt::format("HeightfieldScene: resolution {} exceeds Embree's grid limit (32764)", n));
  }
  place_planes();
  const auto t0 = std::chrono::steady_clock::now();
  if (geometry == HeightfieldGeometry::pyramid) {
    pyramid_ = std::make_unique<PyramidTracer>(field, escape_height_, floor_height_);
    build_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return;
  }
  create_scene(quality);
  attach_heightfield_geometry();
  scene_->commit();
  build_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void HeightfieldScene::place_planes() {
  tile_ = field_.tile_size();
  cell_ = field_.cell_size();
  inv_cell_ = 1.0 / cell_;
  // Escape and floor planes: a relative 2^-20 of the height range plus a few float ulps of the largest
  // coordinate beyond the extreme heights (nothing can be hit above the highest vertex).
  const double zmax = field_.max_height(), zmin = field_.min_height();
  const double range = std::max(zmax - zmin, 0.0);
  const double coordinate_scale = std::max({tile_, std::abs(zmax), std::abs(zmin)});
  const double margin = std::ldexp(range, -20) + 8.0 * std::numeric_limits<float>::epsilon() * coordinate_scale;
  surface_offset_ = std::ldexp(coordinate_scale, -20);
  escape_height_ = zmax + margin;
  floor_height_ = zmin - margin;
  start_height_ = zmax + 2.0 * margin + 1e-3 * range;
  floor_start_height_ = zmin - 2.0 * margin - 1e-3 * range;
}

void HeightfieldScene::create_scene(embree::BuildQuality quality) {
  device_ = std::make_unique<embree::Device>();
  rtcSetDeviceMemoryMonitorFunction(device_->handle(), &HeightfieldScene::on_memory, this);
  device_->check("rtcSetDeviceMemoryMonitorFunction");
  scene_ = std::make_unique<embree::Scene>(*device_, quality, /*robust=*/true);
  rtcSetSceneFlags(scene_->handle(), RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
  device_->check("rtcSetSceneFlags");
}

// The overlapped grid of the tile (see the header) as one Embree geometry, triangles or grid.
void HeightfieldScene::attach_heightfield_geometry() {
  const ExtendedGrid grid{field_.resolution()};
  const int w = grid.vertices(), m = grid.cells();
  const bool is_grid = geometry_ == HeightfieldGeometry::grid;
  RTCGeometry geom = rtcNewGeometry(device_->handle(), is_grid ? RTC_GEOMETRY_TYPE_GRID : RTC_GEOMETRY_TYPE_TRIANGLE);
  device_->check("rtcNewGeometry");
  auto* vb = static_cast<float*>(new_geometry_buffer(*device_, geom, RTC_BUFFER_TYPE_VERTEX, RTC_FORMAT_FLOAT3,
                                                     3 * sizeof(float), std::size_t(w) * w,
                                                     "rtcSetNewGeometryBuffer(vertex)"));
  fill_vertices(vb, field_, w, cell_, is_grid);
  if (!is_grid) {
    auto* ib = static_cast<std::uint32_t*>(new_geometry_buffer(*device_, geom, RTC_BUFFER_TYPE_INDEX, RTC_FORMAT_UINT3,
                                                               3 * sizeof(std::uint32_t), 2 * std::size_t(m) * m,
                                                               "rtcSetNewGeometryBuffer(index)"));
    fill_triangle_indices(ib, grid);
    rtcSetGeometryUserData(geom, nullptr);
  } else {
    auto* gb = static_cast<RTCGrid*>(new_geometry_buffer(*device_, geom, RTC_BUFFER_TYPE_GRID, RTC_FORMAT_GRID,
                                                         sizeof(RTCGrid), 1, "rtcSetNewGeometryBuffer(grid)"));
    gb->startVertexID = 0;
    gb->stride = unsigned(w);
    gb->width = static_cast<unsigned short>(w);
    gb->height = static_cast<unsigned short>(w);
    grid_resolution_ = field_.resolution();
    rtcSetGeometryUserData(geom, &grid_resolution_);
  }
  rtcCommitGeometry(geom);
  rtcAttachGeometry(scene_->handle(), geom);
  rtcReleaseGeometry(geom);
  device_->check("rtcCommitGeometry/rtcAttachGeometry(heightfield)");
}

HeightfieldScene::~HeightfieldScene() = default;

const embree::Scene& HeightfieldScene::embree_scene() const {
  if (!scene_) throw std::logic_error("HeightfieldScene: the pyramid geometry has no Embree scene");
  return *scene_;
}

unsigned int HeightfieldScene::embree_primitive(std::uint32_t triangle) const {
  const auto c = field_.triangle_index(triangle);
  return ExtendedGrid{field_.resolution()}.primitive(c.i + 1, c.j + 1, c.t);
}

unsigned int HeightfieldScene::extended_primitive(unsigned int prim_id, float u, float v) const {
  return geometry_ == HeightfieldGeometry::grid ? ExtendedGrid{field_.resolution()}.grid_primitive(u, v) : prim_id;
}

std::uint32_t HeightfieldScene::hit_triangle(unsigned int prim_id, float u, float v) const {
  const ExtendedGrid grid{field_.resolution()};
  const unsigned int e = extended_primitive(prim_id, u, v);
  const int m = grid.cells();
  const unsigned int cell = e >> 1;
  const int a = int(cell % unsigned(m)), b = int(cell / unsigned(m));
  // a, b in [0, N + 2): the heightfield cell a - 1, b - 1 wrapped (without a division).
  const int n = field_.resolution();
  const auto wrap = [n](int k) { return k < 0 ? k + n : (k >= n ? k - n : k); };
  return field_.triangle_id(wrap(a - 1), wrap(b - 1), int(e & 1u));
}

Vec3<double> HeightfieldScene::lifted(const Vec3<double>& p, std::uint32_t triangle, RaySide side) const {
  if (side == RaySide::inside) return p - surface_offset_ * field_.triangle_normal(triangle);
  return p + surface_offset_ * field_.triangle_normal(triangle);
}

Vec3<double> HeightfieldScene::surface_origin(const Vec3<double>& p, std::uint32_t triangle, const Vec3<double>& up,
                                              RaySide side) const {
  Vec3<double> o = side == RaySide::inside ? Vec3<double>(p - surface_offset_ * up) : Vec3<double>(p + surface_offset_ * up);
  // Over its own triangle (the usual case: p not within the lift of an edge) the origin is surface_offset()
  // / m_z >= surface_offset() off the triangle's plane, on its side: nothing to check.
  const auto c = field_.triangle_index(triangle);
  const double u = o.x() * inv_cell_ - c.i, v = o.y() * inv_cell_ - c.j;
  if (c.t == 0 ? (u <= 1.0 && v >= 0.0 && u >= v) : (v <= 1.0 && u >= 0.0 && v >= u)) return o;
  const double h = field_.height_at(o.x(), o.y());
  if (side == RaySide::outside) {
    if (o.z() < h + 0.5 * surface_offset_) o.z() = h + surface_offset_;
  } else if (o.z() > h - 0.5 * surface_offset_) {
    o.z() = h - surface_offset_;
  }
  return o;
}

// ---- the segment loop ------------------------------------------------------------------------------------
// Its steps are always inlined into trace_impl (one function per kind of call, as before the split: the
// per-ray state stays in registers; bench/bench_trace.cpp, BM_HeightfieldPipeline).

// One ray along its segments: the current segment's origin (x, y in the tile), the direction, the start
// primitive to skip in the first segment, whether a wrong-way first hit is a convex-edge graze.
struct HeightfieldScene::Walk {
  Vec3<double> o;
  Vec3<double> dir;
  Vec3<float> df;
  double dx = 0, dy = 0, dz = 0;
  double overlap = kInf;  // half a cell past the tile edge, in ray distance: covered by the overlap strip
  unsigned int skip = kNoSkip;
  RaySide side = RaySide::outside;
  bool pass_grazes = false;
  double travelled = 0;  // ray distance of the segments before this one
  SkipContext ctx;
};

// Where the segment from w.o ends: at the tile edge (tx, ty per axis) plus the overlap, or where it leaves
// the slab [floor, escape] of heights that can hold geometry (t_slab).
struct HeightfieldScene::SegmentBounds {
  double tx = kInf, ty = kInf, t_exit = kInf, t_slab = kInf, tfar = kInf;
};

template <bool kOcclusionOnly>
[[gnu::always_inline]] inline void HeightfieldScene::start_walk(Walk& w, const Vec3<double>& origin_in, const Vec3<double>& dir,
                                  std::optional<std::uint32_t> skip_triangle, RaySide side, bool from_surface) const {
  const Vec3<double> origin = skip_triangle && !from_surface ? lifted(origin_in, *skip_triangle, side) : origin_in;
  if (from_surface) {  // within a lift of the tile: wrapped by a comparison (no division)
    w.o = origin;
    for (int k = 0; k < 2; ++k) {
      if (w.o[k] < 0.0) w.o[k] += tile_;
      else if (w.o[k] >= tile_) w.o[k] -= tile_;
    }
  } else {
    w.o = Vec3<double>(wrap_coordinate(origin.x(), tile_), wrap_coordinate(origin.y(), tile_), origin.z());
  }
  w.dir = dir;
  w.df = dir.cast<float>();
  w.dx = dir.x(), w.dy = dir.y(), w.dz = dir.z();
  // (trace_from_surface: a plain square root; trace() keeps hypot, whose last bits its outputs depend on)
  const double dxy = from_surface ? std::sqrt(w.dx * w.dx + w.dy * w.dy) : std::hypot(w.dx, w.dy);
  w.overlap = dxy > 0 ? 0.5 * cell_ / dxy : kInf;
  w.skip = skip_triangle ? embree_primitive(*skip_triangle) : kNoSkip;
  w.side = side;
  // Whether the ray provably starts on its side (outside: above the surface at its (x, y), a point lifted
  // off its start facet or a primary ray from above; inside: below it): only then is a wrong-way first hit
  // a convex-edge graze to pass over. A ray started on the other side (tests, negative controls) reports
  // what it hits.
  // A surface_origin() is on its side by construction (by surface_offset() / 2 at least).
  if constexpr (!kOcclusionOnly) {
    const Vec3<double>& o = w.o;
    if (from_surface && skip_triangle) w.pass_grazes = true;
    else if (side == RaySide::outside) w.pass_grazes = o.z() > escape_height_ || o.z() > field_.height_at(o.x(), o.y());
    else w.pass_grazes = o.z() < floor_height_ || o.z() < field_.height_at(o.x(), o.y());
  }
  rtcInitIntersectContext(&w.ctx.base);
}

[[gnu::always_inline]] inline HeightfieldScene::SegmentBounds HeightfieldScene::segment_bounds(const Walk& w) const {
  SegmentBounds s;
  if (w.dx > 0) s.tx = (tile_ - w.o.x()) / w.dx;
  else if (w.dx < 0) s.tx = -w.o.x() / w.dx;
  if (w.dy > 0) s.ty = (tile_ - w.o.y()) / w.dy;
  else if (w.dy < 0) s.ty = -w.o.y() / w.dy;
  s.tx = std::max(s.tx, 0.0);
  s.ty = std::max(s.ty, 0.0);
  s.t_exit = std::min(s.tx, s.ty);
  if (w.dz > 0) s.t_slab = (escape_height_ - w.o.z()) / w.dz;
  else if (w.dz < 0) s.t_slab = (floor_height_ - w.o.z()) / w.dz;
  s.tfar = std::min(s.t_exit + w.overlap, s.t_slab);
  return s;
}

namespace {

// Whether Embree's hit crosses the surface the wrong way for a ray on `side`: outside, a first hit must
// ENTER the solid; inside, it must LEAVE it. Embree's geometric normal Ng is +-m (its sign depends on the
// winding); every facet of a heightfield has m_z > 0, so m ~ Ng sign(Ng_z) (no lookup of the facet's
// heights). Leaving: dir . m >= 0; entering: dir . m <= 0.
inline bool crosses_wrong_way(const RTCHit& hit, const Vec3<float>& df, RaySide side) {
  const float ng_dot_dir = hit.Ng_x * df.x() + hit.Ng_y * df.y() + hit.Ng_z * df.z();
  if (side == RaySide::outside) return hit.Ng_z > 0.0f ? ng_dot_dir >= 0.0f : (hit.Ng_z < 0.0f && ng_dot_dir <= 0.0f);
  return hit.Ng_z > 0.0f ? ng_dot_dir <= 0.0f : (hit.Ng_z < 0.0f && ng_dot_dir >= 0.0f);
}

inline RTCRayHit segment_ray(const Vec3<double>& o, const Vec3<float>& df, float tnear, double tfar) {
  RTCRayHit rh;
  rh.ray.org_x = float(o.x());
  rh.ray.org_y = float(o.y());
  rh.ray.org_z = float(o.z());
  rh.ray.dir_x = df.x();
  rh.ray.dir_y = df.y();
  rh.ray.dir_z = df.z();
  rh.ray.tnear = tnear;
  rh.ray.tfar = std::isfinite(tfar) ? float(tfar) : std::numeric_limits<float>::infinity();
  rh.ray.time = 0.0f;
  rh.ray.mask = 0xffffffffu;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  return rh;
}

}  // namespace

// One Embree call for the segment, plus one per convex-edge graze passed over. Returns whether the ray
// stops here (a hit; `out` filled).
template <bool kOcclusionOnly, bool kRecord>
[[gnu::always_inline]] inline bool HeightfieldScene::intersect_segment(Walk& w, int segment, double tfar, HeightfieldHit& out,
                                         std::vector<EmbreeCall>* calls) const {
  float tnear = 0.0f;
  unsigned int grazed = kNoSkip;
  // Closest-hit calls skip the start primitive lazily: first without the filter (an Embree callback on
  // every candidate hit); only a closest hit ON the start primitive is traced again with it, which finds
  // what the filtered call alone finds (the closest of the other candidates). Occlusion calls filter.
  bool lazy_skip = !kOcclusionOnly;
  for (;;) {
    w.ctx.skip_primitive = segment == 0 ? w.skip : kNoSkip;
    w.ctx.skip_grazed = grazed;
    const bool filter = (w.ctx.skip_primitive != kNoSkip && !lazy_skip) || grazed != kNoSkip;
    w.ctx.base.filter = filter ? &skip_filter : nullptr;
    RTCRayHit rh = segment_ray(w.o, w.df, tnear, tfar);
    ++out.segments;
    if constexpr (kRecord) {
      calls->push_back({Vec3<float>(rh.ray.org_x, rh.ray.org_y, rh.ray.org_z), w.df, rh.ray.tnear, rh.ray.tfar});
    }
    if constexpr (kOcclusionOnly) {
      rtcOccluded1(scene_->handle(), &w.ctx.base, &rh.ray);
      if (rh.ray.tfar != -std::numeric_limits<float>::infinity()) return false;
      out.outcome = RayOutcome::hit;
      return true;
    } else {
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(scene_->handle(), &w.ctx.base, &rh);
      if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
      if (lazy_skip && !filter && w.ctx.skip_primitive != kNoSkip &&
          extended_primitive(rh.hit.primID, rh.hit.u, rh.hit.v) == w.ctx.skip_primitive) {
        lazy_skip = false;  // the start primitive itself: again, filtered
        continue;
      }
      // A first hit the wrong way means that in float the ray passed within about one ulp of a convex
      // edge, over the facet it nearly runs along, and Embree's float t of that nearly parallel facet
      // ordered the two the wrong way round (docs/records/heightfield-trade.md, section 1). The ray is taken to
      // pass over the edge: it continues from the hit, skipping that facet.
      if (w.pass_grazes && crosses_wrong_way(rh.hit, w.df, w.side) && out.edge_grazes < kMaxEdgeGrazes) {
        ++out.edge_grazes;
        tnear = rh.ray.tfar;
        grazed = extended_primitive(rh.hit.primID, rh.hit.u, rh.hit.v);
        continue;
      }
      record_hit(w, rh, out);
      return true;
    }
  }
}

[[gnu::always_inline]] inline void HeightfieldScene::record_hit(const Walk& w, const RTCRayHit& rh,
                                                                HeightfieldHit& out) const {
  const double t = rh.ray.tfar;
  out.outcome = RayOutcome::hit;
  out.t = w.travelled + t;
  out.triangle = hit_triangle(rh.hit.primID, rh.hit.u, rh.hit.v);
  const Vec3<double> p = w.o + t * w.dir;
  out.point = Vec3<double>(wrap_coordinate(p.x(), tile_), wrap_coordinate(p.y(), tile_), p.z());
}

// Wrap: move to the exit point and re-enter from the opposite side (exact 0 or L on the exit axes).
[[gnu::always_inline]] inline void HeightfieldScene::wrap_to_next_tile(Walk& w, const SegmentBounds& s) const {
  w.o += s.t_exit * w.dir;
  w.travelled += s.t_exit;
  if (s.tx <= s.ty) w.o.x() = w.dx > 0 ? 0.0 : tile_;
  if (s.ty <= s.tx) w.o.y() = w.dy > 0 ? 0.0 : tile_;
}

template <bool kOcclusionOnly, bool kRecord>
[[gnu::always_inline]] inline HeightfieldHit HeightfieldScene::trace_impl(const Vec3<double>& origin, const Vec3<double>& dir,
                                            std::optional<std::uint32_t> skip_triangle, RaySide side,
                                            bool from_surface, std::vector<EmbreeCall>* calls) const {
  HeightfieldHit out;
  Walk w;
  start_walk<kOcclusionOnly>(w, origin, dir, skip_triangle, side, from_surface);
  for (int segment = 0; segment < kMaxSegments; ++segment) {
    if (w.dz >= 0 && w.o.z() > escape_height_) {
      out.outcome = RayOutcome::escaped;
      return out;
    }
    if (w.dz <= 0 && w.o.z() < floor_height_) {
      out.outcome = RayOutcome::leaked;
      return out;
    }
    const SegmentBounds s = segment_bounds(w);
    if (intersect_segment<kOcclusionOnly, kRecord>(w, segment, s.tfar, out, calls)) return out;
    if (s.t_slab <= s.t_exit) {  // left the slab before the tile edge: nothing more to hit
      out.outcome = w.dz > 0 ? RayOutcome::escaped : RayOutcome::leaked;
      return out;
    }
    wrap_to_next_tile(w, s);
  }
  out.outcome = RayOutcome::unresolved;
  return out;
}

HeightfieldHit HeightfieldScene::trace(const Vec3<double>& origin, const Vec3<double>& dir,
                                       std::optional<std::uint32_t> skip_triangle, RaySide side) const {
  if (pyramid_) return pyramid_->trace(skip_triangle ? lifted(origin, *skip_triangle, side) : origin, dir, skip_triangle);
  return trace_impl<false>(origin, dir, skip_triangle, side, false);
}

void HeightfieldScene::trace_batch(std::span<const Vec3<double>> origins, const Vec3<double>& dir,
                                   std::span<HeightfieldHit> out) const {
  if (pyramid_) return pyramid_->trace_batch(origins, dir, out);
  for (std::size_t i = 0; i < origins.size(); ++i) out[i] = trace(origins[i], dir);
}

void HeightfieldScene::trace_rays(std::span<const SurfaceRay> rays, std::span<HeightfieldHit> out) const {
  if (!pyramid_) {
    for (std::size_t i = 0; i < rays.size(); ++i) {
      const SurfaceRay& r = rays[i];
      out[i] = r.start ? trace_from_surface(r.point, r.dir, *r.start, r.up, r.side) : trace(r.point, r.dir, std::nullopt, r.side);
    }
    return;
  }
  // The origins as trace() and trace_from_surface() hand them to the pyramid.
  std::vector<PyramidTracer::Ray> walk(rays.size());
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const SurfaceRay& r = rays[i];
    walk[i] = {r.start ? surface_origin(r.point, *r.start, r.up, r.side) : r.point, r.dir, r.start};
  }
  pyramid_->trace_batch(walk, out);
}

HeightfieldHit HeightfieldScene::trace_from_surface(const Vec3<double>& p, const Vec3<double>& dir,
                                                    std::uint32_t triangle, const Vec3<double>& up, RaySide side) const {
  if (pyramid_) return pyramid_->trace(surface_origin(p, triangle, up, side), dir, triangle);
  return trace_impl<false>(surface_origin(p, triangle, up, side), dir, triangle, side, true);
}

HeightfieldHit HeightfieldScene::trace_recording(const Vec3<double>& origin, const Vec3<double>& dir,
                                                 std::optional<std::uint32_t> skip_triangle, RaySide side,
                                                 std::vector<EmbreeCall>& calls) const {
  if (pyramid_) throw std::logic_error("HeightfieldScene::trace_recording: the pyramid geometry makes no Embree calls");
  if (!skip_triangle) return trace_impl<false, true>(origin, dir, std::nullopt, side, false, &calls);
  const Vec3<double> o = surface_origin(origin, *skip_triangle, field_.triangle_normal(*skip_triangle), side);
  return trace_impl<false, true>(o, dir, skip_triangle, side, true, &calls);
}

bool HeightfieldScene::escapes(const Vec3<double>& origin, const Vec3<double>& dir,
                               std::optional<std::uint32_t> skip_triangle, RayOutcome* outcome) const {
  const HeightfieldHit h = pyramid_ ? trace(origin, dir, skip_triangle)
                                    : trace_impl<true>(origin, dir, skip_triangle, RaySide::outside, false);
  if (outcome) *outcome = h.outcome;
  return h.outcome == RayOutcome::escaped;
}

void HeightfieldScene::escape_outcomes(std::span<const ShadowRay> rays, std::span<RayOutcome> out) const {
  if (!pyramid_) {
    for (std::size_t i = 0; i < rays.size(); ++i) escapes(rays[i].origin, rays[i].dir, rays[i].start, &out[i]);
    return;
  }
  std::vector<PyramidTracer::Ray> walk(rays.size());  // the origins as trace() hands them to the pyramid
  for (std::size_t i = 0; i < rays.size(); ++i)
    walk[i] = {lifted(rays[i].origin, rays[i].start, RaySide::outside), rays[i].dir, rays[i].start};
  std::vector<HeightfieldHit> hits(rays.size());
  pyramid_->trace_batch(walk, hits);
  for (std::size_t i = 0; i < rays.size(); ++i) out[i] = hits[i].outcome;
}

// ---- reference tracer (double) ---------------------------------------------------------------------------

namespace {

// The 2D grid traversal (DDA) of the reference tracer, in unwrapped cell coordinates: the current cell,
// and the ray distances to its next x and y edges.
struct CellWalk {
  long ci = 0, cj = 0, ci0 = 0, cj0 = 0;  // current cell, start cell
  int stepx = 0, stepy = 0;
  double tnx = kInf, tny = kInf, dtx = kInf, dty = kInf;

  CellWalk(double h, const Vec3<double>& origin, const Vec3<double>& dir) {
    const double ox = origin.x(), oy = origin.y(), dx = dir.x(), dy = dir.y();
    ci = ci0 = long(std::floor(ox / h));
    cj = cj0 = long(std::floor(oy / h));
    stepx = dx > 0 ? 1 : (dx < 0 ? -1 : 0);
    stepy = dy > 0 ? 1 : (dy < 0 ? -1 : 0);
    tnx = dx > 0 ? ((ci + 1) * h - ox) / dx : (dx < 0 ? (ci * h - ox) / dx : kInf);
    tny = dy > 0 ? ((cj + 1) * h - oy) / dy : (dy < 0 ? (cj * h - oy) / dy : kInf);
    dtx = dx != 0 ? h / std::abs(dx) : kInf;
    dty = dy != 0 ? h / std::abs(dy) : kInf;
  }
  double t_out() const { return std::min(tnx, tny); }
  void step() {
    if (tnx < tny) {
      ci += stepx;
      tnx += dtx;
    } else if (tny < tnx) {
      cj += stepy;
      tny += dty;
    } else {
      ci += stepx;
      cj += stepy;
      tnx += dtx;
      tny += dty;
    }
  }
};

struct CellHit {
  double t = kInf;
  int triangle = -1;  // 0 or 1 within the cell; -1: none
};

// The closest intersection in [t_in, t_out] with the two triangles of the walk's current cell, exactly in
// double; `skip` is skipped in (and next to) the start cell only.
CellHit intersect_cell(const microgeom::Heightfield& field, const Vec3<double>& origin, const Vec3<double>& dir,
                       const CellWalk& walk, double t_in, double t_out,
                       const std::optional<microgeom::Heightfield::TriangleIndex>& skip) {
  const double h = field.cell_size();
  const double ox = origin.x(), oy = origin.y(), oz = origin.z();
  const double dx = dir.x(), dy = dir.y(), dz = dir.z();
  const long ci = walk.ci, cj = walk.cj;
  const double x0 = ci * h, y0 = cj * h;
  const double h00 = field.height(ci, cj), h10 = field.height(ci + 1, cj), h01 = field.height(ci, cj + 1),
               h11 = field.height(ci + 1, cj + 1);
  const int wi = field.wrap(ci), wj = field.wrap(cj);
  CellHit best;
  for (int t = 0; t < 2; ++t) {
    if (skip && skip->i == wi && skip->j == wj && skip->t == t && std::abs(ci - walk.ci0) <= 1 &&
        std::abs(cj - walk.cj0) <= 1) {
      continue;
    }
    // Plane through vertex (i, j): z = h00 + sx (x - x0) + sy (y - y0) (Heightfield's slopes).
    const double sx = t == 0 ? (h10 - h00) / h : (h11 - h01) / h;
    const double sy = t == 0 ? (h11 - h10) / h : (h01 - h00) / h;
    const double a = oz - h00 - sx * (ox - x0) - sy * (oy - y0);
    const double b = dz - sx * dx - sy * dy;
    if (b == 0) continue;  // parallel to the plane (a coplanar ray grazes it: not a hit)
    const double tt = -a / b;
    if (!(tt >= t_in && tt <= t_out)) continue;
    const double u = (ox + tt * dx - x0) / h, v = (oy + tt * dy - y0) / h;
    // Membership with a 1e-12 slack so that a point on the diagonal is never rejected by both
    // triangles through round-off; ties go to triangle 0 (below, by the strict < on best.t).
    constexpr double kSlack = 1e-12;
    const bool inside = t == 0 ? (u >= v - kSlack) : (v > u - kSlack);
    if (inside && tt < best.t) best = {tt, t};
  }
  return best;
}

}  // namespace

HeightfieldHit reference_trace(const microgeom::Heightfield& field, const Vec3<double>& origin,
                               const Vec3<double>& dir, std::optional<std::uint32_t> skip_triangle,
                               long max_cells) {
  HeightfieldHit out;
  const double tile = field.tile_size();
  const double zmax = field.max_height(), zmin = field.min_height();
  CellWalk walk(field.cell_size(), origin, dir);
  std::optional<microgeom::Heightfield::TriangleIndex> skip;
  if (skip_triangle) skip = field.triangle_index(*skip_triangle);
  double t_in = 0;
  for (long visited = 0; visited < max_cells; ++visited) {
    const double z_in = origin.z() + t_in * dir.z();
    if (dir.z() >= 0 && z_in > zmax) {
      out.outcome = RayOutcome::escaped;
      return out;
    }
    if (dir.z() <= 0 && z_in < zmin) {
      out.outcome = RayOutcome::leaked;
      return out;
    }
    const double t_out = walk.t_out();
    const CellHit best = intersect_cell(field, origin, dir, walk, t_in, t_out, skip);
    if (best.triangle >= 0) {
      out.outcome = RayOutcome::hit;
      out.t = best.t;
      out.triangle = field.triangle_id(field.wrap(walk.ci), field.wrap(walk.cj), best.triangle);
      const Vec3<double> p = origin + best.t * dir;
      out.point = Vec3<double>(wrap_coordinate(p.x(), tile), wrap_coordinate(p.y(), tile), p.z());
      out.segments = int(std::min<long>(visited + 1, std::numeric_limits<int>::max()));
      return out;
    }
    if (!std::isfinite(t_out)) {  // vertical ray: it only ever sees this cell
      out.outcome = dir.z() > 0 ? RayOutcome::escaped : RayOutcome::leaked;
      return out;
    }
    t_in = t_out;
    walk.step();
  }
  out.outcome = RayOutcome::unresolved;
  return out;
}

}  // namespace microsim
