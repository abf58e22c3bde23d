// experiment: the library calls behind a decision, shared by the planner's pilots and the runs: the albedo
// table request of a spec quantity (scatter/albedo_table.h), the ellipsoid VNDF measurement of a view
// (measure/vndf.h), and the errors the targets are stated in.
#pragma once

#include "experiment/plan.h"
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

// Whether a target applies to a quantity of an albedo table: orders single, the single-scattering albedos
// (E1, E1_R, E1_T); all orders, every albedo the table holds (E, E_R, E_T and the walk's E1s), not the
// unfinished or lost weight.
bool albedo_target_applies(const SpecQuantity& quantity, std::string_view table_quantity);
std::string albedo_target_text(const SpecQuantity& quantity);  // "E1*" or "E*"

// The request of an albedo quantity (model: the decision's; analytic: tolerance; walk: paths, cap, seed).
AlbedoTableRequest albedo_request(const ExperimentSpec& spec, const SpecQuantity& quantity, Model model,
                                  std::uint64_t paths, int max_order, double tolerance, std::uint64_t seed,
                                  const RunControl& run);

// The table albedo_table_json wrote (alphas, mus, weights, quantities, timings), with `request` (the table's
// own, which the JSON names but does not hold whole). Values read back exactly (JSON numbers round-trip);
// null reads as NaN. Throws std::invalid_argument naming a missing or malformed member. For a resumed run.
AlbedoTable albedo_table_from_json(const nlohmann::json& table, const AlbedoTableRequest& request);

// The ellipsoid-oracle request of a VNDF decision: `rays` rays of `seed` from its view, in its quantity's rows.
VndfRequest vndf_request(const ExperimentSpec& spec, const Decision& decision, std::uint64_t rays, std::uint64_t seed,
                         const RunControl& run);

// The largest relative error (error / value) over the cells and E_avg of the quantities of a table the target
// applies to; an infinite one when a value is 0 with a non-zero error.
double worst_relative_error(const AlbedoTable& table, const SpecQuantity& quantity);

// The validator's options of a validation quantity: `samples` drawn from `seed` (0, 0 for a dump, whose
// samples are given) at the quantity's rows and level. The same for the root and every rank of a split one.
ValidationOptions validation_request(const SpecQuantity& quantity, std::uint64_t samples, std::uint64_t seed,
                                     const RunControl& run);

// Bad input in a validation's dump (a file that is not samples, too few of them), naming the spec key.
std::invalid_argument dump_error(const SpecQuantity& quantity, const std::exception& e);
// A dump opened with its columns and frame (SampleFileError when it cannot be read as they say).
DirectionSampleReader open_dump(const SpecQuantity& quantity);
// What a dump claims: its density, its material's BSDF when it holds a BSDF's samples or weights, kept only.
DumpClaims dump_claims(const SpecQuantity& quantity, const SpecMaterial& material);

// ---- the analytic order-1 lobe (orders = "single") -----------------------------------------------------------

// The order-1 lobe of a scattering decision: the single-scattering expectation of its material at its alpha
// and view (light from inside for theta > 90), binned like the walk's lobes (kScatterRows rows per
// hemisphere) by the cubature of scatter/analytic_scatter.h. Deterministic; Cancelled when run.cancel is set.
ScatterExpectation analytic_scatter_lobe(const SpecMaterial& material, const Decision& decision, const RunControl& run);
// The channel-0 order-1 albedo of an expectation: all of it, or what leaves on one side of the surface
// (reflected: the hemisphere of the light's own side).
double expectation_albedo(const ScatterExpectation& lobe, const Direction& view);
double expectation_albedo(const ScatterExpectation& lobe, const Direction& view, ScatterSide side);
// The cubature's summed error estimate (channel 0) over the albedo: to first order a bound on the TV between
// the computed normalised lobe and the exact one (TV = 1/2 sum |p_i - q_i| <= sum |error_i| / W). 0 for an
// exact lobe; infinite when the albedo is 0 with a non-zero error.
double analytic_lobe_error(const ScatterExpectation& lobe, const Direction& view);

// ---- per-order scattering (the Smith walk) ------------------------------------------------------------------

// Rows per hemisphere of a scattering measurement's hemispheres binning (stats/binning.h).
inline constexpr int kScatterRows = 8;

// The walk of a scattering decision: its material's microsurface at the decision's alpha, and the options of
// `paths` paths from the decision's view at its order cap (light from inside for theta > 90).
SmithMicrosurface scatter_surface(const SpecMaterial& material, const Decision& decision);
ScatterOptions scatter_request(const SpecMaterial& material, const Decision& decision, std::uint64_t paths,
                               std::uint64_t seed, const RunControl& run);

}  // namespace microsim::experiment
