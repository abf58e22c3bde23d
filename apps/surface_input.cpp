#include "surface_input.h"

#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <new>

namespace microsim::app {

namespace fs = std::filesystem;

void check_theta(const std::string& option, double theta) {
  if (!std::isfinite(theta) || theta < 0 || theta >= 90)
    throw UsageError(fmt::format("{} {}: the direction must be in [0, 90) degrees", option, theta));
}

microgeom::Heightfield load_surface(const std::string& path, std::optional<double> tile_size, const std::string& option) {
  if (tile_size && !(*tile_size > 0 && std::isfinite(*tile_size)))
    throw UsageError(fmt::format("--tile-size {}: must be positive and finite", *tile_size));
  if (!fs::exists(path)) throw UsageError(fmt::format("{} '{}': no such file", option, path));
  try {
    return microgeom::load_heightmap_exr(path, tile_size);
  } catch (const std::bad_alloc&) {
    throw;  // out of memory is an internal error (exit 3), not bad input
  } catch (const std::exception& e) {
    throw UsageError(fmt::format("{}: {}", option, e.what()));  // the reader's message names the file
  }
}

}  // namespace microsim::app
