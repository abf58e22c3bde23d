// scatter: a rough GGX dielectric's energy split over Blender Cycles' rough-glass node grid (the layouts of
// scatter/albedo_glass_layout.h: 16 roughness x 16 mu x 16 index nodes, ior or, for the -inv twin, light from
// inside at relative index 1 / ior) from the Smith random walk (Heitz, Hanika, d'Eon, Dachsbacher 2016,
// "Multiple-Scattering Microfacet BSDFs with the Smith Model", sec. 5.2: the dielectric walk, every order).
//
// A dielectric absorbs nothing: the walk's every-order E = E_R + E_T is 1 less the unfinished weight. What the
// walk adds is the split: per node, with standard errors, E_R and E_T of every order and E1_R, E1_T of order 1,
// so that the multiple scattering a compensation lobe returns, E - E1, and the share of it that is transmitted,
// (E_T - E1_T) / (E - E1), are measured rather than assumed.
//
// Masking: the walk's order 1 is single scattering with the Smith microsurface's own masking
// (RefractionMasking::smith_microsurface: the transmission G2 of microfacet/bsdf.h), which is not what Cycles'
// tables hold (RefractionMasking::height_correlated, the reflection form for both lobes, which Cycles'
// glass closure evaluates). So order 1 here matches `albedo --model analytic --material dielectric:ETA` at the
// node, not the analytic glass layout table. The node of roughness 0 (alpha 1e-8) is walked at kMinAlpha, as
// the layout computes it (marked out of range); the first index node (ior 1 + 2e-8) is walked as that dielectric.
//
// Each node is one walk of `paths` paths from its own seed (albedo_cell_seed(seed, z, y * 16 + x)); nodes run
// one after another, each node's paths on the block runner: the same seed gives the same table whatever
// run.threads. Never prints.
#pragma once

#include "core/estimate.h"
#include "core/run_control.h"
#include "scatter/albedo_glass_layout.h"
#include "scatter/scatter_setup.h"
#include "scatter/smith_walk.h"

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace microsim {

struct GlassWalkRequest {
  GlassLayout layout;                 // glass_layouts(): its node grid and side
  std::uint64_t paths = 10'000;       // per node, >= 1
  std::uint64_t seed = 1;
  int max_order = kDefaultMaxOrder;   // in [1, kMaxOrderCap]
  WalkKernel walk_kernel = WalkKernel::scalar;  // scatter/smith_walk.h (lanes: other random numbers, same walk)
  RunControl run;                     // threads, cancel; progress "glass walk table" in paths
};

// The quantities of a node, in this order: E_R / E_T reflected (back to the light's side) / transmitted.
inline constexpr std::array<const char*, 7> kGlassWalkQuantities{"E", "E_R", "E_T", "E1", "E1_R", "E1_T", "unfinished"};
using GlassWalkNode = std::array<Estimate, 7>;

struct GlassWalkTable {
  GlassWalkRequest request;  // as given, without its RunControl
  std::vector<double> roughness, alphas, mus, index_coordinates, iors;  // the layout's axes (glass_layout_coordinate)
  std::vector<bool> in_range;        // per roughness node: alpha >= kMinAlpha
  std::vector<GlassWalkNode> cells;  // [(z * mus + y) * roughness + x], Cycles' storage order
  double seconds = 0;
  std::size_t index(std::size_t x, std::size_t y, std::size_t z) const { return (z * mus.size() + y) * roughness.size() + x; }
};

// One node (x, y, z) of the layout, as the table computes it (bit for bit: same seed, same walk); nullopt when
// cancelled; std::invalid_argument for a node outside the layout or a bad request.
std::optional<GlassWalkNode> glass_walk_node(const GlassWalkRequest& request, std::size_t x, std::size_t y, std::size_t z);
// The table: std::invalid_argument naming a bad value (paths 0, max_order out of range); nullopt when cancelled.
std::optional<GlassWalkTable> glass_walk_table(const GlassWalkRequest& request);
// One line per node: x,y,z,roughness,alpha,mu,t,ior, then per quantity Q its Q,Q_se; after `#` comments naming
// the layout, the walk and its masking.
std::string glass_walk_csv(const GlassWalkTable& table);
// kind "glass walk table": layout, masking note, axes, paths, seed, max_order, walk_kernel, seconds, and per
// quantity Q {value, error} nested [z][y][x].
nlohmann::json glass_walk_json(const GlassWalkTable& table);

}  // namespace microsim
