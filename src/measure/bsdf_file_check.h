// measure: one BSDF's consistency with itself from files (`check-bsdf --dump D --eval E`): a sample dump from one
// view (x, y, z, pdf, weight per channel; the frame and columns of validate/sample_io.h) and an eval file of the
// same BSDF at the same rows (validate/eval_check.h's rows: wi = the view, wo = the dump's direction, f(wi, wo)
// |cos wo| per channel, pdf(wo | wi)), with the battery's tests (bsdf_battery.h, bsdf_self_check.h):
//   - consistency: each weight against eval / pdf and each dump pdf against the eval file's, 1e-3 relative;
//   - furnace: the mean weight (lost samples weigh 0) with its standard error, against a claimed albedo when one
//     is given (the white furnace: 1 for an energy-conserving BSDF).
// With a third file, the BSDF's eval() and pdf() at the view's cell points (bsdf_self_check.h cell_points, written
// by `bsdf-queries --cells` for the renderer to fill in, in the eval file's columns), the battery's cell tests
// too (bsdf_self_check.h cell_tests): density (the dump's directions per cell against the integral of pdf() over
// the cell), integral (the weighted sample histogram against the integral of eval() per cell), furnace (the mean
// weight against the integral of eval cos, both with errors). The pdf is integrated over each cell from the
// file, not estimated from the samples: an estimate from the samples alone, E_q[1_cell / p] = the cell's solid
// angle, is biased in cells the sampler only partly reaches (along the edge of a refraction's support).
// The statistical tests share `level` by Sidak's rule.
#pragma once

#include "measure/bsdf_battery.h"
#include "validate/eval_check.h"
#include "validate/sample_io.h"

#include <filesystem>
#include <optional>
#include <string>

namespace microsim {

// Rows of a file (NPY or text, as sample_io.h reads it) or in memory (a SampleArray holding every column the
// columns' spec names, '-' ones included; its name stands for a path in messages: the Python binding's arrays).
// Empty: none.
struct BsdfRows {
  std::filesystem::path path;
  std::optional<SampleArray> array;
  BsdfRows() = default;
  BsdfRows(std::filesystem::path file) : path(std::move(file)) {}  // NOLINT(google-explicit-constructor): a path
  explicit BsdfRows(SampleArray rows) : array(std::move(rows)) {}
  bool empty() const { return !array && path.empty(); }
  std::string name() const { return array ? array->name : path.string(); }
  DirectionSampleReader open(const SampleColumns& columns) const;
};

// Why the dump's columns (x, y, z, pdf and a weight per channel) or the eval file's (wi, wo, value and pdf) cannot
// be checked; "" when they can. Each caller names its own option or key before it.
std::string dump_columns_problem(const SampleColumns& columns);
std::string eval_columns_problem(const EvalColumns& columns);

struct BsdfFileCheckOptions {
  SampleFrame frame = SampleFrame::z_up;
  std::uint64_t lost = 0;  // samples the dump leaves out (lost below the horizon): they weigh 0
  double level = 0.01;
  std::optional<double> albedo;  // claimed
  // The eval file at the view's cell points (in the eval file's columns, the pdf column for the density test);
  // empty: no cell tests.
  BsdfRows cells;
  RunControl run;
};

// Throws SampleFileError for a file (or array) that cannot be read as its columns say or whose rows do not match
// (counts, wi not the view, wo not the dump's direction, the cells file's wo not in their cells), std::invalid_argument
// for bad options, Cancelled.
BatteryReport check_bsdf_files(const BsdfRows& dump, const SampleColumns& dump_columns, const BsdfRows& eval,
                               const EvalColumns& eval_columns,
                               const Vec3<double>& wi, const BsdfFileCheckOptions& options);

}  // namespace microsim
