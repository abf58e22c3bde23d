// microsim CLI: the inputs shared by the commands that read a heightfield (trace masking, trace vndf
// --surface, merge): checks that turn bad input into usage errors (exit 2). (The surface's JSON record is
// measure/vndf.h surface_json.)
#pragma once

#include "command.h"
#include "microgeom/heightfield.h"
#include "trace/smith_prediction.h"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>

namespace microsim::app {

// A direction's polar angle in [0, 90) degrees, else UsageError naming the option.
void check_theta(const std::string& option, double theta);
// The heightmap at `path`, given as `option` ("--surface", or "heightmap" for a positional argument):
// UsageError naming the option and the file when it is missing or malformed; out of memory passes as
// std::bad_alloc.
microgeom::Heightfield load_surface(const std::string& path, std::optional<double> tile_size,
                                    const std::string& option = "--surface");

}  // namespace microsim::app
