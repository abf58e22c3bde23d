// measure: the VNDF measurement of `microsim trace vndf`, end to end, as a library call: trace the
// ellipsoid (exact quadric or mesh) or a heightfield in the validator's sphere and lobe bins, analyse the
// histogram against the analytic reference, and record the run in the histogram's attributes, including
// its provenance (seed, block range of the whole run), so that a partial result (a shard, or a run
// cancelled part way) can be merged with the others into the whole run, bit for bit.
#pragma once

#include "core/block_runner.h"
#include "core/run_control.h"
#include "microgeom/heightfield.h"
#include "stats/histogram.h"
#include "stats/histogram_io.h"
#include "trace/heightfield_trace.h"
#include "trace/masking.h"
#include "trace/smith_prediction.h"
#include "trace/trace_vndf.h"
#include "validate/compare.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace microsim {

struct VndfRequest {
  double theta_deg = 0, phi_deg = 0;
  std::uint64_t rays = 10'000'000;  // rays of the whole run
  std::uint64_t seed = 1;
  int rows = 31;                    // rows of the sphere and lobe binnings
  std::optional<BlockRange> blocks; // trace only these blocks of kRaysPerBlock rays (a shard)
  // A heightfield's tracer: the pyramid walk, or Embree's triangles or grid (the same hits: heightfield_trace.h).
  HeightfieldGeometry geometry = kDefaultHeightfieldGeometry;
  RunControl run;
};

// The ellipsoid oracle's measurement.
struct EllipsoidVndf {
  TracedHistogram histogram;  // counts, analytic probabilities, run attributes and provenance
  TraceResult trace;          // rays, hits, unbinned, timing, blocks
  TraceAnalysis analysis;     // against the analytic D_v
  double expected_hit_fraction = 0;
};
EllipsoidVndf measure_ellipsoid_vndf(const EllipsoidTarget& target, const VndfRequest& request);

// A heightfield's measurement: Smith's D_v with the analytic reference NDF and with the surface's own.
struct HeightfieldVndf {
  TracedHistogram histogram;
  TraceResult trace;
  HeightfieldVndfDiagnostics diagnostics;
  std::vector<VndfComparison> comparisons;  // per binning
  std::string reference_source;             // "metadata" or "fitted"
};
// The largest TV noise floor (validate/compare.h noise_floor_tv) and the largest TV to the analytic D_v over a
// measurement's binnings.
double vndf_noise_floor(const EllipsoidVndf& measurement);
double vndf_total_variation(const EllipsoidVndf& measurement);
double heightfield_noise_floor(const HeightfieldVndf& measurement);
double heightfield_total_variation(const HeightfieldVndf& measurement);
// `surface` names the heightmap in the attributes (its path).
HeightfieldVndf measure_heightfield_vndf(const microgeom::Heightfield& field, const std::string& surface,
                                         const VndfRequest& request);
// The rays alone on `scene` (the Embree scene of `field`, which the caller keeps between calls): the counts,
// the run's attributes and the tracer's diagnostics, no comparison (`comparisons` empty; the histogram's
// probabilities unset). analyse_heightfield_vndf of it is measure_heightfield_vndf's result, but for `trace`
// (its timing). For rounds whose sum is analysed once: a rank's part, a round added to the earlier ones.
HeightfieldVndf trace_heightfield_vndf(const HeightfieldScene& scene, const microgeom::Heightfield& field,
                                       const std::string& surface, const VndfRequest& request);

// The view of a trace vndf histogram, exactly as the run computed it (from its attributes theta, phi).
Vec3<double> vndf_view(const TracedHistogram& histogram);

// The run a trace vndf histogram records in its attributes, read strictly (the one reader of them, for
// the reports and the merge): throws HistogramMergeError naming a missing or malformed attribute.
struct VndfRunRecord {
  double theta_deg = 0, phi_deg = 0;
  std::uint64_t rays_requested = 0, seed = 0, threads = 0;
  BlockRange blocks;              // attribute "blocks" = "B,E"
  std::uint64_t total_blocks = 0;
  std::string surface, target;    // "ellipsoid" or the heightmap's path; what was traced
  int mesh_level = -1;            // the ellipsoid's tessellation level (-1: the exact quadric, or a heightfield)
};
VndfRunRecord vndf_run_record(const TracedHistogram& histogram);

