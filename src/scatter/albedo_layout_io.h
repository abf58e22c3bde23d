// scatter: a layout table (scatter/albedo_layout.h) as files, and the values of a table in a layout read
// back for a grade. Pure functions of their inputs (the caller writes atomically and reads the files).
//
// EXR: the layout's storage grid (width = layout_columns, height = layout_rows, data[y * width + x] as
// the renderer stores it), 32-bit float channels E.value (the reference), E.error (its quadrature error
// estimate) and E.encoded (the value as the renderer's encoding stores it), and where the layout has a
// grazing channel (AlbedoLayout::grazing_quantity, Filament's DFG.x) the same three as "DFG.x.value", ...; string attributes kind
// "albedo layout table", layout, source, quantity, encoding, columns and rows (which axis each is),
// roughness, alphas and mus (the nodes, %.17g), tolerance, interpolation_max_abs, interpolation_rms, and
// E_avg, E_avg_error where the layout has them.
//
// CSV: a header line, '#' comment lines (the layout, its source, the axes), then one line per node in
// storage order: x,y,roughness,alpha,mu,E,E_error,E_encoded[,E_grazing,E_grazing_error,E_grazing_encoded]
// [,E_avg,E_avg_error] (x, y: the storage column and row; E_avg of the node's roughness repeated on each
// line). %.17g numbers.
//
// Encoded: the values in the renderer's own encoding, storage order: six_decimals as text (%.6f, one
// storage row per line, comma-separated, as Cycles prints its tables); float32, half and unorm16 as raw
// little-endian binary (4, 2 and 2 bytes per value); with a grazing channel, two values per node, the
// grazing one first (Filament's texel: R = DFG.x, G = DFG.y).
//
// Centres CSV: the interpolation error at each cell centre: roughness_index,mu_index,alpha,mu,reference,
// reference_error,bilinear,error.
#pragma once

#include "microgeom/exr_io.h"
#include "scatter/albedo_layout.h"

#include <nlohmann/json_fwd.hpp>

#include <string>
#include <string_view>
#include <vector>

namespace microsim {

inline constexpr const char* kAlbedoLayoutKind = "albedo layout table";

microgeom::ExrImage layout_table_exr(const LayoutTable& table);
std::string layout_table_csv(const LayoutTable& table);
std::string layout_table_encoded(const LayoutTable& table);
std::string layout_centres_csv(const LayoutTable& table);
nlohmann::json layout_table_json(const LayoutTable& table);

// The values of a table in `layout`, storage order, from an EXR: its E.value channel, else its only
// channel, else (a Filament DFG texture) its G channel; from a CSV microsim wrote (columns x, y, E); from
// the layout's encoded bytes. std::invalid_argument naming what is wrong (wrong size, a missing column or
// channel, a cell missing or given twice, a number that does not parse).
std::vector<double> layout_values_from_exr(const microgeom::ExrImage& image, const AlbedoLayout& layout);
// `column`: the column read (E; E_grazing for the grazing channel).
std::vector<double> layout_values_from_csv(std::string_view text, const AlbedoLayout& layout,
                                           std::string_view column = "E");
// The grazing channel (layout.has_grazing()): an EXR's "<grazing_quantity>.value" channel, else (a Filament
// DFG texture with R and G) its R channel; a CSV's E_grazing column. Empty when the layout has no grazing
// channel or the file does not carry it; std::invalid_argument as above for a file that is wrong.
std::vector<double> layout_grazing_values_from_exr(const microgeom::ExrImage& image, const AlbedoLayout& layout);
std::vector<double> layout_grazing_values_from_csv(std::string_view text, const AlbedoLayout& layout);
// The values of a table as a renderer's source prints them (Cycles' `shader.tables` and its
// `cycles_precompute`: %.6f floats, comma-separated, a storage row per line): every number in storage order,
// separated by commas, blanks or line breaks, each with or without C's float suffix 'f'; exactly `count` of
// them. std::invalid_argument naming the line of a number that does not parse, or the count found.
std::vector<double> printed_values(std::string_view text, std::size_t count, const std::string& layout_name);

// The values of the table file at `path`, by its extension: .exr, .csv, or .txt (printed_values), as above. std::invalid_argument
// when it cannot be read, has another extension or is not a table in `layout` (the message without the path).
std::vector<double> read_layout_values(const std::string& path, const AlbedoLayout& layout);
// Both channels of the file at `path` (grazing empty when the layout or the file has none).
struct LayoutValues {
  std::vector<double> values, grazing;
};
LayoutValues read_layout_channels(const std::string& path, const AlbedoLayout& layout);

}  // namespace microsim
