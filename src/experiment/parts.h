// experiment: the parts of a split round (split_rounds.h): what one rank, thread or shard job measured of a
// round's block range, as exact integers (counts, and ExactSum's two halves) in 64-bit words after a header
// (its blocks, whether it was cancelled part way); a drawn validation's tally and a masking round's sums as
// JSON text in such a part. The combine functions add the parts from `first` on (0: the parts of shard jobs
// onto a measurement of no block; 1: the ranks' parts after the root's own, rank 0's) in block order: the
// one-process round, bit for bit. A part that is not rank r's shard of the round (out of block order,
// missing, overlapping) or is malformed is a bug: InternalError.
#pragma once

#include "measure/masking.h"
#include "measure/vndf.h"
#include "scatter/albedo_table.h"
#include "stats/scatter_histogram.h"
#include "validate/battery.h"

#include <optional>
#include <string>
#include <vector>

namespace microsim::experiment {

// VNDF: the counts and the tile tracer's diagnostics (0 on the ellipsoid).
std::string vndf_part(const TraceResult& trace, const HeightfieldVndfDiagnostics& diagnostics);
// A part cancelled before its first block with nothing measured (a tile's build cancelled on that rank).
std::string cancelled_part(const BlockRange& mine);
EllipsoidVndf combine_vndf_parts(EllipsoidVndf own, const std::vector<std::string>& parts, const BlockRange& round,
                                 int first, double seconds);
HeightfieldVndf combine_heightfield_parts(HeightfieldVndf own, const std::vector<std::string>& parts,
                                          const BlockRange& round, int first, double seconds);

// Scattering: every exact sum of the histogram (ScatterHistogram::add_sums order).
std::string scatter_part(const ScatterHistogram& histogram);
ScatterHistogram combine_scatter_parts(ScatterHistogram own, const std::vector<std::string>& parts, const BlockRange& round,
                                       int first);

// A walk albedo table: its cells' estimates as their bits (nullopt: cancelled, no cell).
std::string albedo_part(const BlockRange& cells, const std::optional<AlbedoCells>& estimates);
AlbedoTable cancelled_albedo_table(const AlbedoTableRequest& request);  // a round cut short: no row
// The parts after `cells` (rank 0's, or none): the whole table, or cancelled_albedo_table when a part was.
AlbedoTable combine_albedo_parts(const AlbedoTableRequest& request, AlbedoCells cells, const std::vector<std::string>& parts,
                                 const BlockRange& round, int first, double seconds);

// A drawn validation: a rank's tally (nullopt: cancelled).
std::string validation_part(const BlockRange& blocks, const std::optional<battery::Tally>& tally);
// This process's tally of `blocks`, nullopt when cancelled; the cells of a tally (counts per binning).
std::optional<battery::Tally> own_tally(const SamplerInfo& sampler, const ReferenceDistribution& reference,
                                        ValidationOptions options, const BlockRange& blocks);
std::vector<std::size_t> tally_cells(const battery::Tally& tally);
// The tallies in rank order as one (merge_tallies); Cancelled when any part was cancelled.
battery::Tally merged_validation_tally(const std::optional<battery::Tally>& own, const std::vector<std::size_t>& cells,
                                       const std::vector<std::string>& parts, const BlockRange& round, int first);

// A heightfield masking round: every light's exact sums (nullopt: cancelled).
std::string masking_round_part(const BlockRange& blocks, const std::optional<std::vector<SurfaceMasking>>& round);
std::optional<std::vector<SurfaceMasking>> combine_masking_parts(std::optional<std::vector<SurfaceMasking>> own,
                                                                 const std::vector<std::string>& parts,
                                                                 const BlockRange& round, int first);

// Whether a part was cancelled part way (a prefix of its blocks).
bool part_is_partial(const std::string& part);
// Checks that a part holds rank `rank`'s shard of `round`, whole; InternalError naming what it holds.
void check_whole_part(const std::string& part, const BlockRange& round, int rank, int ranks);
// Rank `rank`'s shard of `round` (rank 0 .. ranks - 1): shard rank + 1 of `ranks`, offset to round.begin.
BlockRange rank_blocks(const BlockRange& round, int rank, int ranks);

}  // namespace microsim::experiment
