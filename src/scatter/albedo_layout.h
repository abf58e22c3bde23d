// scatter: energy-compensation tables in the layouts renderers load, and the grade of a table a renderer
// ships. A layout (AlbedoLayout) is the grid, the storage order and the encoding of one renderer's table
// of the directional albedo E(mu, alpha) of a GGX mirror (F = 1, the Kulla & Conty 2017 E(mu); its
// E_avg(alpha) = 2 int_0^1 E mu dmu where the renderer ships one). Every layout is one row of the
// registry albedo_layouts() (albedo_layout.cpp), the one place layouts are chosen; nothing else switches
// on a layout's name.
//
// The renderers' conventions, read from their public source (the file named in AlbedoLayout::source):
//   cycles          Blender Cycles' ggx_E: 32 x 32 nodes on the edges of [0, 1] (node i at i / 31, the
//                   coordinate clamped to >= 1e-4) in r = sqrt(alpha) and mu; stored data[y * 32 + x]
//                   with x the roughness and y mu; read by bilinear interpolation between nodes
//                   (x (size - 1), lookup_table.h); float32 printed with 6 decimals; ggx_Eavg: 32 over r.
//   filament-dfg    Filament's DFG LUT in its multiscatter form (DFV_Multiscatter): DFG.y = E of F = 1 and
//                   DFG.x = the albedo weighted by Schlick's grazing term (1 - VoH)^5, both with the
//                   height-correlated Smith G2 (Filament's Visibility), which the shaders mix as
//                   E(f0) = mix(DFG.x, DFG.y, f0) (schlick_split_albedo, albedo_table.h): 128 x 128 texels,
//                   values at texel centres ((i + 0.5) / 128) in NoV and perceptual roughness
//                   r = sqrt(alpha) (alpha = Filament's linear_roughness), GL order (row y = roughness,
//                   increasing), half floats, R = DFG.x and G = DFG.y per texel (the engine's texture is
//                   RGB16F: its third, cloth channel, DFV_Charlie, is not modelled here), read by the GPU's
//                   bilinear filter with clamp to edge.
//   enterprise-pbr  Dassault Systemes' Enterprise PBR GGX_E: 32 x 32, [roughness][cos theta] (rows
//                   roughness r = sqrt(alpha), columns mu), float32; GGX_E_avg: 32 over r. The spec gives
//                   the axes, not where the nodes lie; the shipped table matches nodes at cell centres
//                   ((i + 0.5) / 32): docs/records/energy-tables.md.
//   uniform         a plain 32 x 32 grid at cell centres in alpha itself and mu, normalised uint16.
//
// The reference per node: the analytic single-scattering albedo with its error estimate, of GGX (what the
// renderers ship; single_scattering_albedo, quadrature over the visible normals, albedo_table.h) or of
// Beckmann (LayoutTable::ndf: the same grid, storage and encoding holding a Beckmann mirror's E, and for
// Filament its DFG.x; beckmann_mirror_split, the same integrals in the view's visible slopes, albedo_table.h).
// Beckmann clamps alpha at the same kMinAlpha (microfacet/beckmann.h). microsim's GGX clamps alpha from below
// at kMinAlpha = 1e-4 (microfacet/ggx.h), so a node of smaller alpha (Cycles' r = 1e-4, Filament's first
// roughness row) holds the reference at alpha 1e-4: it is outside the reference's range (in_range false),
// not graded, and the cells that touch it are left out of the interpolation error (NaN there). E_avg per roughness node: 2 sum_j
// w_j mu_j E(mu_j) on 32 Gauss-Legendre nodes (the rule's own error is not in the estimate).
// Interpolation error: at the centre of each cell between four nodes (the midpoint in the layout's own
// coordinates), the bilinear interpolation of the four nodes' references minus the reference there:
// what the layout's resolution alone costs a renderer that reads it exactly.
#pragma once

