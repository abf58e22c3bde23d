// Throughput of explicit multiple scattering (scatter_on_surface, scatter/surface_scatter.h) against raw
// Embree rtcIntersect1 on the same 1024^2 heightfield and the same rays, in one run.
//
// Surface: `microsim surface build --assembly smith --res 1024 --alpha 0.5` (seed 1), built in the
// process, or read from --surface=FILE.exr. Paths: kPaths per iteration from theta 45 deg, phi 30, seed 1,
// for a mirror and a dielectric of eta 1.5 (whose refracted paths travel inside the solid).
//
// BM_ScatterPipeline: scatter_on_surface itself (counter-based origins, the periodic segment loop of
//   HeightfieldScene::trace / trace_from_surface with the start triangle skipped by an Embree filter, the
//   facet normal, the facet event, the binning and the exact per-order histogram).
// BM_ScatterPaths: the same paths through SurfacePathTracer::trace_block alone, in the same blocks (no
//   histogram): what the accumulation costs is the difference.
// BM_ScatterRaw: every Embree call the pipeline makes for these paths (recorded once before timing with
//   SurfacePathTracer's recording hook: every segment of every primary and bounce ray, and the re-calls
//   after a convex-edge graze), replayed as plain rtcIntersect1 calls (no filter) in the same TBB blocks
//   of kPathsPerBlock paths.
// Rates are per traced ray (a primary ray or a bounce: HeightfieldScene calls; "bounces traced per
// second"), wall-clock and process CPU time per ray (all threads; robust to the load of other processes
// on a shared machine). After the benchmarks, a table of the medians over the repetitions, pipeline /
// raw. Run with --benchmark_repetitions=3 or more.
#include "core/cpu_time.h"
#include "scatter/surface_scatter.h"

#include "bench_util.h"

#include <benchmark/benchmark.h>
#include <fmt/core.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <vector>

using namespace microsim;
using microsim::bench::median;
using microsim::bench::Samples;

