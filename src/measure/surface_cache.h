// measure: explicit surfaces shared between measurements, built once. A surface is keyed by
// the parameters that determine it (assembly, its reference NDF, alpha pair, resolution N, correlation length
// l, NDF matching, seed, and the builder's version: microgeom's build is a pure function of them, see
// microgeom/assembly.h); its cache file is DIR/surfaces/<hash>.exr, hash = FNV-1a (core/fnv1a.h) of the
// canonical key, in 16 hex digits. The file is the heightmap `surface build` writes, with two more
// attributes: microsim.cache_key (the canonical key) and microsim.cache_heights (FNV-1a of the heights'
// bytes). A file is used only when both read back equal to what they must be: a file that cannot be read,
// holds another key (a hash collision, a file copied in) or heights that changed since it was written is
// rebuilt (and rewritten), never silently used; every such event is in events().
//
// Without a directory the cache lives in memory only (`run --dry-run`, `plan`). A read-only cache (the ranks
// of an MPI run other than the root, which own no file of DIR) uses a valid file of its directory but builds
// in memory what it lacks, never writing. Surfaces stay in memory for the cache's lifetime (references returned
// stay valid). Not thread-safe: one caller at a time.
#pragma once

#include "core/run_control.h"
#include "microgeom/assembly.h"
#include "microgeom/heightfield.h"
#include "trace/heightfield_trace.h"

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace microsim {

// Bumped whenever microgeom's assembly build changes what it produces for the same parameters.
inline constexpr int kSurfaceBuilderVersion = 1;

struct SurfaceKey {
  std::string assembly = "smith";
  std::string ndf = "ggx";  // the assembly's reference NDF
  double alpha_x = 0.5, alpha_y = 0.5;
  int resolution = 1024;
  double corr_cells = 16;
  std::string ndf_match = "radial";
  std::uint64_t seed = 1;
  int builder_version = kSurfaceBuilderVersion;
};

// "assembly=smith;ndf=ggx;alpha=0.5,0.5;resolution=1024;corr_cells=16;ndf_match=radial;seed=1;builder=1"
// (numbers with 17 significant digits: equal keys, equal strings).
std::string canonical_surface_key(const SurfaceKey& key);
std::string surface_key_hash(const SurfaceKey& key);  // 16 hex digits
// FNV-1a of a surface's heights (their float bytes), 16 hex digits: what names a heightmap's content.
std::string heights_digest(const microgeom::Heightfield& field);
// The build parameters of a key (throws std::invalid_argument for an unknown NDF matching).
microgeom::AssemblyParams assembly_params(const SurfaceKey& key);

// Whether a cache writes the files of the surfaces it builds.
enum class CacheFiles { read_write, read_only };

class SurfaceCache {
public:
  // `directory`: where the cache files live (created on the first build); empty: memory only.
  explicit SurfaceCache(std::filesystem::path directory = {}, CacheFiles files = CacheFiles::read_write);

  // The surface of `key`: from memory, else its cache file, else built (and its file written; progress:
  // "build surface", thousandths of the build, through run.progress). Throws
  // Cancelled when run.cancel stops the build, std::invalid_argument for parameters the assembly refuses,
  // FileWriteError-like std::runtime_error when the file cannot be written.
  const microgeom::Heightfield& surface_for(const SurfaceKey& key, const RunControl& run = {});
  // A user's heightmap (a path), read once. Throws std::runtime_error naming the file.
  const microgeom::Heightfield& heightmap(const std::filesystem::path& path);
  // Its heights_digest, computed once when it is read.
  const std::string& heightmap_digest(const std::filesystem::path& path);

  // The Embree scene (triangles) of a surface this cache returned, built once and kept until a scene of
  // another surface is asked for (one at a time: a 1024^2 scene is hundreds of MB). For the ranks of a split
  // run, which trace the same tile round after round.
  const HeightfieldScene& scene_for(const microgeom::Heightfield& field);

  std::filesystem::path path_for(const SurfaceKey& key) const;  // empty without a directory
  std::size_t builds() const { return builds_; }                // surfaces built by this cache
  const std::vector<std::string>& events() const { return events_; }  // built, read, rebuilt (why), in order

private:
  microgeom::Heightfield read_or_build(const SurfaceKey& key, const RunControl& run);
  microgeom::Heightfield build(const SurfaceKey& key, const RunControl& run);

  std::filesystem::path directory_;
  CacheFiles files_ = CacheFiles::read_write;
  std::map<std::string, microgeom::Heightfield> surfaces_;  // by hash, or "file:" path
  std::map<std::string, std::string> heightmap_digests_;    // by "file:" path
  std::size_t builds_ = 0;
  std::unique_ptr<HeightfieldScene> scene_;  // of scene_field_
  const microgeom::Heightfield* scene_field_ = nullptr;
  std::vector<std::string> events_;
};

}  // namespace microsim
