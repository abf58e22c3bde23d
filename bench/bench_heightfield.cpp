// Benchmarks of the periodic heightfield tracer (src/trace/heightfield_trace.h): scene build time and
// Embree memory per texel, primary (VNDF) rays and shadow rays per second for both Embree geometry kinds,
// and the raw rtcIntersect1 rate on the same scene and rays (one unclipped call per ray, no wrapping):
// the cost of the periodic segment loop. Surfaces: the `smith` assembly, alpha 0.5, seed 1, default
// correlation length, built once per resolution (build time is measured separately by
// `microsim surface build`, see docs/records/heightfield-trade.md). Single-threaded loops: the rates are per core.
//
// The whole `trace vndf` pipeline on a 1024^2 heightfield against raw rtcIntersect1 (the same segments)
// is in bench_trace (BM_HeightfieldPipeline, BM_HeightfieldRaw), beside the quadric's.
//
// Run: build-*/bench_heightfield --benchmark_counters_tabular=true
#include "microgeom/assembly.h"
#include "trace/heightfield_trace.h"
#include "core/random.h"

#include <benchmark/benchmark.h>

#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <vector>

namespace {

using microsim::HeightfieldGeometry;
using microsim::HeightfieldScene;
using microsim::Vec3;

const microgeom::Heightfield& surface(int res) {
  static std::map<int, std::unique_ptr<microgeom::Heightfield>> cache;
  auto& slot = cache[res];
  if (!slot) {
    microgeom::AssemblyParams p;
    p.assembly = "smith";
    p.alpha_x = p.alpha_y = 0.5;
    p.resolution = res;
    p.seed = 1;
    slot = std::make_unique<microgeom::Heightfield>(microgeom::build_assembly(p));
  }
  return *slot;
}

const HeightfieldScene& scene(int res, HeightfieldGeometry g) {
  static std::map<std::pair<int, int>, std::unique_ptr<HeightfieldScene>> cache;
  auto& slot = cache[{res, int(g)}];
  if (!slot) slot = std::make_unique<HeightfieldScene>(surface(res), g);
  return *slot;
}

HeightfieldGeometry geometry_arg(std::int64_t a) { return a == 0 ? HeightfieldGeometry::triangles : HeightfieldGeometry::grid; }

void BM_SceneBuild(benchmark::State& state) {
  const int res = int(state.range(0));
  const auto g = geometry_arg(state.range(1));
  const auto& field = surface(res);
  double embree_bytes = 0;
  for (auto _ : state) {
    HeightfieldScene s(field, g);
    embree_bytes = double(s.embree_peak_bytes());
    benchmark::DoNotOptimize(&s);
  }
  state.counters["embree_MiB"] = embree_bytes / (1024.0 * 1024.0);
  state.counters["bytes_per_texel"] = embree_bytes / double(field.texel_count());
  state.SetLabel(microsim::to_string(g));
}

constexpr int kRays = 1 << 14;

void BM_PrimaryRays(benchmark::State& state) {
  const int res = int(state.range(0));
  const auto g = geometry_arg(state.range(1));
  const double theta = double(state.range(2));
  const HeightfieldScene& sc = scene(res, g);
  const double L = sc.field().tile_size();
  const Vec3<double> v = microsim::direction_from_degrees(theta, 30.0);
  std::vector<Vec3<double>> origins(kRays);
  microsim::CounterRng rng(1, 0);
  for (auto& o : origins) o = Vec3<double>(L * rng.uniform(), L * rng.uniform(), sc.start_height());
  microsim::embree::FlushDenormalsScope ftz;
  std::int64_t segments = 0, rays = 0;
  for (auto _ : state) {
    for (const auto& o : origins) {
      const auto h = sc.trace(o, -v);
      segments += h.segments;
      benchmark::DoNotOptimize(h.triangle);
    }
    rays += kRays;
  }
  state.SetItemsProcessed(rays);
  state.counters["rays_per_s"] = benchmark::Counter(double(rays), benchmark::Counter::kIsRate);
  state.counters["segments_per_ray"] = double(segments) / double(rays);
  state.SetLabel(microsim::to_string(g));
}

// The first segment of the same rays as one raw rtcIntersect1 each on the same scene (same origin, tfar
// clipped at the tile edge plus half a cell like the tracer's first segment; plain context, no filter):
// what one Embree call costs. The tracer's efficiency is rays_per_s x segments_per_ray over this rate.
void BM_RawEmbree(benchmark::State& state) {
  const int res = int(state.range(0));
  const auto g = geometry_arg(state.range(1));
  const double theta = double(state.range(2));
  const HeightfieldScene& sc = scene(res, g);
  const double L = sc.field().tile_size(), h = sc.field().cell_size();
  const Vec3<double> dir = -microsim::direction_from_degrees(theta, 30.0);
  const Vec3<float> d = dir.cast<float>();
  struct Ray {
    Vec3<float> o;
    float tfar;
  };
  std::vector<Ray> rays(kRays);
  microsim::CounterRng rng(1, 0);
  const double dxy = std::hypot(dir.x(), dir.y());
  for (auto& r : rays) {
    const Vec3<double> o(L * rng.uniform(), L * rng.uniform(), sc.start_height());
    double t_exit = std::numeric_limits<double>::infinity();
    if (dir.x() != 0) t_exit = std::min(t_exit, (dir.x() > 0 ? L - o.x() : -o.x()) / dir.x());
    if (dir.y() != 0) t_exit = std::min(t_exit, (dir.y() > 0 ? L - o.y() : -o.y()) / dir.y());
    const double tfar = dxy > 0 ? t_exit + 0.5 * h / dxy : std::numeric_limits<double>::infinity();
    r = {o.cast<float>(), float(tfar)};
  }
  microsim::embree::FlushDenormalsScope ftz;
  const auto& es = sc.embree_scene();
  std::int64_t calls = 0, hits = 0;
  for (auto _ : state) {
    for (const auto& r : rays) hits += es.intersect(r.o, d, 0.0f, r.tfar) ? 1 : 0;
    calls += kRays;
  }
  state.counters["calls_per_s"] = benchmark::Counter(double(calls), benchmark::Counter::kIsRate);
  state.counters["first_segment_hits"] = double(hits) / double(calls);
  state.SetLabel(microsim::to_string(g));
}

void BM_ShadowRays(benchmark::State& state) {
  const int res = int(state.range(0));
  const auto g = geometry_arg(state.range(1));
  const double theta = double(state.range(2));
  const HeightfieldScene& sc = scene(res, g);
  const auto& f = sc.field();
  const double L = f.tile_size();
  const Vec3<double> v = microsim::direction_from_degrees(theta, 30.0);
  struct Start {
    Vec3<double> p;
    std::uint32_t tri;
  };
  std::vector<Start> starts;
  microsim::CounterRng rng(2, 0);
  while (starts.size() < std::size_t(kRays)) {
    const double x = L * rng.uniform(), y = L * rng.uniform();
    const auto tri = f.triangle_at(x, y);
    if (f.triangle_normal(tri).dot(v) > 0) starts.push_back({Vec3<double>(x, y, f.height_at(x, y)), tri});
  }
  microsim::embree::FlushDenormalsScope ftz;
  std::int64_t rays = 0, visible = 0;
  for (auto _ : state) {
    for (const auto& s : starts) visible += sc.escapes(s.p, v, s.tri) ? 1 : 0;
    rays += kRays;
  }
  state.counters["rays_per_s"] = benchmark::Counter(double(rays), benchmark::Counter::kIsRate);
  state.counters["visible_fraction"] = double(visible) / double(rays);
  state.SetLabel(microsim::to_string(g));
}

void build_args(benchmark::internal::Benchmark* b) {
  for (int res : {256, 1024, 2048})
    for (int g : {0, 1}) b->Args({res, g});
}
void ray_args(benchmark::internal::Benchmark* b) {
  for (int res : {256, 1024, 2048})
    for (int g : {0, 1})
      for (int theta : {30, 75, 85}) b->Args({res, g, theta});
}

BENCHMARK(BM_SceneBuild)->Apply(build_args)->Unit(benchmark::kMillisecond)->Iterations(2);
BENCHMARK(BM_PrimaryRays)->Apply(ray_args)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RawEmbree)->Apply(ray_args)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ShadowRays)->Apply(ray_args)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
