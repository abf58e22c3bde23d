// tests: a fresh scratch directory for a test process: <temp>/microsim_PREFIX_NAME_PID, emptied first
// (ctest runs each test in its own process, so the pid keeps parallel tests apart). Every scratch directory
// is removed when the process that made it exits, also after a failed ASSERT (which returns from the test
// before its own clean-up); MICROSIM_KEEP_SCRATCH=1 in the environment keeps them to look at.
#pragma once

#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <string>
#include <system_error>
#include <vector>

#include <unistd.h>

namespace microsim::test {

// The scratch directories a process made, removed at its exit by that process only (a forked child that
// exits normally leaves its parent's alone).
class ScratchDirectories {
public:
  void add(const std::filesystem::path& dir) {
    const std::lock_guard lock(mutex_);
    dirs_.push_back(dir);
  }
  ~ScratchDirectories() {
    const char* keep = std::getenv("MICROSIM_KEEP_SCRATCH");
    if (::getpid() != owner_ || (keep && std::string(keep) == "1")) return;
    std::error_code ec;
    for (const std::filesystem::path& dir : dirs_) std::filesystem::remove_all(dir, ec);
  }

private:
  pid_t owner_ = ::getpid();
  std::mutex mutex_;
  std::vector<std::filesystem::path> dirs_;
};

inline ScratchDirectories& scratch_directories() {
  static ScratchDirectories dirs;
  return dirs;
}

inline std::filesystem::path scratch_dir(const std::string& prefix, const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() /
             ("microsim_" + prefix + "_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  scratch_directories().add(dir);
  return dir;
}

}  // namespace microsim::test
