// measure: explicit surfaces built once and cached on disk (surface_cache.h).
#include "measure/surface_cache.h"

#include "core/fnv1a.h"

#include <fmt/core.h>

#include <algorithm>
#include <string_view>

#include <stdexcept>

namespace microsim {
namespace {

std::string key_number(double x) { return fmt::format("{:.17g}", x); }

std::string metadata_or(const microgeom::Heightfield& field, const std::string& key) {
  const auto it = field.metadata.find(key);
  return it == field.metadata.end() ? "(none)" : it->second;
}

// Why a cache file read back is not the surface of `key` ("" when it is).
std::string mismatch(const microgeom::Heightfield& field, const SurfaceKey& key) {
  const std::string canonical = canonical_surface_key(key);
  if (metadata_or(field, "cache_key") != canonical)
    return fmt::format("it holds another surface (cache_key {})", metadata_or(field, "cache_key"));
  if (field.resolution() != key.resolution) return fmt::format("its resolution is {}", field.resolution());
  if (metadata_or(field, "cache_heights") != heights_digest(field))
    return "its heights changed since it was written (cache_heights differs)";
  return "";
}

}  // namespace

std::string canonical_surface_key(const SurfaceKey& k) {
  return fmt::format("assembly={};ndf={};alpha={},{};resolution={};corr_cells={};ndf_match={};seed={};builder={}",
                     k.assembly, k.ndf, key_number(k.alpha_x), key_number(k.alpha_y), k.resolution, key_number(k.corr_cells), k.ndf_match,
                     k.seed, k.builder_version);
}

std::string heights_digest(const microgeom::Heightfield& field) {
  const std::vector<float>& h = field.heights();
  return fmt::format("{:016x}", fnv1a(kFnv1aOffset, h.data(), h.size() * sizeof(float)));
}

std::string surface_key_hash(const SurfaceKey& key) { return fmt::format("{:016x}", fnv1a(canonical_surface_key(key))); }

microgeom::AssemblyParams assembly_params(const SurfaceKey& key) {
  microgeom::AssemblyParams p;
  p.assembly = key.assembly;
  p.alpha_x = key.alpha_x;
  p.alpha_y = key.alpha_y;
  p.resolution = key.resolution;
  p.seed = key.seed;
  p.corr_cells = key.corr_cells;
  const auto match = microgeom::ndf_match_from_string(key.ndf_match);
  if (!match) throw std::invalid_argument(fmt::format("surface: NDF matching '{}' is neither radial nor joint", key.ndf_match));
  p.ndf_match = *match;
  return p;
}

SurfaceCache::SurfaceCache(std::filesystem::path directory, CacheFiles files)
    : directory_(std::move(directory)), files_(files) {}

std::filesystem::path SurfaceCache::path_for(const SurfaceKey& key) const {
  return directory_.empty() ? std::filesystem::path{} : directory_ / (surface_key_hash(key) + ".exr");
}

const microgeom::Heightfield& SurfaceCache::surface_for(const SurfaceKey& key, const RunControl& run) {
  const std::string hash = surface_key_hash(key);
  const auto found = surfaces_.find(hash);
  if (found != surfaces_.end()) return found->second;
  return surfaces_.emplace(hash, read_or_build(key, run)).first->second;
}

const microgeom::Heightfield& SurfaceCache::heightmap(const std::filesystem::path& path) {
  const std::string id = "file:" + path.string();
  const auto found = surfaces_.find(id);
  if (found != surfaces_.end()) return found->second;
  const microgeom::Heightfield& field = surfaces_.emplace(id, microgeom::load_heightmap_exr(path)).first->second;
  heightmap_digests_.emplace(id, heights_digest(field));
  return field;
}

const std::string& SurfaceCache::heightmap_digest(const std::filesystem::path& path) {
  heightmap(path);
  return heightmap_digests_.at("file:" + path.string());
}

const HeightfieldScene& SurfaceCache::scene_for(const microgeom::Heightfield& field) {
  if (scene_field_ != &field) {
    scene_.reset();  // the previous scene's memory first
    scene_ = std::make_unique<HeightfieldScene>(field);
    scene_field_ = &field;
  }
  return *scene_;
}

microgeom::Heightfield SurfaceCache::read_or_build(const SurfaceKey& key, const RunControl& run) {
  const std::filesystem::path path = path_for(key);
  if (path.empty() || !std::filesystem::exists(path)) return build(key, run);
  std::string why;
  try {
    microgeom::Heightfield field = microgeom::load_heightmap_exr(path);
    why = mismatch(field, key);
    if (why.empty()) {
      events_.push_back(fmt::format("read {}", path.string()));
      return field;
    }
  } catch (const std::runtime_error& e) {
    why = fmt::format("it cannot be read ({})", e.what());
  }
  events_.push_back(fmt::format("rebuilt {}: {}", path.string(), why));
  return build(key, run);
}

microgeom::Heightfield SurfaceCache::build(const SurfaceKey& key, const RunControl& run) {
  microgeom::Heightfield field;
  try {
    const auto progress = [&run](std::string_view, double fraction) {  // thousandths of this build
      run.report("build surface", std::uint64_t(std::clamp(fraction, 0.0, 1.0) * 1000), 1000);
    };
    field = microgeom::build_assembly(assembly_params(key), nullptr, progress, [&run] { return run.cancelled(); });
  } catch (const microgeom::BuildCancelled&) {
    throw Cancelled("surface build");
  }
  ++builds_;
  field.metadata["cache_key"] = canonical_surface_key(key);
  field.metadata["cache_heights"] = heights_digest(field);
  const std::filesystem::path path = files_ == CacheFiles::read_write ? path_for(key) : std::filesystem::path{};
  if (!path.empty()) {
    std::filesystem::create_directories(directory_);
    microgeom::save_heightmap_exr(path, field);
  }
  events_.push_back(fmt::format("built {} ({}){}", surface_key_hash(key), canonical_surface_key(key),
                                path.empty() ? " in memory" : ", wrote " + path.string()));
  return field;
}

}  // namespace microsim
