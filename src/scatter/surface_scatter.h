// scatter: multiple scattering on an explicit periodic heightfield, measured by tracing every bounce
// (Heitz 2018: the microsurface ray traced, bounce by bounce).
//
// options.paths paths (scatter/surface_path.h: uniform (x, y) over the tile, along -options.wi, from
// above the surface, or from below it inside the solid for a dielectric lit from inside) are followed
// until they leave the surface or reach options.max_order facet events. Each path that leaves is added
// to the ScatterHistogram (stats/scatter_histogram.h) at its order (1, 2, 3, 4, 5+) in the bin of its
// outgoing direction in the hemispheres binning of options.rows rows per hemisphere, with its weight per
// material channel. The binning is geometric: the upper hemisphere holds the paths that left upward
// (for light from inside: the light transmitted into the upper medium), the lower one those that left
// downward into the lower medium. A path stopped at the order cap adds its weight to add_unfinished; a
// path the tracer lost (surface_path.h, PathLoss) to add_lost; nothing is dropped: per launched path,
// sum of albedos + unfinished + lost = the mean initial weight, 1.
//
// The histogram estimates the BSDF times the cosine: the weight per launched path that leaves into a
// solid angle dw around wo is f(wi, wo) |wo.z| dw, f the surface's BRDF (upper) or BTDF (lower), with
// the BTDF in radiance units (Walter et al. 2007, eq. 21, with its eta_o^2: flux weights, section 5.3).
//
// Engine: blocks of kPathsPerBlock paths (core/block_runner.h); block b draws from CounterRng(seed, b):
// path i its origin from draws 2i and 2i + 1 (exactly the origins of trace_vndf_heightfield for the same
// seed and block), its facet events from its own range of draws after them (path_event_stream,
// surface_path.h; SurfacePathTracer::trace_block). Sums are exact (ExactSum), so the result depends only on (options, block
// range): shards (options.blocks) merge into the unsharded run bit for bit, and a cancelled run
// (options.run) returns the completed prefix of blocks, marked partial. Never prints.
#pragma once

#include "microgeom/heightfield.h"
#include "scatter/scatter_setup.h"
#include "scatter/surface_path.h"
#include "trace/heightfield_trace.h"

#include <cstdint>
#include <string>

namespace microsim {

inline constexpr const char* kSurfaceScatterProducer = "scatter surface";

// What the tracer did, beyond the histogram (counts over the blocks run).
struct SurfaceScatterDiagnostics {
  std::uint64_t paths = 0;
  std::uint64_t traced = 0;        // HeightfieldScene::trace calls: one per primary ray and one per event
  std::uint64_t segments = 0;      // Embree calls made by them
  std::uint64_t facet_events = 0;  // bounces
  std::uint64_t edge_grazes = 0;   // convex-edge grazes passed over (heightfield_trace.h)
  std::uint64_t reflected = 0, transmitted = 0, unfinished = 0;  // paths, by how they ended
  std::uint64_t unbinned = 0;      // paths that left into no bin of their side (counted as escaped unbinned)
  // Lost paths, by cause (PathLoss).
  std::uint64_t leaked = 0, crossed_unseen = 0, unresolved = 0, wrong_side = 0;
  std::uint64_t lost() const { return leaked + crossed_unseen + unresolved + wrong_side; }
  void add(const SurfaceScatterDiagnostics& other);
  bool operator==(const SurfaceScatterDiagnostics&) const = default;
};

// The run's canonical description (ScatterHistogram::provenance.measurement): the surface (resolution,
// tile, a hash of its heights), wi, the material, the order cap, the rows and the number of paths; not
// the seed or the blocks. Parts of one run have equal measurements.
std::string surface_scatter_measurement(const microgeom::Heightfield& field, const ScatterOptions& options);

// Runs options.paths paths (the blocks of options.blocks, or all) on the scene. Throws
// std::invalid_argument for bad options (check_scatter_options, and light from inside on a material that
// does not transmit). `diagnostics` (if given) receives the counts of the blocks run.
ScatterHistogram scatter_on_surface(const HeightfieldScene& scene, const ScatterOptions& options,
                                    SurfaceScatterDiagnostics* diagnostics = nullptr);
// The same on a heightfield (its Embree scene is built for the call).
ScatterHistogram scatter_on_surface(const microgeom::Heightfield& field, const ScatterOptions& options,
                                    SurfaceScatterDiagnostics* diagnostics = nullptr);

}  // namespace microsim