namespace {

constexpr std::uint64_t kPaths = 1 << 16;  // per iteration
constexpr double kTheta = 45.0, kPhi = 30.0;
std::string g_surface_path;  // --surface=FILE.exr; empty: built in the process


struct Surface {
  std::unique_ptr<microgeom::Heightfield> field;
  std::unique_ptr<HeightfieldScene> scene, pyramid;  // Embree's triangles; the pyramid tracer
};

const Surface& surface() {
  static Surface s;
  if (s.scene) return s;
  s.field = bench::smith_surface_or_file(g_surface_path, 0.5);
  s.scene = std::make_unique<HeightfieldScene>(*s.field, HeightfieldGeometry::triangles);
  s.pyramid = std::make_unique<HeightfieldScene>(*s.field, HeightfieldGeometry::pyramid);
  return s;
}

Material material(int k) { return k == 0 ? Material::mirror() : Material::dielectric(1.5); }
std::string material_name(int k) { return k == 0 ? "mirror" : "dielectric 1.5"; }

ScatterOptions scatter_options(int k, int threads) {
  ScatterOptions o;
  o.wi = direction_from_degrees(kTheta, kPhi);
  o.material = material(k);
  o.paths = kPaths;
  o.seed = 1;
  o.run.threads = threads;
  return o;
}

// The pipeline's Embree calls for material k: those of path block b in calls[block_first[b], block_first[b+1]).
struct Recording {
  std::vector<EmbreeCall> calls;
  std::vector<std::size_t> block_first;
  std::uint64_t traced = 0, events = 0;
};

// The paths of scatter_on_surface's block `block` (its variates: trace_block);
// `calls` receives their Embree calls, in the order made, if given.
template <class PerPath>
void run_paths(const SurfacePathTracer& tracer, const ScatterOptions& o, std::uint64_t block, const PerPath& per_path,
               std::vector<EmbreeCall>* calls) {
  const BlockPlan plan{o.paths, kPathsPerBlock};
  tracer.trace_block(o.seed, block, plan.units_in(block), kPathsPerBlock,
                     [&](std::uint64_t, const SurfacePath& path) { per_path(path); }, calls);
}

const Recording& recording(int k) {
  static std::map<int, Recording> recordings;
  Recording& r = recordings[k];
  if (!r.block_first.empty()) return r;
  const ScatterOptions o = scatter_options(k, 1);
  const SurfacePathTracer tracer(*surface().scene, o.material, o.wi, o.max_order);
  embree::FlushDenormalsScope ftz;
  for (std::uint64_t b = 0; b < BlockPlan{o.paths, kPathsPerBlock}.blocks(); ++b) {
    r.block_first.push_back(r.calls.size());
    run_paths(tracer, o, b, [&](const SurfacePath& p) { r.traced += std::uint64_t(p.traced), r.events += std::uint64_t(p.order); }, &r.calls);
  }
  r.block_first.push_back(r.calls.size());
  return r;
}

void set_counters(benchmark::State& state, double cpu0, const Recording& r, int k) {
  const double rays = double(state.iterations()) * double(r.traced);
  state.counters["cpu_ns_per_ray"] = 1e9 * (process_cpu_seconds() - cpu0) / rays;
  state.SetItemsProcessed(std::int64_t(rays));
  state.counters["rays_per_path"] = double(r.traced) / double(kPaths);
  state.counters["bounces_per_path"] = double(r.events) / double(kPaths);
  state.counters["segments_per_ray"] = double(r.calls.size()) / double(r.traced);
  state.SetLabel(material_name(k));
}

void BM_ScatterRaw(benchmark::State& state) {
  const int k = int(state.range(0)), threads = int(state.range(1));
  const Recording& r = recording(k);
  const RTCScene scene = surface().scene->embree_scene().handle();
  tbb::task_arena arena(threads);
  std::uint64_t hits = 0;
  const double cpu0 = process_cpu_seconds();
  for (auto _ : state) {
    std::atomic<std::uint64_t> total{0};
    arena.execute([&] {
      tbb::parallel_for(std::size_t(0), r.block_first.size() - 1, [&](std::size_t b) {
        embree::FlushDenormalsScope ftz;
        RTCIntersectContext context;
        rtcInitIntersectContext(&context);
        std::uint64_t local = 0;
        for (std::size_t i = r.block_first[b]; i < r.block_first[b + 1]; ++i) {
          const EmbreeCall& c = r.calls[i];
          RTCRayHit rh = embree::make_ray_hit(c.origin, c.dir, c.tnear, c.tfar);
          rtcIntersect1(scene, &context, &rh);
          local += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
        }
        total += local;
      });
    });
    hits = total.load();
    benchmark::DoNotOptimize(hits);
  }
  set_counters(state, cpu0, r, k);
}

void BM_ScatterPaths(benchmark::State& state) {
  const int k = int(state.range(0)), threads = int(state.range(1));
  const Recording& r = recording(k);
  const ScatterOptions o = scatter_options(k, threads);
  const SurfacePathTracer tracer(*surface().scene, o.material, o.wi, o.max_order);
  tbb::task_arena arena(threads);
  const double cpu0 = process_cpu_seconds();
  for (auto _ : state) {
    std::atomic<std::uint64_t> traced{0};
    arena.execute([&] {
      tbb::parallel_for(std::uint64_t(0), BlockPlan{o.paths, kPathsPerBlock}.blocks(), [&](std::uint64_t b) {
        embree::FlushDenormalsScope ftz;
        std::uint64_t local = 0;
        run_paths(tracer, o, b, [&](const SurfacePath& p) { local += std::uint64_t(p.traced); }, nullptr);
        traced += local;
      });
    });
    if (traced.load() != r.traced) state.SkipWithError("the paths traced other rays than recorded");
  }
  set_counters(state, cpu0, r, k);
}

void BM_ScatterPipeline(benchmark::State& state) {
  const int k = int(state.range(0)), threads = int(state.range(1));
  const Recording& r = recording(k);
  const ScatterOptions o = scatter_options(k, threads);
  const double cpu0 = process_cpu_seconds();
  for (auto _ : state) {
    SurfaceScatterDiagnostics d;
    const ScatterHistogram h = scatter_on_surface(*surface().scene, o, &d);
    benchmark::DoNotOptimize(h.paths());
    if (d.traced != r.traced || d.segments != r.calls.size()) state.SkipWithError("the pipeline traced other rays than recorded");
  }
  set_counters(state, cpu0, r, k);
}

// The pipeline with the pyramid tracer (the same paths; a path may differ where a ray passes within float
// rounding of an edge, tests/test_pyramid_trace.cpp): rates per ray of the Embree run's count.
void BM_ScatterPipelinePyramid(benchmark::State& state) {
  const int k = int(state.range(0)), threads = int(state.range(1));
  const Recording& r = recording(k);
  const ScatterOptions o = scatter_options(k, threads);
  const double cpu0 = process_cpu_seconds();
  for (auto _ : state) {
    SurfaceScatterDiagnostics d;
    const ScatterHistogram h = scatter_on_surface(*surface().pyramid, o, &d);
    benchmark::DoNotOptimize(h.paths());
    state.counters["traced_differs"] = double(d.traced) - double(r.traced);
  }
  set_counters(state, cpu0, r, k);
}

void timed(benchmark::internal::Benchmark* b) {
  b->ArgsProduct({{0, 1}, {1, 2}})->ArgNames({"material", "threads"})->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(0.5);
}
BENCHMARK(BM_ScatterRaw)->Apply(timed);
BENCHMARK(BM_ScatterPaths)->Apply(timed);
BENCHMARK(BM_ScatterPipeline)->Apply(timed);
BENCHMARK(BM_ScatterPipelinePyramid)->Apply(timed);

// Keeps every repetition's rate and CPU time per ray; prints the medians, pipeline against raw.
class RatioReporter : public bench::RepetitionReporter {
public:
  void PrintRatios() const {
    fmt::print("\nexplicit multiple scattering vs raw rtcIntersect1, same rays (median of the repetitions), theta {} "
               "phi {}:\n| material | threads | raw Mrays/s | paths only Mrays/s | pipeline Mrays/s | pipeline / raw "
               "(wall) | raw CPU ns/ray | paths only CPU ns/ray | pipeline CPU ns/ray | pipeline / raw (CPU) | pyramid pipeline "
               "CPU ns/ray | pyramid / raw (CPU) |\n"
               "|---|---|---|---|---|---|---|---|---|---|---|---|\n",
               kTheta, kPhi);
    for (int k : {0, 1}) {
      for (int threads : {1, 2}) {
        const std::string args = fmt::format("/material:{}/threads:{}/min_time:0.500/real_time", k, threads);
        const double raw = median(rate_, "BM_ScatterRaw" + args), paths = median(rate_, "BM_ScatterPaths" + args),
                     pipe = median(rate_, "BM_ScatterPipeline" + args);
        const double raw_cpu = median(cpu_, "BM_ScatterRaw" + args), paths_cpu = median(cpu_, "BM_ScatterPaths" + args),
                     pipe_cpu = median(cpu_, "BM_ScatterPipeline" + args),
                     pyr_cpu = median(cpu_, "BM_ScatterPipelinePyramid" + args);
        if (raw < 0 || pipe < 0) continue;
        fmt::print("| {} | {} | {:.3f} | {:.3f} | {:.3f} | {:.1f}% | {:.0f} | {:.0f} | {:.0f} | {:.1f}% | {:.0f} | {:.2f}x |\n",
                   material_name(k), threads, raw * 1e-6, paths * 1e-6, pipe * 1e-6, 100.0 * pipe / raw, raw_cpu,
                   paths_cpu, pipe_cpu, 100.0 * raw_cpu / pipe_cpu, pyr_cpu, raw_cpu / pyr_cpu);
      }
    }
  }
};


}  // namespace

int main(int argc, char** argv) {
  bench::take_surface_argument(argc, argv, g_surface_path);
  RatioReporter reporter;
  return bench::run_benchmarks(argc, argv, reporter);
}
