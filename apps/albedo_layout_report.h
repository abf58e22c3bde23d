// microsim CLI: `microsim albedo --layout L` (a table in a renderer's layout: scatter/albedo_layout.h,
// written with scatter/albedo_layout_io.h, each file atomically) and `microsim albedo --grade TABLE
// --layout L` (scatter/albedo_grade.h: exit 0 every node within the tolerance, 1 a node beyond it).
#pragma once

#include "scatter/albedo_glass_layout.h"
#include "scatter/albedo_layout.h"

#include <cstdint>
#include <string>

namespace microsim::app {

struct LayoutOutputs {
  std::string exr, csv, json, encoded, centres;  // "" for none (exr is required)
};

// Computes and writes the layout's table; prints its summary (E_avg, the interpolation error). Returns
// kExitOk, or kExitInterrupted with nothing written.
// ndf: the mirror's distribution (GGX, what the renderers ship, or Beckmann in the same grid and encoding).
int run_albedo_layout(const AlbedoLayout& layout, NdfKind ndf, double tolerance, int threads,
                      const LayoutOutputs& outputs);

struct GlassOutputs {
  std::string csv, encoded, json;  // "" for none
};

// Computes a glass layout's table (scatter/albedo_glass_layout.h) and writes its CSV, encoded text and JSON;
// prints E_avg's corners and the largest error estimate. kExitOk, or kExitInterrupted (nothing written).
int run_albedo_glass_layout(const GlassLayout& layout, double tolerance, int threads, const GlassOutputs& outputs);

// Reads `table` (.exr, or the .csv microsim writes for a layout; UsageError when unreadable or not in the
// layout), grades it and prints the result; `json`: also the whole grade. Returns kExitOk when every node is
// within `tolerance`, kExitRejected otherwise, kExitInterrupted (nothing written) when cancelled.
// ndf: the distribution the table is of (the reference is that mirror's).
int run_albedo_grade(const AlbedoLayout& layout, NdfKind ndf, const std::string& table, double tolerance,
                     std::uint64_t table_samples, int threads, const std::string& json);

// Reads `table` (a glass layout's .csv as microsim writes it, or the .txt of values as Cycles prints them;
// UsageError when unreadable or not in the layout), grades it (scatter/albedo_glass_grade.h) and prints the
// result; exit codes as run_albedo_grade.
int run_albedo_glass_grade(const GlassLayout& layout, const std::string& table, double tolerance,
                           std::uint64_t table_samples, int threads, const std::string& json);

}  // namespace microsim::app
