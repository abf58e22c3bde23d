// The Smith random walk (scatter/smith_walk.h): paths per second on 1 and 2 threads, and what a per-order
// table with a 1% relative standard error on the order-2 albedo costs.
//
// Configuration: GGX alpha 0.5, light at theta 60 deg (phi 0), a mirror (F = 1) and a dielectric of eta 1.5
// seen from outside, uniform heights, the default order cap (100) and 16 rows per hemisphere (the whole
// run through smith_walk_scatter: walks, binning, the in-order reduction into the histogram).
//
// BM_WalkPaths/material:<0 mirror|1 dielectric>/threads:<1|2>: wall-clock time of 64 blocks (262144 paths);
// counter paths_per_second (wall clock); the CPU column is the process's CPU time (all threads), so that on a
// shared machine paths / CPU time gives the rate per busy core.
// BM_WalkOrder2/material:<0|1>: one run of 2^20 paths on 2 threads; counters: the order-2 albedo, its
// relative standard error, the paths needed for 1% (paths * (rel SE / 0.01)^2, from the measured SE), and
// the time they take at the measured rate.
// BM_Heitz2016Paths/material:<0|1> (only when configured with MICROSIM_HEITZ2016_DIR, CMakeLists.txt): the
// supplemental code of Heitz, Hanika, d'Eon, Dachsbacher 2016 on the same configuration, one thread, as a
// reference point: its Microsurface::sample per path (float, std::mt19937, its conductor is the mirror F = 1,
// no order cap), with no binning or reduction, so it times the walk alone.
// BM_WalkKernels/material:<0 mirror|1 dielectric|2 gold conductor>/kernel:<0 scalar|1 lanes|2 lanes on AVX2>: the same run on 1 thread with
// the kernel chosen (smith_walk.h WalkKernel), both kernels in one binary; scripts/bench_walk_kernels.py runs
// them in alternating rounds (docs/records/walk-speed.md, "Third round").
// scripts/bench_walk_side_by_side.py runs the BM_WalkPaths of two builds alternately (docs/records/walk-speed.md).
//   build-*/bench_walk --benchmark_repetitions=3
#include "scatter/smith_walk.h"
#include "stats/direction_binner.h"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <string>
#include <vector>

using namespace microsim;

