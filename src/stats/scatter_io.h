// stats: scattering results in OpenEXR files (`microsim scatter --out HIST.exr`, `microsim merge`,
// `microsim compare-scattering`) and their JSON summaries.
//
// Layout (format "microsim-scatter-1"). The binning is the hemispheres binning (stats/binning.h): an image
// of rows = 2 R scanlines (R per hemisphere: the upper half of the image is reflection, the lower half
// transmission) by cols = 2 rows pixels, pixel (x = col, y = row) = bin row * cols + col. Every channel is
// FLOAT. Channels are named cC.PART.QUANTITY, C the channel's index (its name is in attribute channel_names),
// PART order1, order2, order3, order4, order5plus or total.
//
// A measured histogram (kind "histogram", a ScatterHistogram) has, per channel C and order PART:
//   cC.PART.w            the bin's sum of weights, as a float (to look at; total: the sum over orders)
//   cC.PART.w2           the bin's sum of squared weights, as a float
//   cC.PART.w.hi0..hi2   } the exact sum (core/exact_sum.h, a 128-bit fixed-point integer) as its two
//   cC.PART.w.lo0..lo2   } 64-bit halves, each in three 24-bit limbs (least significant first: bits 0-23,
//   cC.PART.w2.hi0..lo2  } 24-47, 48-63), integers below 2^24 and so exact in a float
// (total has the float channels only: it is derived). An expectation (kind "expectation", a
// ScatterExpectation) has, per channel C:
//   cC.order1.expected             the expected weight per launched path, as a float
//   cC.order1.expected.bits0..2    the double's 64 bits in three 24-bit limbs: read back bit for bit
// String attributes: format, kind, binning (DirectionBinning::describe() of the hemispheres binning, as
// JSON), channel_names (a JSON array of the channel names), producer, measurement, channel_layout; for a
// histogram also paths, seed, total_blocks, blocks ("BEGIN,END"), partial ("true"/"false") and per channel
// the sums outside the bins as "HIGH,LOW" (the two 64-bit halves, decimal): cC.PART.unbinned.w and .w2
// (PART an order), cC.unfinished.w and .w2, cC.lost.w and .w2; for an expectation cC.error_estimate (the
// cubature's, shortest round-trip decimal). Attributes "note.KEY" carry free text (material, wi, ...).
//
// Reading is strict: every attribute and channel is checked (known names only, every expected one
// present, limbs integers in range, each float channel equal to its exact value, the blocks inside the
// run, channels 1 to Material::kMaxChannels, the image's size the binning's), and a message names the file,
// the attribute or channel and quotes at most a short excerpt of the bad value. A histogram read back is
// == the one written, so the merge of parts read from files is the single run bit for bit.
#pragma once

#include "stats/scatter_expectation.h"
#include "stats/scatter_histogram.h"

#include <nlohmann/json_fwd.hpp>

#include <filesystem>
#include <map>
#include <stdexcept>
#include <string>

namespace microgeom {
struct ExrImage;
}

namespace microsim {

struct ScatterIoError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

inline constexpr const char* kScatterFormat = "microsim-scatter-1";

enum class ScatterFileKind { histogram, expectation };

// What a scatter file holds: a measured histogram or an expectation (the other member is empty).
struct ScatterFile {
  ScatterFileKind kind = ScatterFileKind::histogram;
  ScatterHistogram histogram;
  ScatterExpectation expectation;
  std::map<std::string, std::string> notes;  // the "note.KEY" attributes, by KEY
};

// Writes atomically (nothing left behind on failure). Throws ScatterIoError when the result's binning is
// not a hemispheres binning with reflection bins in its upper half, or a note's key is empty.
void write_scatter_exr(const std::filesystem::path& path, const ScatterHistogram& histogram,
                       const std::map<std::string, std::string>& notes = {});
void write_scatter_exr(const std::filesystem::path& path, const ScatterExpectation& expectation,
                       const std::map<std::string, std::string>& notes = {});

// Reads a file written by write_scatter_exr; throws ScatterIoError naming the file and the problem.
ScatterFile read_scatter_exr(const std::filesystem::path& path);
// The same checks on an image already read (the fuzz target's entry point); `name` names it in messages.
ScatterFile scatter_from_exr(const microgeom::ExrImage& image, const std::string& name);
// Whether an image says it is a scatter file (its format attribute): the merge command's dispatch.
bool is_scatter_image(const microgeom::ExrImage& image);

// The JSON summary of a histogram: paths, provenance, partial, and per channel the albedo of every order
// and in total, left into the "upper" and the "lower" hemisphere and "both", each {"value", "standard_error"}
// (per launched path; the hemispheres are geometric: for light from above, upper is reflected and lower is
// transmitted, for light from inside a dielectric the reverse),
// the unbinned, unfinished and lost energy, and the energy balance (escaped + unfinished + lost).
nlohmann::json scatter_summary_json(const ScatterHistogram& histogram);
// The same keys for an expectation (order 1 only; standard errors 0, the cubature's error estimate given).
nlohmann::json scatter_summary_json(const ScatterExpectation& expectation);

}  // namespace microsim
