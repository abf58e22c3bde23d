// The options for tracing a periodic heightfield, measured on the same rays in one run: first hits of the
// `trace vndf --surface` primary rays (origins drawn as trace_vndf_heightfield draws them, seed 1, blocks
// of kRaysPerBlock rays; view theta 45, phi 30) on `smith` surfaces of alpha 0.3 (seed 1), 1 thread,
// process CPU time per ray (robust to the load of other processes on a shared machine).
//
// Raw Embree (the Embree calls alone: every segment HeightfieldScene::trace makes for the ray, each a
// plain rtcIntersect1 of the overlapped tile, recorded once before timing from the triangle scene):
//   raw_high          HeightfieldScene's triangles: RTC_BUILD_QUALITY_HIGH, robust (bench_trace's raw baseline)
//   raw_high_morton   the same, the rays of each block in Morton order of their origins
//   raw_medium, raw_low   RTC_BUILD_QUALITY_MEDIUM / LOW
//   raw_compact       high quality with RTC_SCENE_FLAG_COMPACT
//   raw_grid          RTC_GEOMETRY_TYPE_GRID (HeightfieldScene's grid geometry)
// The whole tracer (HeightfieldScene::trace: the segment loop, the lift and skip rules, the convex-edge
// pass-over; or the pyramid's walk):
//   trace_triangles, trace_grid    Embree
//   trace_pyramid                  the min-max pyramid walk (trace/heightfield_pyramid.h)
//   trace_pyramid_morton           the same, Morton order
//   trace_pyramid_lanes            the same rays, each block's traced by PyramidTracer::trace_batch (walks
//                                  in SIMD lanes, every ray's result trace()'s to the bit), 64 lanes;
//                                  _L: with L lanes; _pf / _npf: with / without software prefetch
// After the benchmarks: one table, ns/ray per option per resolution, and each option's rate against raw_high;
// also how many of the rays the pyramid and Embree's triangles hit on a different triangle.
//
// Run: build/bench_tracers --res=256,1024,4096 --benchmark_repetitions=3
// (resolutions: default 256,1024; from 4096 on only the high-quality triangles, whose BVH is 4.6 GB there,
// and the pyramid).
#include "microgeom/assembly.h"
#include "core/cpu_time.h"
#include "core/random.h"
#include "trace/heightfield_pyramid_lanes.h"
#include "trace/heightfield_trace.h"
#include "trace/trace_vndf.h"

#include "bench_util.h"

#include <benchmark/benchmark.h>
#include <embree3/rtcore.h>
#include <fmt/core.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <memory>
#include <numeric>
#include <span>
#include <string>
#include <vector>

using namespace microsim;
using microsim::bench::median;

namespace {

constexpr double kTheta = 45.0, kPhi = 30.0, kAlpha = 0.3;
constexpr std::uint64_t kRays = 1 << 18;
constexpr double kInfinity = std::numeric_limits<double>::infinity();
std::vector<int> g_resolutions = {256, 1024};
constexpr int kLargest = 4096;  // from this resolution on, only raw_high*, trace_triangles and trace_pyramid*

const char* const kOptions[] = {"raw_high",        "raw_high_morton", "raw_medium",    "raw_low",
                                "raw_compact",     "raw_grid",        "trace_triangles", "trace_grid",
                                "trace_pyramid",   "trace_pyramid_morton", "trace_pyramid_lanes",
                                "trace_pyramid_lanes_8", "trace_pyramid_lanes_16", "trace_pyramid_lanes_32",
                                "trace_pyramid_lanes_pf", "trace_pyramid_lanes_npf"};
constexpr int kOptionCount = int(sizeof(kOptions) / sizeof(kOptions[0]));

struct Segment {
  Vec3<float> origin;
  float tfar;
  std::uint32_t ray;  // index of its ray
};

// A raw Embree scene of the overlapped tile (as HeightfieldScene's triangles: vertices -1 .. N+1, two
// triangles per cell), with the given build quality and scene flags.
struct RawScene {
  embree::Device device;
  RTCScene scene = nullptr;
  RawScene(const microgeom::Heightfield& f, RTCBuildQuality quality, RTCSceneFlags flags) {
    const int n = f.resolution(), w = n + 3, m = n + 2;
    const double h = f.cell_size();
    scene = rtcNewScene(device.handle());
    rtcSetSceneFlags(scene, flags);
    rtcSetSceneBuildQuality(scene, quality);
    RTCGeometry g = rtcNewGeometry(device.handle(), RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(g, quality);
    auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                           3 * sizeof(float), std::size_t(w) * w));
    auto* ib = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                   3 * sizeof(std::uint32_t), 2 * std::size_t(m) * m));
    for (int r = 0; r < w; ++r)
      for (int c = 0; c < w; ++c) {
        float* p = vb + 3 * (std::size_t(r) * w + c);
        p[0] = float((c - 1) * h), p[1] = float((r - 1) * h), p[2] = f.height(long(c) - 1, long(r) - 1);
      }
    for (int b = 0; b < m; ++b)
      for (int a = 0; a < m; ++a) {
        const std::uint32_t v00 = std::uint32_t(b * w + a), v10 = v00 + 1, v01 = v00 + std::uint32_t(w), v11 = v01 + 1;
        std::uint32_t* t = ib + 6 * (std::size_t(b) * m + a);
        t[0] = v00, t[1] = v10, t[2] = v11, t[3] = v00, t[4] = v11, t[5] = v01;
      }
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(scene);
    device.check("RawScene");
  }
  ~RawScene() { rtcReleaseScene(scene); }
};

