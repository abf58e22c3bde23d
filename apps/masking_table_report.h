// microsim CLI: the report of the masking table (`trace masking --table`, measure/masking_table.h): one
// line per view on stderr while it runs, the markdown table on stdout (and --markdown), the JSON report
// (--json).
#pragma once

#include "measure/masking_table.h"

#include <string>

namespace microsim::app {

// The view's line on stderr (TV, the masking ratios, the leak ratio, seconds).
void print_table_view(const MaskingTableView& view);

struct MaskingTableOutputs {
  std::string json, markdown;  // "" for none
};

// Writes the JSON and the markdown, prints the table. Returns the exit code: 130 when partial, 1 when the
// leak test failed in a complete view, else 0.
int report_masking_table(const MaskingTable& table, const MaskingTableOutputs& outputs);

}  // namespace microsim::app
