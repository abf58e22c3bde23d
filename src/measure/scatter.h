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
#include <vector>
#include <utility>

namespace microsim {

// The order-1 expectation of an `ndf` surface of roughness `alpha` (alpha_x, alpha_y) seen from wi, binned in
// `rows` rows per hemisphere. Deterministic; throws Cancelled when run.cancel is set.
ScatterExpectation measure_analytic_scatter(NdfKind ndf, std::pair<double, double> alpha, const Vec3<double>& wi,
                                            const Material& material, int rows, const RunControl& run);

// A sampled model: the histogram of the paths a request asks for (all of its blocks, or options.blocks).
using ScatterPaths = std::function<ScatterHistogram(const ScatterOptions&)>;
// The Smith walk on `surface`, walked by `kernel` (scatter/smith_walk.h: lanes throws std::invalid_argument where
// smith_walk_lanes_support is false).
ScatterPaths smith_walk_paths(const SmithMicrosurface& surface, WalkKernel kernel = WalkKernel::scalar);
// Every bounce traced on `scene` (which must outlive the function); the tracer's diagnostics of a request
// written to `*diagnostics` when it is given (and outlives the function).
ScatterPaths surface_paths(const HeightfieldScene& scene, SurfaceScatterDiagnostics* diagnostics = nullptr);

// ---- a sampled lobe's noise (the targets of an experiment's scattering quantity) -----------------------------

// The expected TV between an order bin's normalised lobe (channel 0) and its mean: each bin's share
// p_i = w_i / W has a standard error ~ sqrt(w2_i - w_i^2 / n) / W, an error of that size has a mean absolute
// value sqrt(2 / pi) times it, and TV = 1/2 sum |error| (the normalisation's covariance neglected). Falls
// as 1/sqrt(n). 0 for an order bin without weight.
double scatter_order_floor(const ScatterHistogram& histogram, int order_bin);
// The order bins a per-order TV target applies to, as the plan decides them from its pilot: those that may
// carry at least `target` of the escaped albedo (channel 0): their share plus kShareMargin of its standard
// errors. A lighter order moves the whole lobe by less than the target whatever its shape. An experiment's plan fixes
// the set (its decision's targeted_orders) and the run resolves those orders: judged again on each round's
// estimate, an order whose share is near the target entered and left the set with the noise of its share
// (left out by the pilot, in after a small first round: a second round sized for it, 50 times the paths).
inline constexpr double kShareMargin = 2.0;
std::vector<int> targeted_order_bins(const ScatterHistogram& histogram, double target);
// The largest floor over the given order bins.
double scatter_noise_floor(const ScatterHistogram& histogram, const std::vector<int>& order_bins);
// The largest floor over the given order bins that `whole`'s paths would have on the
// 1/sqrt(n) law a long run follows, extrapolated from a pilot (`whole`) and the pilot's first quarter of
// blocks (`quarter`). sqrt(n) floor(n) rises toward its limit C as sparse bins fill (a bin with few hits:
// E sqrt(w2) < sqrt(E w2)), about as C (1 - b / sqrt(n)): C = 2 C(n) - C(n / 4), never below C(n).
double extrapolated_scatter_floor(const ScatterHistogram& quarter, const ScatterHistogram& whole,
                                  const std::vector<int>& order_bins);

// The report of a scatter file (`scatter --json`, `merge --json`): its summary (scatter_summary_json), the
// notes, and what each geometric hemisphere holds: light arriving from above (note theta < 90) is reflected
// into the upper one, light from inside a dielectric (theta > 90) is transmitted into it; "" without theta.
nlohmann::json scatter_report_json(nlohmann::json summary, const std::map<std::string, std::string>& notes);

}  // namespace microsim