struct Fixture {
  std::unique_ptr<microgeom::Heightfield> field;
  std::map<HeightfieldGeometry, std::unique_ptr<HeightfieldScene>> scenes;
  std::map<std::string, std::unique_ptr<RawScene>> raw;
  std::vector<Vec3<double>> origins;          // the rays (all of direction dir)
  std::vector<std::uint32_t> morton;          // the rays in Morton order within each block
  std::vector<Segment> segments, segments_morton;
  Vec3<double> dir;
  std::uint64_t differing = 0;  // rays whose pyramid hit differs from the triangles' (triangle or outcome)
  std::uint64_t lanes_differing = 0;  // rays whose trace_batch result differs from trace()'s (any bit)
  std::unique_ptr<PyramidTracer> pyramid;  // as the pyramid scene's, for trace_batch with a lane count
};

std::uint64_t morton_code(double x, double y, double tile) {
  const auto q = [&](double v) { return std::uint64_t(std::min(65535.0, std::max(0.0, v / tile * 65536.0))); };
  std::uint64_t code = 0, a = q(x), b = q(y);
  for (int bit = 0; bit < 16; ++bit) code |= ((a >> bit) & 1u) << (2 * bit) | ((b >> bit) & 1u) << (2 * bit + 1);
  return code;
}

// The segments of a primary ray from above as HeightfieldScene::trace makes them (bench_trace.cpp).
void append_segments(RTCScene scene, const microgeom::Heightfield& field, Vec3<double> o, const Vec3<double>& dir,
                     std::uint32_t ray, std::vector<Segment>& out) {
  const double tile = field.tile_size(), overlap = 0.5 * field.cell_size() / std::hypot(dir.x(), dir.y());
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  for (int segment = 0; segment < 1000; ++segment) {
    const double tx = dir.x() > 0 ? (tile - o.x()) / dir.x() : (dir.x() < 0 ? -o.x() / dir.x() : kInfinity);
    const double ty = dir.y() > 0 ? (tile - o.y()) / dir.y() : (dir.y() < 0 ? -o.y() / dir.y() : kInfinity);
    const double t_exit = std::min(std::max(tx, 0.0), std::max(ty, 0.0));
    out.push_back({o.cast<float>(), float(t_exit + overlap), ray});
    RTCRayHit rh = embree::make_ray_hit(out.back().origin, dir.cast<float>(), 0.0f, out.back().tfar);
    rtcIntersect1(scene, &context, &rh);
    if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) return;
    o += t_exit * dir;
    if (tx <= ty) o.x() = dir.x() > 0 ? 0.0 : tile;
    if (ty <= tx) o.y() = dir.y() > 0 ? 0.0 : tile;
  }
}

void make_rays(Fixture& f) {
  const HeightfieldScene& tri = *f.scenes.at(HeightfieldGeometry::triangles);
  const double tile = f.field->tile_size(), z0 = tri.start_height();
  for (std::uint64_t block = 0; block * kRaysPerBlock < kRays; ++block) {
    CounterRng rng(1, block);  // trace_vndf_heightfield's origins for seed 1
    const std::size_t first = f.origins.size();
    for (std::uint64_t i = block * kRaysPerBlock; i < std::min(kRays, (block + 1) * kRaysPerBlock); ++i) {
      const double x = tile * rng.uniform(), y = tile * rng.uniform();
      f.origins.emplace_back(x, y, z0);
    }
    std::vector<std::uint32_t> order(f.origins.size() - first);
    std::iota(order.begin(), order.end(), std::uint32_t(first));
    std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
      return morton_code(f.origins[a].x(), f.origins[a].y(), tile) < morton_code(f.origins[b].x(), f.origins[b].y(), tile);
    });
    f.morton.insert(f.morton.end(), order.begin(), order.end());
  }
  embree::FlushDenormalsScope ftz;
  const RTCScene scene = tri.embree_scene().handle();
  for (std::uint32_t i = 0; i < f.origins.size(); ++i) append_segments(scene, *f.field, f.origins[i], f.dir, i, f.segments);
  for (std::uint32_t i : f.morton) append_segments(scene, *f.field, f.origins[i], f.dir, i, f.segments_morton);
}