#include "core/estimate.h"
#include "core/ndf_kind.h"
#include "core/run_control.h"
#include "microfacet/material.h"
#include "scatter/albedo_table.h"

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace microsim {

enum class LayoutPlacement { edges, centres };  // node i at i / (n - 1), or at (i + 0.5) / n
// How a renderer stores a value: float32; float32 printed with 6 decimals; IEEE half; normalised uint16.
enum class LayoutEncoding { float32, six_decimals, half, unorm16 };
std::string to_string(LayoutEncoding encoding);

struct LayoutAxis {
  int nodes = 32;
  LayoutPlacement placement = LayoutPlacement::edges;
  double lowest = 0;  // the coordinate of a node is clamped to [lowest, 1]
};

struct AlbedoLayout {
  std::string name, summary;
  std::string source;             // the renderer's public file(s) this layout follows
  std::string quantity;           // the renderer's name of the table ("ggx_E", "DFG.y", "GGX_E", "E")
  LayoutAxis roughness, mu;
  bool roughness_is_alpha = false;  // the roughness coordinate is alpha itself (else r = sqrt(alpha))
  bool mu_rows = false;             // storage rows are mu, columns roughness (else rows roughness)
  LayoutEncoding encoding = LayoutEncoding::float32;
  bool has_average = false;         // the renderer ships E_avg over the roughness nodes
  // The renderer's name of a second channel, the albedo weighted by Schlick's grazing term (1 - VoH)^5
  // (Filament's "DFG.x": SchlickSplitAlbedo::grazing); "" when the layout ships E alone.
  std::string grazing_quantity;
  bool has_grazing() const { return !grazing_quantity.empty(); }
};

// The registry, in a fixed order (cycles, filament-dfg, enterprise-pbr, uniform).
const std::vector<AlbedoLayout>& albedo_layouts();
// The layout of that name; ParseError naming `what`, quoting the text and listing the names otherwise.
const AlbedoLayout& find_albedo_layout(std::string_view what, std::string_view name);
std::string albedo_layout_names();  // "cycles, filament-dfg, enterprise-pbr, uniform"

// A node's coordinate on an axis (clamped), and a cell centre's: the midpoint between nodes i and i + 1.
double layout_coordinate(const LayoutAxis& axis, double index);
double layout_alpha(const AlbedoLayout& layout, double roughness_coordinate);
// The storage index of node (roughness ri, mu mj) and the storage grid's size: columns x rows.
std::size_t layout_storage_index(const AlbedoLayout& layout, std::size_t ri, std::size_t mj);
int layout_columns(const AlbedoLayout& layout);
int layout_rows(const AlbedoLayout& layout);

// A value as the renderer stores it (rounded to its encoding) and the largest rounding error there.
double encode_layout_value(LayoutEncoding encoding, double value);
double layout_quantisation(LayoutEncoding encoding, double value);
std::uint16_t half_bits(double value);      // IEEE 754 binary16, round to nearest even (finite values)
double half_value(std::uint16_t bits);

// The interpolation error of a grid at its cell centres (see above).
struct InterpolationError {
  std::vector<double> errors;  // per cell centre, [ri * (mu nodes - 1) + mj]: bilinear - reference (NaN:
                               // a corner outside the reference's range)
  double max_abs = 0, rms = 0;
  std::size_t worst_ri = 0, worst_mj = 0;
  double worst_alpha = 0, worst_mu = 0;
};

struct LayoutTable {
  AlbedoLayout layout;
  NdfKind ndf = NdfKind::ggx;              // the microfacet distribution of the mirror
  double tolerance = 1e-8;                 // each reference's quadrature target
  std::vector<double> roughness, alphas;   // per roughness node: its coordinate and alpha
  std::vector<bool> in_range;              // per roughness node: alpha >= kMinAlpha (the reference holds)
  std::vector<double> mus;                 // per mu node
  std::vector<Estimate> cells;             // [ri * mus + mj], the reference and its error estimate
  std::vector<Estimate> average;           // E_avg per roughness node (when the layout has it)
  std::vector<Estimate> centres;           // the reference at each cell centre (InterpolationError order)
  InterpolationError interpolation;
  // The grazing channel where the layout has it (has_grazing), as cells, centres and interpolation above.
  std::vector<Estimate> grazing, grazing_centres;
  InterpolationError grazing_interpolation;
  double seconds = 0;
};

// The reference single-scattering albedo of a GGX (or Beckmann) mirror at (alpha, mu) (alpha > 0, mu in
// (0, 1]; alpha below kMinAlpha is computed at kMinAlpha). GGX: single_scattering_albedo; Beckmann:
// beckmann_mirror_split (albedo_table.h).
Estimate mirror_albedo_reference(double alpha, double mu, double tolerance, NdfKind ndf = NdfKind::ggx);
// Both channels of the Schlick split (schlick_split_albedo, or beckmann_mirror_split) at (alpha, mu), alpha
// clamped as above.
SchlickSplitAlbedo mirror_split_reference(double alpha, double mu, double tolerance, NdfKind ndf = NdfKind::ggx);

// The layout's nodes, cell centres and (if the layout has it) E_avg, each cell in parallel on
// run.threads; progress "layout table" in evaluations. nullopt when cancelled. `tolerance` in [1e-13, 1e-2]
// (std::invalid_argument otherwise).
// averages false: no E_avg (a grade needs only the nodes and the centres). ndf: the mirror's distribution.
std::optional<LayoutTable> layout_table(const AlbedoLayout& layout, double tolerance, const RunControl& run = {},
                                        bool averages = true, NdfKind ndf = NdfKind::ggx);
// The interpolation error of `nodes` ([ri * mus + mj]) against `centres` (the references there; by default
// the table's centres of E).
InterpolationError interpolation_error(const LayoutTable& table, const std::vector<double>& nodes);
InterpolationError interpolation_error(const LayoutTable& table, const std::vector<double>& nodes,
                                       const std::vector<Estimate>& centres);

}  // namespace microsim
