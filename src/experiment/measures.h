// experiment: the library calls behind a decision, shared by the planner's pilots and the runs: the albedo
// table request of a spec quantity (scatter/albedo_table.h), the ellipsoid VNDF measurement of a view
// (measure/vndf.h), and the errors the targets are stated in.
#pragma once

#include "experiment/plan.h"
#include "measure/vndf.h"
#include "scatter/albedo_table.h"

#include <string_view>

namespace microsim::experiment {

// The facet material of an albedo table: a conductor's is the mirror (Kulla & Conty 2017 tabulate E(mu)
// for F = 1), mirror and dielectric their own.
Material albedo_table_material(const SpecMaterial& material);

// The quantity of an albedo table a target applies to: E1 (orders single) or E (all orders).
std::string_view albedo_target_quantity(const SpecQuantity& quantity);

// The request of an albedo quantity (model: the decision's; analytic: tolerance; walk: paths, cap, seed).
AlbedoTableRequest albedo_request(const ExperimentSpec& spec, const SpecQuantity& quantity, Model model,
                                  std::uint64_t paths, int max_order, double tolerance, std::uint64_t seed,
                                  const RunControl& run);

// The largest relative error (error / value) over the cells and E_avg of one quantity of a table; an
// infinite one when a value is 0 with a non-zero error.
double worst_relative_error(const AlbedoTable& table, std::string_view quantity);

// The largest TV noise floor over the binnings of a VNDF measurement (validate/compare.h noise_floor_tv).
double vndf_noise_floor(const EllipsoidVndf& measurement);
// The largest measured TV against the analytic D_v over its binnings.
double vndf_total_variation(const EllipsoidVndf& measurement);

}  // namespace microsim::experiment
