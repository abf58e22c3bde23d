// scatter: a rough dielectric's energy-compensation table over an index axis, from both sides, in the layout
// of Blender Cycles' rough-glass tables (ggx_glass_E, ggx_glass_Eavg and their inverse-eta twins
// ggx_glass_inv_E, ggx_glass_inv_Eavg): the directional albedo E = E_R + E_T of a GGX dielectric (reflection
// plus refraction, flux), Walter et al. 2007's BSDF with the reflection form of the masking for both lobes,
// RefractionMasking::height_correlated, which Cycles' glass closure evaluates.
//
// Cycles' convention, read from its public source (GlassLayout::source):
//   generator  intern/cycles/app/cycles_precompute.cpp: 16 x 16 x 16 nodes; roughness r = x / 15 and
//              mu = y / 15 clamped to [1e-4, 1], alpha = r^2; the index coordinate t = z / 15 clamped to
//              [1e-4, 0.99] and ior = ior_from_F0(t^4), i.e. sqrt(F0) = t^2 and ior = (1 + t^2) / (1 - t^2)
//              (t = 1e-4 is ior 1 + 2e-8, t = 0.99 is ior 99.5); the twin at 1 / ior (light inside the denser
//              medium); stored data[z][y][x], each value clamped to [0, 1] (saturatef) and printed by
//              std::to_string (6 decimals), a blank line between z slices; E_avg = 2 int E mu dmu over
//              16 x 16 (z, x): data[z][x].
//   reader     intern/cycles/kernel/closure/bsdf_microfacet.h (microfacet_ggx_preserve_energy, the glass
//              branch): ior < 1 reads the inverse table at 1 / ior; z = sqrt(|ior - 1| / (ior + 1));
//              lookup_table_read_3D(rough, mu, z, 16, 16, 16) (intern/cycles/kernel/util/lookup_table.h:
//              coordinate x (size - 1), linear between neighbours): the reader puts node 15 at t = 1 where the
//              generator computed t = 0.99.
//
// The reference per node: single_scattering_albedo (albedo_table.h) of the dielectric ior (inverse: light
// from inside, relative index 1 / ior), reflected and transmitted with their error estimates. Nodes of alpha
// below kMinAlpha (r = 1e-4) are computed at kMinAlpha and marked out of range (as the mirror layouts do).
// The first index node, ior 1 + 2e-8, is 1 in Cycles' float arithmetic: there the interface is invisible and
// E = E_T = (1 + Lambda) / (1 + 2 Lambda) in closed form (the quadrature from inside, at a critical angle
// 2e-4 from grazing, would not converge in reasonable time).
// The Smith walk's every-order albedo of a dielectric is 1 (no absorption: every path leaves), so only the
// single-scattering table carries information; the walk's split of that 1 into reflection and transmission, of
// every order and of order 1, on these nodes: scatter/albedo_glass_walk.h. Never prints.
#pragma once

#include "core/estimate.h"
#include "core/run_control.h"
#include "scatter/albedo_table.h"

#include <nlohmann/json_fwd.hpp>

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace microsim {

struct GlassLayout {
  std::string name, summary, source, quantity;  // quantity: Cycles' table name ("ggx_glass_E")
  int roughness_nodes = 16, mu_nodes = 16, index_nodes = 16;
  bool inverse = false;  // the twin at 1 / ior: light from inside
};

// The registry: cycles-glass, cycles-glass-inv.
const std::vector<GlassLayout>& glass_layouts();
// The glass layout of that name, or nullptr.
const GlassLayout* find_glass_layout(std::string_view name);
std::string glass_layout_names();  // "cycles-glass, cycles-glass-inv"

// Node coordinates as the generator computes them: r and mu at i / (n - 1) clamped to [1e-4, 1]; the index
// coordinate t at k / (n - 1) clamped to [1e-4, 0.99], and its ior (1 + t^2) / (1 - t^2).
double glass_layout_coordinate(int index, int nodes);
double glass_layout_index_coordinate(int index, int nodes);
double glass_layout_ior(double index_coordinate);
// The axes of a table on layout `l` (its roughness, alphas, in_range, mus, index_coordinates and iors members),
// shared by the analytic table and the walk's.
template <class Table> void fill_glass_axes(Table& t, const GlassLayout& l) {
  for (int i = 0; i < l.roughness_nodes; ++i) {
    t.roughness.push_back(glass_layout_coordinate(i, l.roughness_nodes));
    t.alphas.push_back(t.roughness.back() * t.roughness.back());
    t.in_range.push_back(t.alphas.back() >= kMinAlpha);
  }
  for (int j = 0; j < l.mu_nodes; ++j) t.mus.push_back(glass_layout_coordinate(j, l.mu_nodes));
  for (int k = 0; k < l.index_nodes; ++k) {
    t.index_coordinates.push_back(glass_layout_index_coordinate(k, l.index_nodes));
    t.iors.push_back(glass_layout_ior(t.index_coordinates.back()));
  }
}

struct GlassLayoutTable {
  GlassLayout layout;
  double tolerance = 1e-8;
  std::vector<double> roughness, alphas, mus, index_coordinates, iors;
  std::vector<bool> in_range;                // per roughness node: alpha >= kMinAlpha
  std::vector<SingleScatteringAlbedo> cells;  // [(z * mus + y) * roughness + x], Cycles' storage order
  std::vector<Estimate> average;             // E_avg, [z * roughness + x] (empty without averages)
  double seconds = 0;
  std::size_t index(std::size_t x, std::size_t y, std::size_t z) const { return (z * mus.size() + y) * roughness.size() + x; }
};

// Every node (and E_avg per (index, roughness) node: 2 sum_j w_j mu_j E(mu_j) on 32 Gauss-Legendre nodes,
// errors added) in parallel on run.threads; progress "glass layout table" in evaluations; nullopt when
// cancelled. tolerance in [1e-13, 1e-2] (std::invalid_argument otherwise).
std::optional<GlassLayoutTable> glass_layout_table(const GlassLayout& layout, double tolerance,
                                                   const RunControl& run = {}, bool averages = true);

// A value as Cycles stores it: clamped to [0, 1], float, 6 decimals.
double encode_glass_value(double value);
// The table as cycles_precompute prints its values (without the C++ declaration): per z slice, 16 lines of
// 16 comma-separated values (y rows, x columns), a blank line between slices; and E_avg's 16 lines (z) of 16
// (x) when the table has them.
std::string glass_layout_encoded(const GlassLayoutTable& table);
std::string glass_layout_average_encoded(const GlassLayoutTable& table);
// CSV, one line per node: x,y,z,roughness,alpha,mu,t,ior,E,E_error,E_R,E_R_error,E_T,E_T_error,E_encoded
// [,E_avg,E_avg_error], after a header and `#` comments naming the layout and its source.
std::string glass_layout_csv(const GlassLayoutTable& table);
// The same as JSON: kind "glass layout table", the layout's name, summary, source and quantity, the axes
// (roughness, alphas, mus, index_coordinates, iors), tolerance, seconds, E, E_R and E_T {value, error} nested
// [z][y][x] (Cycles' order), E_encoded the same, and E_avg {value, error} nested [z][x] when the table has it.
nlohmann::json glass_layout_json(const GlassLayoutTable& table);

}  // namespace microsim
