// microsim benchmarks: what the pipeline-vs-raw benchmarks share (medians over the repetitions, the
// --surface=FILE.exr argument, the 1024^2 surface, the reporter; CPU time: core/cpu_time.h).
#pragma once

#include "microgeom/assembly.h"
#include "microgeom/exr_io.h"
#include "microgeom/heightfield.h"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace microsim::bench {

// Per benchmark name, one value per repetition.
using Samples = std::map<std::string, std::vector<double>>;

// The median of a benchmark's repetitions, or -1 if it did not run.
inline double median(const Samples& samples, const std::string& name) {
  const auto it = samples.find(name);
  if (it == samples.end() || it->second.empty()) return -1.0;
  std::vector<double> v = it->second;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Takes --surface=FILE.exr out of argv (before Google Benchmark sees it) into `path`.
inline void take_surface_argument(int& argc, char** argv, std::string& path) {
  int kept = 1;
  for (int i = 1; i < argc; ++i) {
    if (std::strncmp(argv[i], "--surface=", 10) == 0) path = argv[i] + 10;
    else argv[kept++] = argv[i];
  }
  argc = kept;
}

// The benchmarks' 1024^2 heightfield: `microsim surface build --assembly smith --res 1024 --alpha ALPHA`
// (seed 1), built in the process, or the heightmap read from `path` if not empty.
inline std::unique_ptr<microgeom::Heightfield> smith_surface_or_file(const std::string& path, double alpha) {
  if (!path.empty()) return std::make_unique<microgeom::Heightfield>(microgeom::load_heightmap_exr(path));
  microgeom::AssemblyParams p;
  p.assembly = "smith";
  p.alpha_x = p.alpha_y = alpha;
  p.resolution = 1024;
  p.seed = 1;
  return std::make_unique<microgeom::Heightfield>(microgeom::build_assembly(p));
}

// A console reporter that also keeps every repetition's rate (items per second) and CPU time per ray
// (counter cpu_ns_per_ray), for the tables of medians printed at the end (PrintRatios() of a subclass).
class RepetitionReporter : public benchmark::ConsoleReporter {
public:
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& run : runs) {
      if (run.run_type == Run::RT_Iteration && !run.error_occurred) keep(run);
    }
  }

protected:
  virtual void keep(const Run& run) {
    const auto rate = run.counters.find("items_per_second"), cpu = run.counters.find("cpu_ns_per_ray");
    if (rate == run.counters.end() || cpu == run.counters.end()) return;
    rate_[run.benchmark_name()].push_back(double(rate->second));
    cpu_[run.benchmark_name()].push_back(double(cpu->second));
  }
  Samples rate_, cpu_;
};

// Google Benchmark's main with `reporter` (a ConsoleReporter with PrintRatios(), printed at the end).
template <class Reporter> int run_benchmarks(int argc, char** argv, Reporter& reporter) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  reporter.PrintRatios();
  benchmark::Shutdown();
  return 0;
}

}  // namespace microsim::bench
