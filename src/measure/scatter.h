// measure: the scattering measurement of `microsim scatter` and of an experiment's scattering quantity, as a
// library call: light arriving along -wi on a microsurface, where it leaves histogrammed per bounce order over
// the hemispheres binning (stats/scatter_histogram.h). Three models: the single-scattering expectation of a
// GGX or Beckmann surface by cubature (scatter/analytic_scatter.h: exact, no paths), the Smith random walk
// (Heitz et al. 2016, scatter/smith_walk.h), and every bounce traced on an explicit heightfield's scene
// (scatter/surface_scatter.h). A sampled model's histogram records its seed and blocks (ScatterOptions::blocks:
// a shard, a rank's part of a round): the parts of a run merge into the whole run bit for bit.
#pragma once

#include "core/ndf_kind.h"
#include "scatter/analytic_scatter.h"
#include "scatter/smith_walk.h"
#include "scatter/surface_scatter.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <map>
#include <string>
#include <utility>

namespace microsim {

// The order-1 expectation of an `ndf` surface of roughness `alpha` (alpha_x, alpha_y) seen from wi, binned in
// `rows` rows per hemisphere. Deterministic; throws Cancelled when run.cancel is set.
ScatterExpectation measure_analytic_scatter(NdfKind ndf, std::pair<double, double> alpha, const Vec3<double>& wi,
                                            const Material& material, int rows, const RunControl& run);

// A sampled model: the histogram of the paths a request asks for (all of its blocks, or options.blocks).
using ScatterPaths = std::function<ScatterHistogram(const ScatterOptions&)>;
// The Smith walk on `surface`.
ScatterPaths smith_walk_paths(const SmithMicrosurface& surface);
// Every bounce traced on `scene` (which must outlive the function); the tracer's diagnostics of a request
// written to `*diagnostics` when it is given (and outlives the function).
ScatterPaths surface_paths(const HeightfieldScene& scene, SurfaceScatterDiagnostics* diagnostics = nullptr);

// The report of a scatter file (`scatter --json`, `merge --json`): its summary (scatter_summary_json), the
// notes, and what each geometric hemisphere holds: light arriving from above (note theta < 90) is reflected
// into the upper one, light from inside a dielectric (theta > 90) is transmitted into it; "" without theta.
nlohmann::json scatter_report_json(nlohmann::json summary, const std::map<std::string, std::string>& notes);

}  // namespace microsim
