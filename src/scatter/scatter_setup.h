// scatter: what every scattering measurement shares (explicit heightfields, scatter/surface_scatter.h,
// and the Smith random walk, scatter/smith_walk.h): the options of a run and the empty result it fills.
//
// A run launches `paths` paths arriving along -wi, in blocks of kPathsPerBlock (core/block_runner.h:
// block b draws from CounterRng(seed, b)), follows each until it leaves the surface or reaches
// max_order facet events (the weight it still carries is reported as unfinished), and histograms the
// outgoing directions per order over the hemispheres binning of `rows` rows per hemisphere (stats/scatter_histogram.h).
#pragma once

#include "core/block_runner.h"
#include "core/math.h"
#include "core/run_control.h"
#include "microfacet/material.h"
#include "stats/binning.h"
#include "stats/scatter_histogram.h"

#include <cstdint>
#include <optional>
#include <string>

namespace microsim {

inline constexpr std::uint64_t kPathsPerBlock = 4096;
inline constexpr int kDefaultMaxOrder = 100;
inline constexpr int kMaxOrderCap = 100000;

struct ScatterOptions {
  Vec3<double> wi = Vec3<double>::UnitZ();  // toward the light, unit; wi.z() < 0 for light from inside
  Material material = Material::mirror();
  std::uint64_t paths = 1'000'000;
  std::uint64_t seed = 1;
  int max_order = kDefaultMaxOrder;  // >= 1
  int rows = 16;                     // per hemisphere, of the hemispheres binning (stats/binning.h)
  std::optional<BlockRange> blocks;  // a shard of [0, blocks); nullopt: all
  RunControl run;
};

// Throws std::invalid_argument naming the bad value (paths 0, max_order outside [1, kMaxOrderCap],
// a wi that is not a unit, finite, non-horizontal direction, rows outside [1, kMaxBinningRows / 2]).
void check_scatter_options(const ScatterOptions& options);

// The empty result of a run: the hemispheres binning of options.rows rows per hemisphere, the material's channels, the
// provenance (producer, canonical measurement string, seed, total blocks, the selected block range).
ScatterHistogram empty_scatter_histogram(const ScatterOptions& options, const std::string& producer,
                                         const std::string& measurement);

}  // namespace microsim
