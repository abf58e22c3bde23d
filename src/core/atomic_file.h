// core: atomic file output, the one implementation behind every writer of microgeom and microsim
// (EXR images, meshes, JSON, text, SVG, markdown, .npy).
//
// A file is written to a temporary sibling of its destination (same directory, so the final rename is
// atomic; same extension, so writers that choose the format from the name still work) and renamed over
// the destination only once complete. On any failure the temporary is removed: the destination is either
// untouched or complete, and nothing is left behind.
//
// The temporary's name, ".STEM.tmp-PID-K.EXT", is claimed by creating the file exclusively (O_CREAT |
// O_EXCL), trying the next K while the name is taken. A temporary is therefore always a file that did not
// exist before: it can never be, and never truncate, an input of the command or any other existing file.
#pragma once

#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string_view>

namespace microsim {

// A temporary could not be created, written or renamed into place; the message names the destination.
struct FileWriteError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// A freshly created, empty temporary sibling of `destination`. Removed on destruction unless commit()
// has renamed it over the destination.
class TemporaryFile {
public:
  explicit TemporaryFile(std::filesystem::path destination);  // throws FileWriteError
  ~TemporaryFile();
  TemporaryFile(TemporaryFile&& other) noexcept;
  TemporaryFile& operator=(TemporaryFile&&) = delete;
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;

  const std::filesystem::path& path() const { return path_; }  // where to write
  const std::filesystem::path& destination() const { return destination_; }
  // Renames the temporary over the destination (replacing a file there). Throws FileWriteError.
  void commit();

private:
  std::filesystem::path destination_, path_;
  bool owned_ = true;  // false once committed or moved from
};

// Calls writer(tmp), which must write the complete file at the temporary path `tmp` (it exists, empty),
// then renames it over `path`. Exceptions of the writer propagate unchanged (after the temporary is
// removed); a failed rename throws FileWriteError.
void write_file_atomically(const std::filesystem::path& path,
                           const std::function<void(const std::filesystem::path& tmp)>& writer);

// Writes `bytes` to `path` atomically. Throws FileWriteError.
void write_file_atomically(const std::filesystem::path& path, std::string_view bytes);

}  // namespace microsim