namespace {

Material bench_material(int material) {
  if (material == 0) return Material::mirror();
  if (material == 1) return Material::dielectric(1.5);
  return Material::conductor({{0.18, 3.4}, {0.42, 2.35}, {1.37, 1.77}});  // gold, 3 channels
}

ScatterOptions bench_options(int material, int threads, std::uint64_t paths) {
  ScatterOptions o;
  o.wi = direction_from_degrees(60.0, 0.0);
  o.material = bench_material(material);
  o.paths = paths;
  o.seed = 2016;
  o.rows = 16;
  o.run.threads = threads;
  return o;
}

const SmithMicrosurface kSurface{NdfKind::ggx, 0.5, 0.5, HeightDistribution::uniform};

void BM_WalkPaths(benchmark::State& state) {
  const ScatterOptions o = bench_options(int(state.range(0)), int(state.range(1)), 64 * kPathsPerBlock);
  for (auto _ : state) {
    const ScatterHistogram h = smith_walk_scatter(kSurface, o);
    benchmark::DoNotOptimize(h.paths());
  }
  state.counters["paths_per_second"] =
      benchmark::Counter(double(state.iterations()) * double(o.paths), benchmark::Counter::kIsRate);
  state.SetLabel(state.range(0) == 0 ? "GGX 0.5 mirror" : "GGX 0.5 dielectric 1.5");
}

void BM_WalkKernels(benchmark::State& state) {
  const ScatterOptions o = bench_options(int(state.range(0)), 1, 64 * kPathsPerBlock);
  const WalkKernel kernel = state.range(1) == 0 ? WalkKernel::scalar : WalkKernel::lanes;
  // kernel 2: the lanes on AVX2 (4 lanes of doubles) where the CPU has better (Highway's choice is global).
  const std::vector<std::string> targets = direction_binner_targets();
  if (state.range(1) == 2 && std::find(targets.begin(), targets.end(), "AVX2") == targets.end()) {
    state.SkipWithError("AVX2 not available");
    return;
  }
  if (state.range(1) == 2) use_direction_binner_target("AVX2");
  for (auto _ : state) {
    const ScatterHistogram h = smith_walk_scatter(kSurface, o, kernel);
    benchmark::DoNotOptimize(h.paths());
  }
  state.counters["paths_per_second"] =
      benchmark::Counter(double(state.iterations()) * double(o.paths), benchmark::Counter::kIsRate);
  const char* names[] = {"GGX 0.5 mirror, ", "GGX 0.5 dielectric 1.5, ", "GGX 0.5 gold, "};
  state.SetLabel(std::string(names[state.range(0)]) +
                 (kernel == WalkKernel::scalar ? "scalar" : "lanes " + smith_walk_lanes_target()));
  use_direction_binner_target("");
}

void BM_WalkOrder2(benchmark::State& state) {
  const ScatterOptions o = bench_options(int(state.range(0)), 2, std::uint64_t(1) << 20);
  double seconds = 0;
  Estimate e2{};
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    const ScatterHistogram h = smith_walk_scatter(kSurface, o);
    seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    e2 = h.albedo(0, 1);
  }
  const double rel = e2.standard_error / e2.value;
  const double paths_1pct = double(o.paths) * (rel / 0.01) * (rel / 0.01);
  state.counters["order2_albedo"] = e2.value;
  state.counters["order2_rel_se"] = rel;
  state.counters["paths_for_1pct"] = paths_1pct;
  state.counters["seconds_for_1pct"] = seconds * paths_1pct / double(o.paths);
  state.SetLabel(state.range(0) == 0 ? "GGX 0.5 mirror, 2 threads" : "GGX 0.5 dielectric 1.5, 2 threads");
}

}  // namespace

BENCHMARK(BM_WalkPaths)
    ->ArgsProduct({{0, 1}, {1, 2}})
    ->ArgNames({"material", "threads"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->MinTime(0.5);
BENCHMARK(BM_WalkKernels)
    ->ArgsProduct({{0, 1, 2}, {0, 1, 2}})
    ->ArgNames({"material", "kernel"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->MinTime(0.5);
BENCHMARK(BM_WalkOrder2)->DenseRange(0, 1)->ArgName("material")->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);

#ifdef MICROSIM_BENCH_HEITZ2016
// Included last: the header brings glm's names into the global namespace.
#include "MicrosurfaceScattering.h"

namespace {

void BM_Heitz2016Paths(benchmark::State& state) {
  const bool mirror = state.range(0) == 0;
  const float theta = float(60.0 * kPi<double> / 180.0);
  const vec3 wi(std::sin(theta), 0.0f, std::cos(theta));
  MicrosurfaceConductor conductor(true, false, 0.5f, 0.5f);
  MicrosurfaceDielectric dielectric(true, false, 0.5f, 0.5f, 1.5f);
  const Microsurface& surface = mirror ? static_cast<const Microsurface&>(conductor) : dielectric;
  const std::uint64_t paths = 64 * kPathsPerBlock;
  for (auto _ : state) {
    float sum = 0;
    for (std::uint64_t i = 0; i < paths; ++i) {
      int order = 0;
      sum += surface.sample(wi, order).z;
    }
    benchmark::DoNotOptimize(sum);
  }
  state.counters["paths_per_second"] =
      benchmark::Counter(double(state.iterations()) * double(paths), benchmark::Counter::kIsRate);
  state.SetLabel(mirror ? "Heitz 2016 code, GGX 0.5 mirror" : "Heitz 2016 code, GGX 0.5 dielectric 1.5");
}

}  // namespace

BENCHMARK(BM_Heitz2016Paths)
    ->DenseRange(0, 1)
    ->ArgName("material")
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime()
    ->MinTime(0.5);
#endif

BENCHMARK_MAIN();
