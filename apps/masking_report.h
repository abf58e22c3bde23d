// microsim CLI: the report of a masking measurement (`trace masking --surface S`, and `merge` of its
// parts): the JSON report (with the provenance and exact sums a merge needs) and the table on stdout. One
// renderer, so a merged run reports exactly what the single run would.
#pragma once

#include "measure/masking.h"

#include <string>
#include <vector>

namespace microsim::app {

// (The leak test, kLeakSigmas and leak_failed, and the JSON report are measure/masking.h's.)
// "value ± se" with `digits` decimals.
std::string pm(const Estimate& e, int digits = 4);
// Ctrl-C: what was measured has been written, marked partial; says so on stderr. Returns exit code 130.
int interrupted_partial_written(const char* command, const std::vector<std::string>& outputs);

struct MaskingOutputs {
  std::string json;  // the JSON report ("" for none)
};

// Writes the JSON report (surface_masking_json and the peak memory) and prints the table. Returns the exit code: 130 when partial (cancelled, or the
// VNDF requested but not traced), 1 when the leak test failed, else 0.
int report_surface_masking(const SurfaceMasking& m, const MaskingSurface& surface, const MaskingOutputs& outputs);

}  // namespace microsim::app
