#include "scatter/scatter_setup.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <stdexcept>

namespace microsim {

void check_scatter_options(const ScatterOptions& o) {
  if (o.paths == 0) throw std::invalid_argument("scatter: the number of paths must be positive");
  if (o.max_order < 1 || o.max_order > kMaxOrderCap) {
    throw std::invalid_argument(fmt::format("scatter: order cap {} (expected 1 to {})", o.max_order, kMaxOrderCap));
  }
  if (!o.wi.allFinite() || std::abs(o.wi.norm() - 1.0) > 1e-9 || o.wi.z() == 0.0) {
    throw std::invalid_argument(fmt::format("scatter: wi ({}, {}, {}) must be a unit direction off the horizon",
                                            o.wi.x(), o.wi.y(), o.wi.z()));
  }
  if (o.rows < 1 || 2 * o.rows > kMaxBinningRows) {
    throw std::invalid_argument(fmt::format("scatter: {} rows per hemisphere (1 to {})", o.rows, kMaxBinningRows / 2));
  }
}

ScatterHistogram empty_scatter_histogram(const ScatterOptions& o, const std::string& producer,
                                         const std::string& measurement) {
  check_scatter_options(o);
  const DirectionBinning sphere = DirectionBinning::hemispheres(o.rows);
  std::vector<bool> reflection(std::size_t(sphere.size()));
  for (int b = 0; b < sphere.size(); ++b) reflection[std::size_t(b)] = b < sphere.size() / 2;  // rows from the top
  std::vector<std::string> channels;
  for (int c = 0; c < o.material.channels(); ++c) channels.push_back(o.material.channel_name(c));
  ScatterHistogram h(sphere.describe().dump(), std::size_t(sphere.size()), std::move(reflection), std::move(channels));
  const BlockPlan plan{o.paths, kPathsPerBlock};
  h.provenance = {producer, measurement, o.seed, plan.blocks(), selected_blocks(plan, o.blocks)};
  return h;
}

}  // namespace microsim
