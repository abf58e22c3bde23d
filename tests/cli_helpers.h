// Shared helpers of the end-to-end command-line tests: run the built `microsim` (MICROSIM_BINARY) in a
// scratch directory, capture its exit code, stdout and stderr, and count what it left behind.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <sys/wait.h>
#include <unistd.h>

namespace microsim::test {

namespace fs = std::filesystem;

struct CliRun {
  int exit_code = -1;  // -1 when the process did not exit normally (killed by a signal)
  std::string out, err;
};

inline std::string slurp(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A fresh, empty directory under the system's temporary directory, unique to this test process.
inline fs::path scratch_dir(const std::string& prefix, const std::string& name) {
  auto dir = fs::temp_directory_path() / ("microsim_" + prefix + "_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Runs `microsim ARGS` with DIR as its working directory. Its stdout and stderr go to files beside DIR
// (not inside it), so that tests can assert that DIR holds exactly the files the command wrote.
inline CliRun run_cli(const fs::path& dir, const std::string& args) {
  const fs::path out = dir.parent_path() / (dir.filename().string() + ".stdout");
  const fs::path err = dir.parent_path() / (dir.filename().string() + ".stderr");
  const std::string cmd = "cd '" + dir.string() + "' && '" + MICROSIM_BINARY + "' " + args + " > '" +
                          out.string() + "' 2> '" + err.string() + "'";
  const int status = std::system(cmd.c_str());
  CliRun r{WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(out), slurp(err)};
  fs::remove(out);
  fs::remove(err);
  return r;
}

inline std::size_t file_count(const fs::path& dir) {
  std::size_t n = 0;
  for ([[maybe_unused]] auto& e : fs::directory_iterator(dir)) ++n;
  return n;
}

}  // namespace microsim::test
