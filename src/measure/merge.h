// measure: the merge of the partial results of one run into the whole run (`microsim merge`, Python
// `merge`). A part is a JSON file with provenance and exact sums (stats/part_json.h), written by
// `trace vndf --shard K/N`, `scatter --shard K/N`, `trace masking --shard`, `validate --shard`,
// `stability --shard` or `albedo --shard` (measure/albedo.h), its kind told by its provenance's producer. The parts must come from one run (every
// run attribute or parameter equal, same binnings, same seed) and together hold every block exactly once;
// they are added in block order, so the merged result is the single run's bit for bit.
//
// The kinds are the table kPartKinds of merge.cpp, the one place that decides a part's kind and its merge.
#pragma once

#include "measure/albedo.h"
#include "measure/masking.h"
#include "measure/validation.h"
#include "measure/vndf.h"
#include "stats/histogram.h"
#include "stats/scatter_histogram.h"
#include "validate/stability.h"

#include <cstdint>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

namespace microsim {

// Parts that do not merge: a part that cannot be read ("part 'P': ..."; an EXR file, the part form of
// earlier versions, is named as such), parts of another kind or of different runs, blocks missing or
// repeated ("cannot merge: ...", the ranges named).
struct MergeError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

enum class PartKind { vndf, scatter, masking, validate, stability, albedo };

// The producer that writes parts of the kind: "trace vndf", "scatter", "trace masking", "validate",
// "stability", "albedo".
const char* part_kind_name(PartKind kind);

// The kind of the parts, all of one kind (MergeError otherwise), by their provenance's producer (every part
// is read: a missing or unreadable one is named).
PartKind merge_kind(const std::vector<std::string>& paths);

struct MergedVndf {
  TracedHistogram histogram;
  std::vector<std::uint64_t> unbinned;  // rays outside the binning, per binning
};

struct MergedScatter {
  ScatterHistogram histogram;
  std::map<std::string, std::string> notes;  // the parts' notes (equal in every part)
};

// The whole run of the parts: the histogram (vndf, scatter), the part (masking, validate, stability) or the
// table (albedo) that the single run would have written.
struct MergedRun {
  PartKind kind = PartKind::vndf;
  std::size_t parts = 0;
  std::variant<MergedVndf, MergedScatter, MaskingPart, ValidationPart, StabilityTable, AlbedoTable> result;
};

// Reads the parts (any order) and merges them. Throws MergeError naming the offending part and the block
// ranges missing or repeated.
MergedRun merge_parts(const std::vector<std::string>& paths);
// The same, the parts' kind already found by merge_kind (a front end checks its options in between).
MergedRun merge_parts(PartKind kind, const std::vector<std::string>& paths);

// A merged trace vndf run on the ellipsoid analysed as the single run is: its target rebuilt from the
// histogram's attributes (roughness, tessellation), its D_v fits, its exact hit fraction.
struct MergedEllipsoid {
  std::unique_ptr<EllipsoidTarget> target;
  EllipsoidVndf vndf;
};
// Throws HistogramMergeError when an attribute is missing or malformed.
MergedEllipsoid analyse_merged_ellipsoid(MergedVndf merged);

// Whether `path` is an EXR file of format microsim-scatter-1 (false for a missing or unreadable file): a
// scattering result, not a part.
bool is_scatter_part(const std::string& path);

}  // namespace microsim
