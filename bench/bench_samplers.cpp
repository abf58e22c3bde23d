// Cost of the sampler zoo: nanoseconds per sample of every sampler in float and in double, side by side,
// and of evaluating the analytic D_v (GGX::visible_normal_pdf) and D. One sample = one call of the
// sampler (header-only templates, so each is inlined into its loop as it would be in a renderer) for a
// fixed view and roughness; the uniform variates come from a precomputed table (CounterRng) so that the
// random-number generator is not measured, and every result goes through benchmark::DoNotOptimize.
//
// Configurations: "iso" = alpha 0.3, theta 60, phi 30 (the example); "grazing" = alpha
// (0.05, 0.5), theta 85, phi 30. A reference row, naive-heitz2018, evaluates Heitz 2018 the textbook way
// (cos/sin of 2 pi u, sqrt(1 - p1^2 - p2^2)): it is not in the zoo; it shows what the numerically careful
// formulation of docs/reference/stability.md costs.
//
// After the benchmarks a markdown table is printed (CPU time per sample, which on a shared machine is
// steadier than wall-clock time; the best of --benchmark_repetitions; ratios within one run).
// docs/records/benchmarks.md quotes it.
//   build-*/bench_samplers --benchmark_min_time=0.2 --benchmark_repetitions=3
#include "core/random.h"
#include "microfacet/samplers.h"

#include <benchmark/benchmark.h>
#include <fmt/core.h>

#include <algorithm>
#include <map>
#include <string>
#include <vector>

using namespace microsim;

