// experiment: the library calls behind a decision, shared by the planner's pilots and the runs: the albedo
// table request of a spec quantity (measured by measure/albedo.h), the ellipsoid VNDF measurement of a view
// (measure/vndf.h), and the errors the targets are stated in.
#pragma once

#include "experiment/plan.h"
#include "measure/albedo.h"
#include "measure/scatter.h"
#include "measure/vndf.h"
#include "scatter/albedo_table.h"
#include "scatter/smith_walk.h"
#include "stats/scatter_expectation.h"
#include "validate/dump_validation.h"
#include "validate/sample_io.h"
#include "validate/validate.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <string_view>

namespace microsim::experiment {

// The facet material of an albedo table: a conductor's is the mirror (Kulla & Conty 2017 tabulate E(mu)
// for F = 1), mirror and dielectric their own.
Material albedo_table_material(const SpecMaterial& material);

// The request of an albedo quantity (model: the decision's; analytic: tolerance; walk: paths, cap, seed).
AlbedoTableRequest albedo_request(const ExperimentSpec& spec, const SpecQuantity& quantity, Model model,
                                  std::uint64_t paths, int max_order, double tolerance, std::uint64_t seed,
                                  const RunControl& run);

// The ellipsoid-oracle request of a VNDF decision: `rays` rays of `seed` from its view, in its quantity's rows.
VndfRequest vndf_request(const ExperimentSpec& spec, const Decision& decision, std::uint64_t rays, std::uint64_t seed,
                         const RunControl& run);

// ---- the analytic order-1 lobe (orders = "single") -----------------------------------------------------------

// The order-1 lobe of a scattering decision: the single-scattering expectation of its material at its alpha
// and view (light from inside for theta > 90), binned like the walk's lobes (kScatterRows rows per
// hemisphere) by the cubature of scatter/analytic_scatter.h. Deterministic; Cancelled when run.cancel is set.
ScatterExpectation analytic_scatter_lobe(const SpecMaterial& material, const Decision& decision, const RunControl& run);
// ---- per-order scattering (the Smith walk) ------------------------------------------------------------------

// Rows per hemisphere of a scattering measurement's hemispheres binning (stats/binning.h).
inline constexpr int kScatterRows = 8;

// The walk of a scattering decision: its material's microsurface at the decision's alpha, and the options of
// `paths` paths from the decision's view at its order cap (light from inside for theta > 90).
SmithMicrosurface scatter_surface(const SpecMaterial& material, const Decision& decision);
// The walk kernel a quantity asked for (read_walk_kernel): lanes when its settings say so, else scalar.
WalkKernel walk_kernel_of(const SpecQuantity& quantity);
ScatterOptions scatter_request(const SpecMaterial& material, const Decision& decision, std::uint64_t paths,
                               std::uint64_t seed, const RunControl& run);

}  // namespace microsim::experiment
