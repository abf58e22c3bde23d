// measure: an energy-compensation table (scatter/albedo_table.h: E(mu, alpha) and E_avg, Kulla & Conty 2017) as
// one measurement, end to end: the library call of `microsim albedo` (and its `--shard K/N` parts and their
// `microsim merge`) and of an experiment's albedo quantity (its rounds, its ranks and shard jobs, its pilots).
//
// A sampled table's blocks are its cells, row-major (cell c is alpha c / mus, mu c % mus), each its own walk or
// tracing of request.paths paths from its own seed (albedo_cell_seed): a block range of cells is what a rank,
// a thread or a shard job runs, and the cells of the ranges joined in block order give the one-process table
// bit for bit (albedo_table_from_cells). A range's estimates travel as exact reals (stats/part_json.h).
#pragma once

#include "core/block_runner.h"
#include "scatter/albedo_table.h"
#include "stats/part_json.h"

#include <nlohmann/json.hpp>

#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace microsim {

// The whole table of a request, row by row (albedo_table: every model; `on_row` after each complete row).
AlbedoTable measure_albedo_table(const AlbedoTableRequest& request, const AlbedoRowCallback& on_row = {});

// The table albedo_table_json (scatter/albedo_table_io.h) wrote, with `request` (the table's own: the JSON
// does not hold it whole): what an interrupted run reads back. std::invalid_argument for a malformed table.
AlbedoTable albedo_table_from_json(const nlohmann::json& table, const AlbedoTableRequest& request);

// ---- a sampled table by its cells ---------------------------------------------------------------------------

// The cells of a sampled table: alphas x mus.
std::uint64_t albedo_cell_count(const AlbedoTableRequest& request);

// The estimates of a block range of a sampled table's cells, nullopt when cancelled: the Smith walk's
// (walk_albedo_cells), or on surfaces the caller holds (an experiment's tiles: surface_albedo_cells).
using AlbedoCellsOf = std::function<std::optional<AlbedoCells>(const AlbedoTableRequest& request, const BlockRange& cells)>;

// A table from every cell of it (albedo_table_from_cells, `seconds` the time they took), or, when they were
// cancelled (nullopt), a partial table with no row.
AlbedoTable albedo_table_of_cells(const AlbedoTableRequest& request, const std::optional<AlbedoCells>& cells,
                                  double seconds);
// Every cell of a sampled table from `cells_of` in this process, as one table (albedo_table_of_cells).
AlbedoTable measure_albedo_cells_table(const AlbedoTableRequest& request, const AlbedoCellsOf& cells_of);

// ---- a block range of cells as a part ------------------------------------------------------------------------

// The part of `microsim albedo --shard K/N`: a sampled table's cells `blocks` (of albedo_cell_count) with
// provenance (producer kAlbedoPartProducer; the request's model, ndf, material, side, alphas, mus, paths,
// order cap and, for a surface, resolution as its parameters; its seed), "quantity_names", "cells" (per cell,
// its quantities' estimates in albedo_quantity_names order as [value, error], each exact_real_json) and
// "seconds" (the time the cells took). The part of a rank or shard job of an experiment's albedo round too.
inline constexpr const char* kAlbedoPartProducer = "albedo";
nlohmann::json albedo_part_json(const AlbedoTableRequest& request, const BlockRange& blocks, const AlbedoCells& cells,
                                double seconds);

// The part of cells `blocks` of a Smith-walk table (walk_albedo_cells), nullopt when cancelled; throws as
// walk_albedo_cells.
std::optional<nlohmann::json> measure_albedo_part(const AlbedoTableRequest& request, const BlockRange& blocks);

struct AlbedoPart {
  AlbedoTableRequest request;  // from the provenance (its RunControl empty)
  Provenance provenance;
  nlohmann::json parameters;
  AlbedoCells cells;           // one per block of provenance.blocks
  double seconds = 0;
};
// Reads a part of albedo_part_json's form; HistogramMergeError naming what is missing or malformed.
AlbedoPart read_albedo_part(const nlohmann::json& part);
// The parts of one run (any order) as its table: their cells in block order, albedo_table_from_cells (the
// single run's, bit for bit; its time the parts' summed). HistogramMergeError for parts of different runs,
// blocks repeated or missing.
AlbedoTable merge_albedo_parts(const std::vector<AlbedoPart>& parts);

// ---- what a table achieved, and the pilots that plan one ----------------------------------------------------

// The worst relative error (error / value) over the cells and E_avg of the quantities whose name starts
// with `prefix` ("E1": the single-scattering albedos; "E": every albedo, not the unfinished or lost weight);
// infinite for a value 0 with an error, 0 for an error 0.
double worst_relative_albedo_error(const AlbedoTable& table, std::string_view prefix);

// The weight a sampled table's first row leaves at its order cap, relative to E: at the mu where the
// unfinished weight plus two standard errors is the largest share of E (none left among n paths: the rule of
// three's 95% bound 3 / n taken as two standard errors). The walk's order cap is planned from it on the
// roughest row, where paths stay longest.
struct AlbedoUnfinishedShare {
  double share = 0, share_se = 0;
};
AlbedoUnfinishedShare albedo_unfinished_share(const AlbedoTable& table);

}  // namespace microsim
