// microsim CLI: the report of a VNDF measurement (`trace vndf`, and `merge` of its parts): the histogram
// EXR (a shard: its JSON part), the JSON summary and the table on stdout. One renderer, so a merged run reports exactly what the
// single run would.
#pragma once

#include "measure/vndf.h"

#include <nlohmann/json.hpp>

#include <string>

namespace microsim::app {

struct VndfOutputs {
  std::string out;    // histogram EXR, or the part (JSON) when `part`
  std::string json;   // JSON summary ("" for none)
  bool part = false;  // a shard: `out` is its part for `microsim merge` (measure/vndf.h vndf_part_json)
};

// Writes the EXR and the JSON, prints the table; returns the exit code (130 when partial).
int report_ellipsoid_vndf(const EllipsoidVndf& m, const EllipsoidTarget& target, const VndfOutputs& outputs);
int report_heightfield_vndf(const HeightfieldVndf& m, const microgeom::Heightfield& field, const VndfOutputs& outputs);

}  // namespace microsim::app
