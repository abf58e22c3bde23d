// scatter: the grade of an energy-compensation table a renderer ships, in one of the layouts of
// scatter/albedo_layout.h: each node against the reference (the analytic single-scattering albedo, at the
// quadrature tolerance the grade needs: grade_reference_tolerance), and the table's bilinear interpolation
// at the cell centres against the reference there (what the table costs a renderer that reads it).
//
// Per node: difference = table - reference; within quantisation when |difference| <= the encoding's
// rounding (layout_quantisation) + the reference's error estimate; within noise, for a table built from N
// samples per cell (stated by the user), when |difference| <= z sqrt(E (1 - E) / N) + that rounding + the
// reference's error, z the two-sided normal quantile of the Sidak level 1 - (1 - 1e-3)^(1 / nodes) (so that a
// table of unbiased nodes has a node beyond its noise with probability at most about 1e-3): E (1 - E) bounds the variance of a per-sample weight in [0, 1] of mean E (the
// Bhatia-Davis inequality), which a VNDF-sampled mirror's weight G1(wo) is; a table built by NDF sampling
// has a larger variance (weights above 1), so its noise can exceed this bound. Passed: every graded node
// within the tolerance the user gives beyond that rounding and the reference's error (|difference| <= tolerance
// + quantisation + error; a node below the reference's alpha range is reported, not graded).
// Never prints.
#pragma once

#include "core/run_control.h"
#include "scatter/albedo_layout.h"

#include <nlohmann/json_fwd.hpp>

#include <cmath>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace microsim {

// One node of a table against the reference (the rules above; the glass layouts' grade uses them too).
struct NodeGrade {
  double value = 0;  // the table's
  Estimate reference;
  double difference = 0, quantisation = 0, noise = 0;  // noise: 0 when no sample count is stated
  bool graded = true;  // the node's alpha is in the reference's range (reported, not graded, otherwise)
  bool within_quantisation = false, within_noise = false, within_tolerance = false;
};
// `quantisation`: the encoding's rounding at the value; `z`: the noise check's quantile (grade_noise_z).
NodeGrade grade_node(double value, const Estimate& reference, double quantisation, bool graded, double tolerance,
                     std::uint64_t samples, double z);
// The noise check's two-sided normal quantile for `nodes` nodes at the family level kGradeNoiseLevel (Sidak);
// 0 when no sample count is stated.
double grade_noise_z(std::size_t nodes, std::uint64_t samples);

// What the graded nodes add up to: the largest and RMS difference, where, and the counts beyond each bound.
struct GradeTotals {
  double max_abs = 0, rms = 0;
  std::size_t worst = 0;  // index into the cells (graded nodes only, as max_abs and rms)
  std::size_t failed = 0, beyond_quantisation = 0, beyond_noise = 0, not_graded = 0;
  bool passed() const { return failed == 0; }
};
// The totals of `nodes` (each a NodeGrade) in their order; samples_stated: the noise check ran.
template <class Node>
GradeTotals grade_totals(const std::vector<Node>& nodes, bool samples_stated);

struct CellGrade : NodeGrade {
  std::size_t ri = 0, mj = 0;  // roughness and mu node
  double alpha = 0, mu = 0;
};

struct AlbedoGrade : GradeTotals {
  AlbedoLayout layout;
  std::string quantity;             // the channel graded: the layout's quantity, or its grazing_quantity
  NdfKind ndf = NdfKind::ggx;       // the reference mirror's distribution
  double tolerance = 0, reference_tolerance = 0;
  double noise_z = 0;               // the noise check's quantile (0 when no sample count)
  std::uint64_t table_samples = 0;  // 0: not stated
  std::vector<CellGrade> cells;     // [ri * mus + mj]
  InterpolationError table_interpolation;      // the table's bilinear at cell centres vs the reference
  InterpolationError reference_interpolation;  // the layout's own (the reference's nodes)
  // A failed table that the reference fits far better read another way (its rows a node off in roughness or
  // mu, or transposed): each such reading in words with both RMS differences ("" none).
  std::vector<std::string> hints;
};

inline constexpr double kGradeNoiseLevel = 1e-3;  // the family level of the noise check

// The grade of `values` (storage order of the layout: layout_storage_index) with tolerance `tolerance`
// (> 0). std::invalid_argument for a wrong count, a non-finite value or tolerance; nullopt when cancelled.
// The reference: layout_table at grade_reference_tolerance(layout, tolerance), without E_avg: a hundredth of
// the grade's tolerance and a tenth of the encoding's rounding step (layout_quantisation at E = 1/2, the
// step of every albedo in [1/2, 1); the 6-decimal text's 5.3e-7, float32's 3e-8, half's 2.4e-4, unorm16's
// 7.6e-6), whichever is smaller, clamped to [1e-13, 1e-6]: the reference's own error then stays well below
// both the difference the user grades and the rounding the quantisation check allows. (No finer: the
// quadrature's cost grows as its tolerance shrinks, and a finer reference changes no verdict.)
double grade_reference_tolerance(const AlbedoLayout& layout, double tolerance);
// The same against a reference computed once (layout_table of the layout, any tolerance).
// grazing: grade the layout's grazing channel (Filament's DFG.x) against the reference's (std::invalid_argument
// when the layout or the reference has none); its per-sample weight G1 (1 - VoH)^5 is in [0, 1] too, so the
// noise bound holds for it as for E.
AlbedoGrade grade_against(const LayoutTable& reference, const std::vector<double>& values, double tolerance,
                          std::uint64_t table_samples = 0, bool grazing = false);
// ndf: the distribution the table is of (the reference is that mirror's).
std::optional<AlbedoGrade> grade_albedo_table(const AlbedoLayout& layout, const std::vector<double>& values,
                                              double tolerance, std::uint64_t table_samples = 0,
                                              const RunControl& run = {}, NdfKind ndf = NdfKind::ggx);
// The grade of E (values) and, when `grazing` is not empty, of the layout's grazing channel, against one
// reference (computed as grade_albedo_table's, both channels in one quadrature): one or two grades, E first.
// std::invalid_argument as above, and for grazing values in a layout without that channel.
std::optional<std::vector<AlbedoGrade>> grade_albedo_channels(const AlbedoLayout& layout,
                                                              const std::vector<double>& values,
                                                              const std::vector<double>& grazing, double tolerance,
                                                              std::uint64_t table_samples = 0,
                                                              const RunControl& run = {}, NdfKind ndf = NdfKind::ggx);
nlohmann::json albedo_grade_json(const AlbedoGrade& grade);

template <class Node>
GradeTotals grade_totals(const std::vector<Node>& nodes, bool samples_stated) {
  GradeTotals g;
  double sum = 0;
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    const NodeGrade& c = nodes[k];
    if (!c.graded) {
      ++g.not_graded;
      continue;
    }
    sum += c.difference * c.difference;
    if (std::abs(c.difference) > g.max_abs || !nodes[g.worst].graded) {
      g.max_abs = std::abs(c.difference);
      g.worst = k;
    }
    g.failed += !c.within_tolerance;
    g.beyond_quantisation += !c.within_quantisation;
    g.beyond_noise += samples_stated && !c.within_noise;
  }
  const std::size_t graded = nodes.size() - g.not_graded;
  g.rms = graded == 0 ? 0.0 : std::sqrt(sum / double(graded));
  return g;
}

}  // namespace microsim
