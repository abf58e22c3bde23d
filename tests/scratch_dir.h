// tests: a fresh scratch directory for a test process: <temp>/microsim_PREFIX_NAME_PID, emptied first
// (ctest runs each test in its own process, so the pid keeps parallel tests apart).
#pragma once

#include <filesystem>
#include <string>

#include <unistd.h>

namespace microsim::test {

inline std::filesystem::path scratch_dir(const std::string& prefix, const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() /
             ("microsim_" + prefix + "_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace microsim::test
