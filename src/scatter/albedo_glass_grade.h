// scatter: the grade of a rough-glass table in one of Cycles' glass layouts (scatter/albedo_glass_layout.h),
// node by node against the reference (glass_layout_table at the tolerance the grade needs), as the grade of a
// mirror's table (scatter/albedo_grade.h) does for a 2D layout:
//   difference = table - reference (E = E_R + E_T);
//   within quantisation when |difference| <= Cycles' rounding (6 decimals of a float: layout_quantisation of
//     LayoutEncoding::six_decimals) + the reference's error estimate;
//   within noise, for a table built from N samples per node (stated by the user), when |difference| <=
//     z sqrt(E (1 - E) / N) + that slack, z the two-sided normal quantile of the Sidak level 1 - (1 - 1e-3)^(1 /
//     nodes): a dielectric's flux weight per sample (reflected or transmitted, chosen by Fresnel, times the
//     masking ratio) lies in [0, 1], so E (1 - E) bounds its variance (Bhatia-Davis), as for the mirror;
//   within the tolerance the user gives; passed when every graded node is. Nodes of alpha below kMinAlpha (r =
//   1e-4) are reported, not graded.
// No interpolation error at cell centres here (the 3D grid's centres would cost 15^3 more quadratures).
// The files read: the CSV microsim writes for a glass layout (columns x, y, z, E) and the values as Cycles
// prints them (glass_layout_encoded: 16 slices of 16 lines of 16 values, blank lines between slices ignored).
// Never prints.
#pragma once

#include "core/run_control.h"
#include "scatter/albedo_glass_layout.h"
#include "scatter/albedo_grade.h"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace microsim {

struct GlassCellGrade : NodeGrade {
  std::size_t x = 0, y = 0, z = 0;  // roughness, mu and index node
  double alpha = 0, mu = 0, ior = 0;
};

struct GlassGrade : GradeTotals {
  GlassLayout layout;
  double tolerance = 0, reference_tolerance = 0, noise_z = 0;
  std::uint64_t table_samples = 0;
  std::vector<GlassCellGrade> cells;  // Cycles' storage order, GlassLayoutTable::index
};

// The reference's quadrature tolerance for a grade at `tolerance`: the smaller of tolerance / 100 and a tenth
// of the 6-decimal rounding step, clamped to [1e-13, 1e-6] (grade_reference_tolerance's rule).
double glass_grade_reference_tolerance(double tolerance);
// The grade of `values` (Cycles' storage order) against `reference` (glass_layout_table of the layout, any
// tolerance; E_avg not needed). std::invalid_argument for a wrong count, a non-finite value or tolerance.
GlassGrade grade_glass_against(const GlassLayoutTable& reference, const std::vector<double>& values, double tolerance,
                               std::uint64_t table_samples = 0);
// The same, computing the reference (no E_avg) at glass_grade_reference_tolerance on run.threads; nullopt when
// cancelled.
std::optional<GlassGrade> grade_glass_table(const GlassLayout& layout, const std::vector<double>& values,
                                            double tolerance, std::uint64_t table_samples = 0,
                                            const RunControl& run = {});
nlohmann::json glass_grade_json(const GlassGrade& grade);

// The values of a glass table, Cycles' storage order: from the CSV microsim writes (columns x, y, z, E; every
// node once), or from the text Cycles prints (comma-separated values, any line breaks). std::invalid_argument
// naming what is wrong (a missing column, a cell missing or given twice, a wrong count, a bad number).
std::vector<double> glass_values_from_csv(std::string_view text, const GlassLayout& layout);
std::vector<double> glass_values_from_text(std::string_view text, const GlassLayout& layout);
// By the file's extension: .csv, or .txt (Cycles' printed values). std::invalid_argument when the file cannot
// be read, has another extension or is not a table of the layout (the message without the path).
std::vector<double> read_glass_values(const std::string& path, const GlassLayout& layout);

}  // namespace microsim
