// scatter: an energy-compensation table (scatter/albedo_table.h) as files a renderer loads. Pure
// functions of the table (the caller writes them atomically, core/atomic_file.h, microgeom::write_exr).
//
// EXR (microgeom/exr_io.h): width = mus, height = alphas (row y = alpha index, column x = mu index, both
// increasing), 32-bit float channels QUANTITY.value and QUANTITY.error for each quantity (E1.value,
// E1.error, ...). String attributes: kind "albedo table", model, ndf, material, side ("outside" or
// "inside"), alphas and mus (the axes' values, comma-separated, %.17g), mu_weights, mu_rule, error (what
// the .error channels hold), QUANTITY.average and QUANTITY.average_error (E_avg per alpha), quantities,
// paths, seed, max_order, resolution, tolerance (those of the model), partial ("true" / "false"),
// alphas_requested.
//
// CSV: a first line of column names, then '#' comment lines (the model, its parameters, the mu rule;
// "# PARTIAL" for a partial table), then one line per cell, alpha-major:
//   alpha,mu,mu_weight,Q,Q_error,...,Q_avg,Q_avg_error,...
// with E_avg(alpha) repeated on each line of its alpha, so that a renderer reads E(mu, alpha) and
// E_avg(alpha) from one numeric file (numpy.genfromtxt(path, delimiter=",", names=True), pandas.read_csv(
// path, comment="#")). Numbers are %.17g (doubles round-trip).
//
// JSON: the request, the axes, per quantity the value and error matrices [alpha][mu] and the averages,
// the timings, partial.
#pragma once

#include "microgeom/exr_io.h"
#include "scatter/albedo_table.h"

#include <nlohmann/json_fwd.hpp>

#include <string>
#include <vector>

namespace microsim {

inline constexpr const char* kAlbedoTableKind = "albedo table";

// Throws std::invalid_argument for a table with no complete row (an EXR cannot be empty).
microgeom::ExrImage albedo_table_exr(const AlbedoTable& table);
std::string albedo_table_csv(const AlbedoTable& table);
nlohmann::json albedo_table_json(const AlbedoTable& table);

// The values (or, errors: the standard errors) of `estimates`, in their order.
std::vector<double> estimate_values(const std::vector<Estimate>& estimates, bool errors);
// Estimates stored row by row, `columns` to a row, as JSON rows: {"value": [[...], ...], "error": [[...], ...]}.
nlohmann::json estimate_rows_json(const std::vector<Estimate>& estimates, std::size_t columns);

// "mirror" / "dielectric:1.5" and the side: the table's one-line description ("analytic ggx mirror outside").
std::string describe_albedo_request(const AlbedoTableRequest& request);

}  // namespace microsim