// The keys every VNDF report shares (`trace vndf --json`, `merge --json`): the view, the run, its
// provenance; `out` the histogram file written.
nlohmann::json vndf_run_json(const TracedHistogram& h, const TraceResult& r, const std::string& out);
// The JSON report of an ellipsoid run: vndf_run_json and the target, the hit fraction, the analysis.
nlohmann::json ellipsoid_vndf_json(const EllipsoidVndf& m, const EllipsoidTarget& target, const std::string& out);

// A heightfield as reports record it: path, resolution, tile, heights, metadata, analytic reference
// (`source`: "metadata" or "fitted").
nlohmann::json surface_json(const microgeom::Heightfield& field, const std::string& path, const AnalyticSmith& analytic,
                            const std::string& source);
// The JSON report of a heightfield run (`trace vndf --surface S --json`): vndf_run_json, the surface, the
// tracer's diagnostics, the comparisons with Smith's D_v (the lobe bins' as the headline keys).
nlohmann::json heightfield_vndf_json(const HeightfieldVndf& m, const microgeom::Heightfield& field, const std::string& out);

// ---- partial results -------------------------------------------------------------------------------------

// The provenance a trace vndf histogram records: seed, block range, blocks of the run (attributes
// "seed", "blocks" = "B,E", "total_blocks", "block_size", "unbinned" = per binning).
Provenance vndf_provenance(const TracedHistogram& histogram);

// The part of `trace vndf --shard K/N` as JSON (stats/part_json.h): {"provenance": {"producer": "trace vndf",
// "parameters": the attributes that define the run (strings; not the seed and blocks), "seed", "blocks",
// "total_blocks"}, "rays", "hits", "partial", "binnings": [descriptions], "counts": [per binning, per bin],
// "attributes": the attributes of this part alone (threads, unbinned, ...)}. Counts are integers: exact.
inline constexpr const char* kVndfPartProducer = "trace vndf";
nlohmann::json vndf_part_json(const TracedHistogram& histogram);
// The histogram a part holds, its attributes as the histogram written had them (no probabilities). Throws
// HistogramMergeError naming what is missing or malformed ("not a trace vndf part: WHERE ...").
TracedHistogram read_vndf_part(const nlohmann::json& report);

// The parts of one run merged: counts, rays, hits and unbinned summed, the block ranges joined. Throws
// HistogramMergeError naming the problem: parts of different runs (the first attribute that differs),
// different binnings, or blocks repeated or missing (named as ranges). `unbinned` receives the sum.
TracedHistogram merge_vndf_parts(const std::vector<TracedHistogram>& parts, std::vector<std::uint64_t>& unbinned);
// Adds one part (or one round) to a running sum of the same binnings, exactly: its counts, rays and hits and
// its heightfield diagnostics to `sum`, its unbinned rays (attribute "unbinned") to `unbinned`; sum's other
// attributes (blocks, unbinned) are the caller's to set. merge_vndf_parts adds its parts with it; the
// experiment adds a round's parts in block order, and its rounds. Throws HistogramMergeError for binnings of
// other sizes or a malformed attribute.
void add_vndf_part(TracedHistogram& sum, std::vector<std::uint64_t>& unbinned, const TracedHistogram& part);
// Adds a part's (or a round's) heightfield tracer diagnostics (backfacing, edge_grazes, leaked, unresolved) to
// those `sum` records; an ellipsoid histogram has none. Throws HistogramMergeError for a malformed or missing one.
void add_heightfield_diagnostics(TracedHistogram& sum, const TracedHistogram& part);
// The heightfield tracer's diagnostics a histogram records (all 0 for an ellipsoid's). Throws HistogramMergeError.
HeightfieldVndfDiagnostics heightfield_diagnostics(const TracedHistogram& histogram);

// The analyses of a merged histogram, exactly as measure_*_vndf computes them for the same counts.
EllipsoidVndf analyse_ellipsoid_vndf(TracedHistogram histogram, const std::vector<std::uint64_t>& unbinned);
HeightfieldVndf analyse_heightfield_vndf(TracedHistogram histogram, const std::vector<std::uint64_t>& unbinned,
                                         const microgeom::Heightfield& field);

}  // namespace microsim
