// measure: the masking measurement of `microsim trace masking --surface S` (one view of one heightfield),
// end to end, as a library call; and its partial results: a run over some of its blocks (a shard, or a
// run cancelled part way) records its provenance (the run's parameters, seed, blocks) and its exact sums
// (trace/masking.h MaskingSums), so that the parts of a run merge into the whole run, bit for bit: the
// merge recomputes the view's setup from the surface and the result from the summed sums exactly as the
// single run does.
#pragma once

#include "core/block_runner.h"
#include "core/run_control.h"
#include "microgeom/heightfield.h"
#include "stats/histogram.h"
#include "trace/heightfield_trace.h"
#include "trace/masking.h"
#include "trace/smith_prediction.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace microsim {

inline constexpr int kMaskingVndfRows = 8;  // rows of the lobe bins of the VNDF beside a masking run (sphere: 2 x + 1)

struct MaskingRequest {
  double theta_deg = 0, phi_deg = 0;  // the view
  std::optional<double> theta_l_deg;  // a light for G2(v, l), if given
  double phi_l_deg = 0;
  double cone_deg = 5.0;              // mirror cone of the pair
  std::uint64_t samples = 1'000'000;  // surface points of the whole run
  std::uint64_t seed = 1;
  int bins = 10;                      // bins of <v, m> and of height
  double grazing_share = 0.02;
  std::uint64_t vndf_rays = 0;        // also trace the VNDF (measure_masking_vndf); never with `blocks`
  std::optional<BlockRange> blocks;   // sample only these blocks of kSamplesPerBlock points (a shard)
  RunControl run;
};

// A heightfield ready to be measured: its Smith predictions (analytic reference and own NDF) and, when it
// is to be traced, its ray-tracing scene (a merge needs none). `field` must outlive it.
struct MaskingSurface {
  // `path` names the heightmap in the reports and the provenance.
  MaskingSurface(const microgeom::Heightfield& field, std::string path, HeightfieldGeometry geometry, bool trace);
  const microgeom::Heightfield& field;
  std::string path;
  HeightfieldGeometry geometry;
  std::string reference_source;  // "metadata" or "fitted"
  AnalyticSmith analytic;
  EmpiricalSmith empirical;
  std::unique_ptr<HeightfieldScene> scene;  // null unless traced
};

// The VNDF traced beside a masking run (sphere and lobe bins, against Smith with both NDFs).
struct MaskingVndf {
  TraceResult trace;
  HeightfieldVndfDiagnostics diagnostics;
  std::vector<VndfComparison> comparisons;
};

// One view's masking measurement, with what a merge needs of it.
struct SurfaceMasking {
  MaskingRequest request;
  MaskingResult result;             // result.sums: the exact sums of its blocks
  nlohmann::json parameters;        // the run's parameters every part must share (masking_parameters)
  Provenance provenance;            // "trace masking", parameters, seed, blocks of the whole run
  std::optional<MaskingVndf> vndf;  // measure_masking_vndf, if run
};

// The tracer's options of a request (trace/masking.h): its samples, seed, blocks, run, bins, cone, light.
MaskingOptions masking_options(const MaskingRequest& request);

// Samples the view (the request's blocks, or all). Throws std::invalid_argument for a surface without a
// scene and for what estimate_masking refuses.
SurfaceMasking measure_masking(const MaskingSurface& surface, const MaskingRequest& request);
// Traces request.vndf_rays rays along -v. Throws std::invalid_argument when request.blocks is set (the VNDF
// of a heightfield is sharded by `trace vndf --surface S --shard K/N`) or the surface has no scene.
MaskingVndf measure_masking_vndf(const MaskingSurface& surface, const MaskingRequest& request);

// The leak test's threshold in standard errors: at 4 SE a correct tracer fails with probability 6e-5
// per view (normal tails).
inline constexpr double kLeakSigmas = 4.0;
// The leak test failed: a ray leaked through the surface, or E[w V] / cos(theta_v) is more than
// kLeakSigmas standard errors from 1.
bool leak_failed(const MaskingResult& r);
// Cancelled, or the VNDF requested but not traced (Ctrl-C before its trace): the run is partial.
bool masking_is_partial(const SurfaceMasking& m);
// The JSON report of a run (`trace masking --surface S --json`, and the merge of its parts): its part
// (masking_part_json), the surface, the view, the masking results, the leak test, the VNDF when traced.
// The command adds the peak memory (what measures the machine).
nlohmann::json surface_masking_json(const SurfaceMasking& m, const MaskingSurface& surface);

// ---- partial results ---------------------------------------------------------------------------------------

// What a masking report carries for a merge: {"provenance": {"producer": "trace masking", "parameters":
// {...}, "seed", "blocks": [B, E], "total_blocks"}, "sums": {...}}, every exact sum as 32 hex digits (its
// 128-bit fixed-point value: the high then the low 64 bits), so that it round-trips exactly.
nlohmann::json masking_part_json(const SurfaceMasking& m);

struct MaskingPart {
  Provenance provenance;
  nlohmann::json parameters;
  MaskingSums sums;
  double seconds = 0;  // sampling time (summed over merged parts)
  // From the parameters: the surface the run traced, as it was loaded, and the geometry of its scene.
  std::string surface;
  double tile_size = 0;
  HeightfieldGeometry geometry = HeightfieldGeometry::triangles;
};

// Whether a JSON report is a trace masking part (its provenance's producer is "trace masking").
bool is_masking_part(const nlohmann::json& report);
// The part a masking report carries. Throws HistogramMergeError naming what is missing or malformed.
MaskingPart read_masking_part(const nlohmann::json& report);
// The parts of one run joined: their sums added exactly, their block ranges joined. Throws
// HistogramMergeError naming the problem: parts of different runs (the first parameter that differs, the
// seed), or blocks repeated or missing (named as ranges).
MaskingPart merge_masking_parts(const std::vector<MaskingPart>& parts);
// Adds one part of the run `sum` holds some blocks of (its parameters and seed) to it, exactly: its sums and
// its shadow rays; the blocks and the time are the caller's. merge_masking_parts adds its parts' sums the same
// way; the experiment a round's parts in block order. Throws HistogramMergeError for a part of another run or
// of other bins.
void add_masking_part(SurfaceMasking& sum, const MaskingPart& part);
// The measurement of a (merged) part, computed exactly as measure_masking computes it for the same sums.
// Throws HistogramMergeError when `surface` is not the surface the part was traced on.
SurfaceMasking analyse_masking_part(const MaskingPart& part, const MaskingSurface& surface);

}  // namespace microsim