Fixture& fixture(int res) {
  static std::map<int, Fixture> fixtures;
  Fixture& f = fixtures[res];
  if (f.field) return f;
  microgeom::AssemblyParams p;
  p.assembly = "smith";
  p.alpha_x = p.alpha_y = kAlpha;
  p.resolution = res;
  p.seed = 1;
  f.field = std::make_unique<microgeom::Heightfield>(microgeom::build_assembly(p));
  f.dir = -direction_from_degrees(kTheta, kPhi);
  for (auto g : {HeightfieldGeometry::triangles, HeightfieldGeometry::grid, HeightfieldGeometry::pyramid})
    if (res < kLargest || g != HeightfieldGeometry::grid) f.scenes[g] = std::make_unique<HeightfieldScene>(*f.field, g);
  if (res < kLargest) {
      f.raw["raw_medium"] = std::make_unique<RawScene>(*f.field, RTC_BUILD_QUALITY_MEDIUM, RTC_SCENE_FLAG_ROBUST);
    f.raw["raw_low"] = std::make_unique<RawScene>(*f.field, RTC_BUILD_QUALITY_LOW, RTC_SCENE_FLAG_ROBUST);
    f.raw["raw_compact"] = std::make_unique<RawScene>(*f.field, RTC_BUILD_QUALITY_HIGH,
                                                      RTCSceneFlags(RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_COMPACT));
  }
  make_rays(f);
  const HeightfieldScene& ps = *f.scenes[HeightfieldGeometry::pyramid];
  f.pyramid = std::make_unique<PyramidTracer>(*f.field, ps.escape_height(), ps.floor_height());
  std::vector<HeightfieldHit> batch(f.origins.size());
  f.pyramid->trace_batch(f.origins, f.dir, batch);
  for (std::size_t i = 0; i < f.origins.size(); ++i) {
    const HeightfieldHit a = f.pyramid->trace(f.origins[i], f.dir, std::nullopt), &b = batch[i];
    f.lanes_differing += a.outcome != b.outcome || a.triangle != b.triangle || a.segments != b.segments ||
                         std::memcmp(&a.t, &b.t, sizeof(double)) != 0;
  }
  for (std::size_t i = 0; i < f.origins.size(); ++i) {
    embree::FlushDenormalsScope ftz;
    const HeightfieldHit a = f.scenes[HeightfieldGeometry::triangles]->trace(f.origins[i], f.dir);
    const HeightfieldHit b = f.scenes[HeightfieldGeometry::pyramid]->trace(f.origins[i], f.dir);
    f.differing += a.outcome != b.outcome || (a.is_hit() && a.triangle != b.triangle);
  }
  return f;
}

std::uint64_t replay(RTCScene scene, const std::vector<Segment>& segments, const Vec3<float>& dir) {
  embree::FlushDenormalsScope ftz;
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  std::uint64_t hits = 0;
  for (const Segment& s : segments) {
    RTCRayHit rh = embree::make_ray_hit(s.origin, dir, 0.0f, s.tfar);
    rtcIntersect1(scene, &context, &rh);
    hits += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
  }
  return hits;
}

std::uint64_t trace_all(const HeightfieldScene& scene, const Fixture& f, bool morton) {
  embree::FlushDenormalsScope ftz;
  std::uint64_t hits = 0;
  for (std::size_t k = 0; k < f.origins.size(); ++k) {
    const std::size_t i = morton ? f.morton[k] : k;
    hits += scene.trace(f.origins[i], f.dir).is_hit();
  }
  return hits;
}

std::uint64_t trace_lanes(PyramidTracer& tracer, const Fixture& f, int lanes, int prefetch = -1) {
  embree::FlushDenormalsScope ftz;
  tracer.set_batch_lanes(lanes);
  tracer.set_batch_prefetch(prefetch < 0 ? f.field->resolution() >= PyramidTracer::kPrefetchResolution : prefetch > 0);
  std::vector<HeightfieldHit> out(kRaysPerBlock);
  std::uint64_t hits = 0;
  for (std::size_t first = 0; first < f.origins.size(); first += kRaysPerBlock) {
    const std::size_t n = std::min<std::size_t>(kRaysPerBlock, f.origins.size() - first);
    tracer.trace_batch(std::span<const Vec3<double>>(f.origins.data() + first, n), f.dir,
                       std::span<HeightfieldHit>(out.data(), n));
    for (std::size_t i = 0; i < n; ++i) hits += out[i].is_hit();
  }
  return hits;
}

