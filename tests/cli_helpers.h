// Shared helpers of the end-to-end command-line tests: run the built `microsim` (microsim_binary()) in a
// scratch directory, capture its exit code, stdout and stderr, and count what it left behind.
#pragma once

#include "binary_path.h"
#include "scratch_dir.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <ostream>
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

// Runs `microsim ARGS` with DIR as its working directory. Its stdout and stderr go to files beside DIR
// (not inside it), so that tests can assert that DIR holds exactly the files the command wrote.
inline CliRun run_cli(const fs::path& dir, const std::string& args) {
  const fs::path out = dir.parent_path() / (dir.filename().string() + ".stdout");
  const fs::path err = dir.parent_path() / (dir.filename().string() + ".stderr");
  const std::string cmd = "cd '" + dir.string() + "' && '" + microsim_binary() + "' " + args + " > '" +
                          out.string() + "' 2> '" + err.string() + "'";
  const int status = std::system(cmd.c_str());
  CliRun r{WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(out), slurp(err)};
  fs::remove(out);
  fs::remove(err);
  return r;
}

// Where the shared fixtures live: beside the test binary, in the build tree, not in the system's temporary
// directory (they outlive the test processes that use them: no process can remove them at its exit).
inline fs::path shared_fixture_root() {
  const fs::path root = fs::read_symlink("/proc/self/exe").parent_path() / "test-fixtures";
  fs::create_directories(root);
  return root;
}

// Removes the fixtures `name` of other builds (another key) published more than a day ago: no test run uses
// them any more, and the build tree does not keep a set per rebuild.
inline void remove_stale_fixtures(const fs::path& root, const std::string& name, const fs::path& current) {
  const std::string prefix = "microsim_fixture_" + name + "_";
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(root, ec)) {
    const std::string file = entry.path().filename().string();
    if (entry.path() == current || file.rfind(prefix, 0) != 0 ||
        file.find_first_not_of("0123456789", prefix.size()) != std::string::npos)
      continue;  // the current fixture, another name, or a fixture being made (_tmp_PID)
    const auto published = fs::last_write_time(entry.path() / ".complete", ec);
    if (!ec && fs::file_time_type::clock::now() - published > std::chrono::hours(24)) fs::remove_all(entry.path(), ec);
  }
}

// A directory of inputs that many tests share, built once per build of the tests. ctest runs every test in
// a process of its own, so a function-local static would be rebuilt by each; this one lives in
// shared_fixture_root(), keyed by the size and modification time of the test binary and of `microsim` (a new
// build gets a new directory). `build` fills a private directory that is then renamed into place; when
// two processes race, the first rename wins and the other uses its files (both built the same content). A
// fixture whose making failed a test assertion is used by this process only, never published, and removed
// when it exits.
inline fs::path shared_fixture_dir(const std::string& name, const std::function<void(const fs::path&)>& build) {
  std::size_t key = 0;
  for (const fs::path& f : {fs::read_symlink("/proc/self/exe"), fs::path(microsim_binary())}) {
    const auto stamp = fs::last_write_time(f).time_since_epoch().count();
    key = key * 1000003u ^ std::hash<std::string>{}(f.string() + ":" + std::to_string(fs::file_size(f)) + ":" +
                                                     std::to_string(stamp));
  }
  const fs::path root = shared_fixture_root();
  const fs::path dir = root / ("microsim_fixture_" + name + "_" + std::to_string(key));
  if (fs::exists(dir / ".complete")) return dir;
  const fs::path tmp = root / ("microsim_fixture_" + name + "_tmp_" + std::to_string(::getpid()));
  fs::remove_all(tmp);
  fs::create_directories(tmp);
  build(tmp);
  if (::testing::Test::HasFailure()) {  // never publish a fixture whose making failed
    scratch_directories().add(tmp);
    return tmp;
  }
  std::ofstream(tmp / ".complete") << "complete\n";
  std::error_code ec;
  fs::rename(tmp, dir, ec);  // fails when another process got there first
  if (ec) fs::remove_all(tmp);
  else remove_stale_fixtures(root, name, dir);
  return dir;
}

// Copies the regular files of `from` (a shared fixture) into `to`, leaving out the fixture's marker.
inline void copy_fixture_files(const fs::path& from, const fs::path& to) {
  for (const auto& e : fs::directory_iterator(from))
    if (e.is_regular_file() && e.path().filename() != ".complete") fs::copy_file(e.path(), to / e.path().filename());
}

inline std::size_t file_count(const fs::path& dir) {
  std::size_t n = 0;
  for ([[maybe_unused]] auto& e : fs::directory_iterator(dir)) ++n;
  return n;
}

}  // namespace microsim::test

namespace microsim::test {

// Every regular file below DIR with its size and contents: two snapshots compare equal exactly when no
// file was created, removed or changed.
inline std::map<std::string, std::string> snapshot_files(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) files[fs::relative(e.path(), dir).string()] = slurp(e.path());
  return files;
}

// One row of a bad-input table: the command's arguments, the exit code it must give and a piece
// of text its stderr must contain (the bad value, named). The command runs in a scratch directory that
// `prepare` fills with the inputs it needs; afterwards no file there may have been created or changed.
struct BadInputCase {
  std::string name;     // a gtest-safe identifier
  std::string args;     // after `microsim`
  int exit_code = 2;
  std::string message;  // must appear in stderr
  std::function<void(const fs::path&)> prepare = nullptr;
};

inline std::ostream& operator<<(std::ostream& os, const BadInputCase& c) { return os << c.name; }

// Runs one case: exit code, message, and "nothing written, nothing changed".
inline void expect_bad_input(const BadInputCase& c, const std::string& suite) {
  const fs::path dir = scratch_dir(suite, c.name);
  if (c.prepare) c.prepare(dir);
  const auto before = snapshot_files(dir);
  const CliRun r = run_cli(dir, c.args);
  EXPECT_EQ(r.exit_code, c.exit_code) << "microsim " << c.args << "\nstderr: " << r.err;
  EXPECT_NE(r.err.find(c.message), std::string::npos)
      << "microsim " << c.args << "\nstderr does not contain '" << c.message << "': " << r.err;
  EXPECT_TRUE(snapshot_files(dir) == before) << "microsim " << c.args << " created or changed a file";
  fs::remove_all(dir);
}

}  // namespace microsim::test
