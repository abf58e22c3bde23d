// microsim CLI: the report of an energy-compensation table (`microsim albedo`): the EXR, CSV and JSON files
// (scatter/albedo_table_io.h, each written atomically) and the E_avg table on stdout.
#pragma once

#include "scatter/albedo_table.h"

#include <string>

namespace microsim::app {

struct AlbedoOutputs {
  std::string exr;   // --out
  std::string csv;   // "" for none
  std::string json;  // "" for none
};

// One line on stderr for a completed row (the progress of the rows).
void print_albedo_row(const AlbedoTable& so_far, std::size_t row);

// Writes the outputs and prints the table; returns kExitOk, kExitInterrupted when the table is partial
// (written, marked partial), or, with no complete row, kExitInterrupted with nothing written.
int report_albedo_table(const AlbedoTable& table, const AlbedoOutputs& outputs);

}  // namespace microsim::app