std::uint64_t run_option(Fixture& f, const std::string& option) {
  const Vec3<float> d = f.dir.cast<float>();
  const RTCScene triangles = f.scenes.at(HeightfieldGeometry::triangles)->embree_scene().handle();
  if (option == "raw_high") return replay(triangles, f.segments, d);
  if (option == "raw_high_morton") return replay(triangles, f.segments_morton, d);
  if (option == "raw_grid") return replay(f.scenes.at(HeightfieldGeometry::grid)->embree_scene().handle(), f.segments, d);
  if (option.rfind("raw_", 0) == 0) return replay(f.raw.at(option)->scene, f.segments, d);
  if (option == "trace_triangles") return trace_all(*f.scenes.at(HeightfieldGeometry::triangles), f, false);
  if (option == "trace_grid") return trace_all(*f.scenes.at(HeightfieldGeometry::grid), f, false);
  if (option == "trace_pyramid_lanes_pf" || option == "trace_pyramid_lanes_npf")
    return trace_lanes(*f.pyramid, f, 0, option == "trace_pyramid_lanes_pf");
  if (option.rfind("trace_pyramid_lanes", 0) == 0)
    return trace_lanes(*f.pyramid, f, option.size() > 20 ? std::atoi(option.c_str() + 20) : 0);
  return trace_all(*f.scenes.at(HeightfieldGeometry::pyramid), f, option == "trace_pyramid_morton");
}

void BM_Tracer(benchmark::State& state, int res, std::string option) {
  Fixture& f = fixture(res);
  std::uint64_t hits = 0;
  const double cpu0 = process_cpu_seconds();
  for (auto _ : state) {
    hits = run_option(f, option);
    benchmark::DoNotOptimize(hits);
  }
  state.counters["cpu_ns_per_ray"] = 1e9 * (process_cpu_seconds() - cpu0) / (double(state.iterations()) * double(kRays));
  state.SetItemsProcessed(std::int64_t(state.iterations()) * std::int64_t(kRays));
  state.counters["segments_per_ray"] = double(f.segments.size()) / double(kRays);
  state.counters["pyramid_differs"] = double(f.differing);
  state.counters["lanes_differ"] = double(f.lanes_differing);
}

std::string name(int res, const std::string& option) { return fmt::format("BM_Tracer/{}/{}", res, option); }

class TableReporter : public bench::RepetitionReporter {
public:
  void PrintRatios() const {
    fmt::print("\nfirst hits of the same {} rays per resolution (theta {}, phi {}, smith alpha {}), 1 thread, median "
               "CPU ns/ray (x = raw_high / option); lanes: {} doubles per vector ({}):\n| option |", kRays, kTheta, kPhi,
               kAlpha, pyramid_lanes::vector_lanes(), pyramid_lanes::target_name());
    for (int res : g_resolutions) fmt::print(" {}^2 ns/ray | x |", res);
    fmt::print("\n|---|");
    for (std::size_t i = 0; i < g_resolutions.size(); ++i) fmt::print("---|---|");
    fmt::print("\n");
    for (int o = 0; o < kOptionCount; ++o) {
      fmt::print("| {} |", kOptions[o]);
      for (int res : g_resolutions) {
        const double base = median(cpu_, name(res, "raw_high") + "/min_time:0.500");
        const double v = median(cpu_, name(res, kOptions[o]) + "/min_time:0.500");
        if (v < 0) fmt::print(" - | - |");
        else fmt::print(" {:.1f} | {:.2f} |", v, base / v);
      }
      fmt::print("\n");
    }
  }
};

}  // namespace

int main(int argc, char** argv) {
  int kept = 1;
  for (int i = 1; i < argc; ++i) {
    if (std::strncmp(argv[i], "--res=", 6) == 0) {
      g_resolutions.clear();
      for (const char* p = argv[i] + 6; *p;) {
        g_resolutions.push_back(std::atoi(p));
        while (*p && *p != ',') ++p;
        if (*p == ',') ++p;
      }
    } else {
      argv[kept++] = argv[i];
    }
  }
  argc = kept;
  for (int res : g_resolutions)
    for (int o = 0; o < kOptionCount; ++o) {
      const std::string option = kOptions[o];
      if (res >= kLargest && (option == "raw_medium" || option == "raw_low" || option == "raw_compact" ||
                              option == "raw_grid" || option == "trace_grid"))
        continue;
      benchmark::RegisterBenchmark(name(res, option).c_str(), [res, option](benchmark::State& s) { BM_Tracer(s, res, option); })
          ->Unit(benchmark::kMillisecond)
          ->MinTime(0.5);
    }
  TableReporter reporter;
  return bench::run_benchmarks(argc, argv, reporter);
}