namespace {

constexpr int kBatch = 1024;  // samples per benchmark iteration (power of two)

struct Config {
  const char* name;
  double ax, ay, theta, phi;
};
constexpr Config kConfigs[] = {{"iso", 0.3, 0.3, 60.0, 30.0}, {"grazing", 0.05, 0.5, 85.0, 30.0}};

template <class T> const std::vector<Vec2<T>>& u_table() {
  static const std::vector<Vec2<T>> table = [] {
    std::vector<Vec2<T>> t;
    CounterRng rng(2024, 0);
    for (int i = 0; i < kBatch; ++i) {
      const double a = rng.uniform(), b = rng.uniform();
      t.emplace_back(T(a), T(b));
    }
    return t;
  }();
  return table;
}

// Heitz 2018 the textbook way, for reference (same distribution as sample_heitz2018; see the header).
template <class T> SampleResult<T> naive_heitz2018(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u) {
  const Vec3<T> vh = Vec3<T>(ggx.alpha_x() * wi.x(), ggx.alpha_y() * wi.y(), wi.z()).normalized();
  const T lensq = vh.x() * vh.x() + vh.y() * vh.y();
  const Vec3<T> t1 = lensq > T(0) ? Vec3<T>(Vec3<T>(-vh.y(), vh.x(), T(0)) / std::sqrt(lensq)) : Vec3<T>(1, 0, 0);
  const Vec3<T> t2 = vh.cross(t1);
  const T r = std::sqrt(u.x()), phi = T(2) * kPi<T> * u.y();
  const T p1 = r * std::cos(phi);
  const T s = T(0.5) * (T(1) + vh.z());
  const T p2 = (T(1) - s) * std::sqrt(std::max(T(1) - p1 * p1, T(0))) + s * r * std::sin(phi);
  const T height = std::sqrt(std::max(T(1) - p1 * p1 - p2 * p2, T(0)));
  const Vec3<T> nh = p1 * t1 + p2 * t2 + height * vh;
  const Vec3<T> st(ggx.alpha_x() * nh.x(), ggx.alpha_y() * nh.y(), std::max(nh.z(), T(0)));
  const T len = st.norm();
  const T pdf = T(2) * height / (kPi<T> * (T(1) + vh.z())) * len * len * len / (ggx.alpha_x() * ggx.alpha_y());
  return DirectionSample<T>{st / len, pdf};
}

template <class T> using SamplerFn = SampleResult<T> (*)(const GGX<T>&, const Vec3<T>&, Vec2<T>);

// The sampler is a template argument, so that the call inlines into the loop.
template <class T, SamplerFn<T> F> void BM_Sample(benchmark::State& state, Config cfg) {
  const GGX<T> ggx(T(cfg.ax), T(cfg.ay));
  const Vec3<double> wd = direction_from_degrees(cfg.theta, cfg.phi);
  const Vec3<T> wi(T(wd.x()), T(wd.y()), T(wd.z()));
  const std::vector<Vec2<T>>& us = u_table<T>();
  for (auto _ : state) {
    for (int i = 0; i < kBatch; ++i) {
      SampleResult<T> s = F(ggx, wi, us[std::size_t(i)]);
      benchmark::DoNotOptimize(s);
    }
  }
  state.SetItemsProcessed(state.iterations() * kBatch);
}

// D_v(wi, m) and D(m) at the normals that heitz2018 samples for this view.
template <class T, bool kVisible> void BM_Density(benchmark::State& state, Config cfg) {
  const GGX<T> ggx(T(cfg.ax), T(cfg.ay));
  const Vec3<double> wd = direction_from_degrees(cfg.theta, cfg.phi);
  const Vec3<T> wi(T(wd.x()), T(wd.y()), T(wd.z()));
  std::vector<Vec3<T>> normals;
  for (const Vec2<T>& u : u_table<T>()) normals.push_back(sample_heitz2018(ggx, wi, u)->direction);
  for (auto _ : state) {
    for (int i = 0; i < kBatch; ++i) {
      T v;
      if constexpr (kVisible) v = ggx.visible_normal_pdf(wi, normals[std::size_t(i)]);
      else v = ggx.D(normals[std::size_t(i)]);
      benchmark::DoNotOptimize(v);
    }
  }
  state.SetItemsProcessed(state.iterations() * kBatch);
}

template <class T> struct Zoo {
  struct Entry {
    const char* name;
    void (*bench)(benchmark::State&, Config);
  };
  static std::vector<Entry> entries() {
    return {
        {"ndf", &BM_Sample<T, &sample_ndf<T>>},
        {"heitz2014", &BM_Sample<T, &sample_heitz2014<T>>},
        {"heitz2018", &BM_Sample<T, &sample_heitz2018<T>>},
        {"dupuy2023", &BM_Sample<T, &sample_dupuy2023<T>>},
        {"bounded2023", &BM_Sample<T, &sample_bounded2023<T>>},
        {"heitz2018-talk", &BM_Sample<T, &sample_heitz2018_talk<T>>},
        {"naive-heitz2018 (ref.)", &BM_Sample<T, &naive_heitz2018<T>>},
        {"D_v(wi, m)", &BM_Density<T, true>},
        {"D(m)", &BM_Density<T, false>},
    };
  }
};

// Keeps the console output and records CPU ns per sample for the summary table.
class TableReporter : public benchmark::ConsoleReporter {
public:
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& r : runs) {
      if (r.run_type != Run::RT_Iteration || r.iterations == 0) continue;
      // The best of the repetitions (--benchmark_repetitions): the least disturbed by other processes.
      const double ns = r.GetAdjustedCPUTime() / kBatch;  // time unit: ns
      auto [it, inserted] = ns_per_sample.emplace(r.run_name.function_name, ns);
      if (!inserted) it->second = std::min(it->second, ns);
    }
  }
  std::map<std::string, double> ns_per_sample;
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  const auto float_zoo = Zoo<float>::entries();
  const auto double_zoo = Zoo<double>::entries();
  for (const Config& cfg : kConfigs)
    for (std::size_t k = 0; k < float_zoo.size(); ++k) {
      benchmark::RegisterBenchmark(fmt::format("{}/float/{}", float_zoo[k].name, cfg.name).c_str(), float_zoo[k].bench, cfg)
          ->Unit(benchmark::kNanosecond);
      benchmark::RegisterBenchmark(fmt::format("{}/double/{}", double_zoo[k].name, cfg.name).c_str(), double_zoo[k].bench, cfg)
          ->Unit(benchmark::kNanosecond);
    }
  TableReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();

  // Side-by-side table: CPU ns per sample (per evaluation for D_v and D), and float relative to heitz2018.
  auto ns = [&](const std::string& name, const char* type, const char* cfg) {
    const auto it = reporter.ns_per_sample.find(fmt::format("{}/{}/{}", name, type, cfg));
    return it == reporter.ns_per_sample.end() ? -1.0 : it->second;
  };
  auto cell = [](double v) { return v < 0 ? std::string("-") : fmt::format("{:.1f}", v); };
  fmt::print("\nCPU ns per sample (batch of {} precomputed u; lower is better)\n\n", kBatch);
  fmt::print("| sampler |");
  for (const Config& c : kConfigs) fmt::print(" {0} float | {0} double | {0} float / heitz2018 float |", c.name);
  fmt::print("\n|---|");
  for (std::size_t i = 0; i < std::size(kConfigs); ++i) fmt::print("---:|---:|---:|");
  fmt::print("\n");
  for (const auto& e : float_zoo) {
    fmt::print("| {} |", e.name);
    for (const Config& c : kConfigs) {
      const double f = ns(e.name, "float", c.name), d = ns(e.name, "double", c.name);
      const double ref = ns("heitz2018", "float", c.name);
      fmt::print(" {} | {} | {} |", cell(f), cell(d), f > 0 && ref > 0 ? fmt::format("{:.2f}", f / ref) : "-");
    }
    fmt::print("\n");
  }
  return 0;
}
