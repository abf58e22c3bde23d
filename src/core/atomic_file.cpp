#include "core/atomic_file.h"

#include <fmt/core.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <string>
#include <system_error>

#include <fcntl.h>
#include <unistd.h>

namespace microsim {

namespace {

namespace fs = std::filesystem;

// Temporary names differ in K; a name some other file already has is skipped.
constexpr int kMaxNameAttempts = 1000;
// Keeps ".STEM.tmp-PID-K.EXT" within the usual 255-byte limit of a file name.
constexpr std::size_t kMaxStemBytes = 200;

// Creates an empty file at a new name next to `destination`; returns its path.
fs::path create_temporary_sibling(const fs::path& destination) {
  static std::atomic<unsigned> counter{0};
  const fs::path dir = destination.parent_path();
  const std::string stem = destination.stem().string().substr(0, kMaxStemBytes);
  const std::string ext = destination.extension().string();
  for (int attempt = 0; attempt < kMaxNameAttempts; ++attempt) {
    const fs::path tmp = dir / fmt::format(".{}.tmp-{}-{}{}", stem, ::getpid(), counter.fetch_add(1), ext);
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd >= 0) {
      ::close(fd);
      return tmp;
    }
    if (errno != EEXIST)
      throw FileWriteError(fmt::format("cannot write '{}': cannot create a temporary file in its directory: {}",
                                       destination.string(), std::strerror(errno)));
  }
  throw FileWriteError(fmt::format("cannot write '{}': no free temporary file name in its directory", destination.string()));
}

}  // namespace

TemporaryFile::TemporaryFile(fs::path destination)
    : destination_(std::move(destination)), path_(create_temporary_sibling(destination_)) {}

TemporaryFile::~TemporaryFile() {
  if (!owned_) return;
  std::error_code ignored;
  fs::remove(path_, ignored);
}

TemporaryFile::TemporaryFile(TemporaryFile&& other) noexcept
    : destination_(std::move(other.destination_)), path_(std::move(other.path_)), owned_(other.owned_) {
  other.owned_ = false;
}

void TemporaryFile::commit() {
  std::error_code ec;
  fs::rename(path_, destination_, ec);
  if (ec) throw FileWriteError(fmt::format("cannot move the output into '{}': {}", destination_.string(), ec.message()));
  owned_ = false;
}

void write_file_atomically(const fs::path& path, const std::function<void(const fs::path& tmp)>& writer) {
  TemporaryFile tmp(path);
  writer(tmp.path());
  tmp.commit();
}

void write_file_atomically(const fs::path& path, std::string_view bytes) {
  write_file_atomically(path, [&](const fs::path& tmp) {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw FileWriteError(fmt::format("cannot write '{}'", path.string()));
    out.write(bytes.data(), std::streamsize(bytes.size()));
    out.close();
    if (!out) throw FileWriteError(fmt::format("write error on '{}'", path.string()));
  });
}

}  // namespace microsim
