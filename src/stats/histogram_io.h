// microsim: traced direction histograms in OpenEXR files (`microsim trace vndf --out HIST.exr`), and
// reading them back (`microsim validate --against HIST.exr`).
//
// Layout (format "microsim-histogram-1"). All binnings of a file share the same number of rows, so each
// is an image of `rows` scanlines by `cols` = 2 rows pixels, pixel (x = col, y = row) = bin
// row * cols + col (DirectionBinning's bin order). Per binning NAME ("sphere", "lobe"), FLOAT channels:
//   NAME.count       the count (exact up to 2^24; beyond, use count_high/count_low)
//   NAME.count_high  floor(count / 2^24)     } exact: count = count_high * 16777216 + count_low,
//   NAME.count_low   count mod 2^24          } both integers below 2^24, exactly representable in float
//   NAME.stderr      standard error of the count, multinomial given the hits: sqrt(c (1 - c / hits))
//   NAME.expected    hits x the bin's analytic probability under D_v (only when computed)
// String attributes:
//   format = "microsim-histogram-1", binnings = "sphere,lobe" (the order of the binnings),
//   binning.NAME = DirectionBinning::describe() as JSON (enough to rebuild it),
//   surface ("ellipsoid"), target ("quadric" or "mesh level K (N triangles)"), mesh_level (-1 = quadric),
//   alpha ("ax,ay"), theta, phi (degrees), wi ("x,y,z"), rays, hits, seed, partial ("true"/"false"),
//   rays_per_second, threads, channel_layout (a one-line description of the channels above).
// Numbers are written with enough digits to read back exactly.
#pragma once

#include "stats/binning.h"

#include <cstdint>
#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace microgeom {
struct ExrImage;
}

namespace microsim {

struct HistogramIoError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct TracedHistogram {
  std::vector<DirectionBinning> binnings;           // all with the same rows
  std::vector<std::vector<std::uint64_t>> counts;   // per binning, per bin
  std::vector<std::vector<double>> probability;     // per binning: analytic bin probabilities (may be empty)
  std::uint64_t rays = 0, hits = 0;
  bool partial = false;
  // Run parameters (surface, target, alpha, theta, phi, wi, seed, ...), written as string attributes.
  std::map<std::string, std::string> attributes;

  // Index of the binning of that kind, or -1.
  int find(BinningKind kind) const;
};

// Writes atomically (temporary file + rename; nothing left behind on failure). Throws HistogramIoError.
void write_histogram_exr(const std::filesystem::path& path, const TracedHistogram& histogram);
// Reads a file written by write_histogram_exr; throws HistogramIoError naming the file and the problem
// (not an EXR, not a microsim histogram, a missing channel, a malformed binning description, counts
// that are not non-negative integers, sizes that disagree).
// Every attribute is checked strictly: rays and hits are plain decimal counts (no sign, no overflow) with
// hits <= rays; partial is "true" or "false"; binnings lists known names (sphere, lobe), none twice;
// each binning.NAME matches the image's rows and columns; every channel belongs to a listed binning and
// NAME.count agrees with the exact count; NAME.expected is finite and >= 0. Messages quote at most a
// short escaped excerpt of a bad value. The EXR reader's size limits apply (kMaxExrDecodedBytes).
TracedHistogram read_histogram_exr(const std::filesystem::path& path);
// The same checks on an image already read (the fuzz target's entry point); `name` names it in messages.
TracedHistogram histogram_from_exr(const microgeom::ExrImage& image, const std::string& name);
// Whether an image says it is a traced histogram (its format attribute), before any other check.
bool is_traced_histogram_image(const microgeom::ExrImage& image);

}  // namespace microsim
