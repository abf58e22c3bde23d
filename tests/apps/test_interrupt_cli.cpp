// Interruption, end to end: Ctrl-C (SIGINT) sent to a running `microsim` mid-run.
// Interrupted is exit 130 everywhere, with what was done written and marked partial (JSON "partial": true,
// a PARTIAL line in markdown and on stdout), or nothing written and a note on stderr.
//
// Robust on a slow, loaded machine: the signal is sent only once the process has installed its SIGINT
// handler (read from /proc/PID/status) and, where a phase matters, once its output shows that phase; the
// work is large enough (seconds to minutes) that the signal always arrives mid-run, and the command then
// stops at its next check, so no test waits for the whole work.
#include "cli_helpers.h"

#include "microgeom/assembly.h"
#include "microgeom/heightfield.h"
#include "stats/histogram_io.h"
#include "stats/scatter_io.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <ostream>
#include <sstream>
#include <string>
#include <thread>

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_interrupt_cli {

namespace {

namespace fs = std::filesystem;
using microsim::test::slurp;
using Clock = std::chrono::steady_clock;

// Whether process `pid` catches SIGINT (its handler is installed): the SigCgt mask of /proc/PID/status.
bool catches_sigint(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("SigCgt:", 0) != 0) continue;
    const unsigned long long mask = std::stoull(line.substr(7), nullptr, 16);
    return (mask >> (SIGINT - 1)) & 1u;
  }
  return false;
}

// Polls every 20 ms until done() holds (true) or the deadline passes (false).
bool poll_until(Clock::time_point deadline, const std::function<bool()>& done) {
  while (!done()) {
    if (Clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

struct InterruptedRun {
  int exit_code = -1;        // -1: killed by a signal
  bool ended_early = false;  // finished before the signal could be sent (the work was too small)
  std::string out, err;
};

// Runs `microsim ARGS` in DIR; once it catches SIGINT, `phase(stdout, stderr)` holds and `delay` has passed
// since, sends SIGINT and waits for the process to end (a hang is killed after 180 s and fails).
InterruptedRun run_and_interrupt(const fs::path& dir, const std::string& args,
                                 const std::function<bool(const std::string&, const std::string&)>& phase,
                                 std::chrono::milliseconds delay) {
  const fs::path out = dir.parent_path() / (dir.filename().string() + ".stdout");
  const fs::path err = dir.parent_path() / (dir.filename().string() + ".stderr");
  const std::string command = "exec '" + microsim::test::microsim_binary() + "' " + args;
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (::chdir(dir.c_str()) != 0) ::_exit(127);
    const int fo = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int fe = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fo, 1);
    ::dup2(fe, 2);
    ::execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  InterruptedRun r;
  int status = 0;
  bool exited = false;
  const auto reaped = [&] { return exited = exited || ::waitpid(pid, &status, WNOHANG) == pid; };
  const auto kill_hard = [&](const std::string& why) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
    ADD_FAILURE() << "microsim " << args << ": " << why;
  };
  std::optional<Clock::time_point> ready_since;
  const bool ready = poll_until(Clock::now() + std::chrono::seconds(300), [&] {
    if (reaped()) return true;
    if (!ready_since && catches_sigint(pid) && phase(slurp(out), slurp(err))) ready_since = Clock::now();
    return ready_since && Clock::now() - *ready_since >= delay;
  });
  r.ended_early = exited;
  if (!ready) {
    kill_hard("the phase to interrupt never came");
  } else if (!exited) {
    ::kill(pid, SIGINT);
    if (!poll_until(Clock::now() + std::chrono::seconds(180), reaped)) kill_hard("did not stop within 180 s of SIGINT");
  }
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = slurp(out);
  r.err = slurp(err);
  fs::remove(out);
  fs::remove(err);
  return r;
}

const auto kAnyPhase = [](const std::string&, const std::string&) { return true; };
auto stderr_has(std::string text) {
  return [text](const std::string&, const std::string& err) { return err.find(text) != std::string::npos; };
}

// Exit 130, and the run was really interrupted (not finished before the signal, not killed by it).
void expect_interrupted(const InterruptedRun& r, const std::string& what) {
  ASSERT_FALSE(r.ended_early) << what << " finished before it could be interrupted: make its work larger";
  EXPECT_EQ(r.exit_code, 130) << what << "\nstdout: " << r.out << "\nstderr: " << r.err;
  EXPECT_NE(r.err.find("interrupted"), std::string::npos) << what << " says nothing on stderr: " << r.err;
}

nlohmann::json read_json(const fs::path& p) {
  EXPECT_TRUE(fs::exists(p)) << p;
  return fs::exists(p) ? nlohmann::json::parse(slurp(p)) : nlohmann::json();
}

// A 256^2 heightmap in DIR/s.exr (built with the library).
void put_heightmap(const fs::path& dir) {
  microgeom::AssemblyParams p;
  p.assembly = "beckmann";
  p.resolution = 256;
  microgeom::save_heightmap_exr(dir / "s.exr", microgeom::build_assembly(p));
}

// The builder polls its cancel callback between steps and throws BuildCancelled (no surface) once it says
// stop; a callback that never says stop changes nothing (same heights as without one).
TEST(BuildCancel, StopsBetweenStepsAndChangesNothingOtherwise) {
  for (const char* assembly : {"beckmann", "smith", "mixture", "sorted", "spikes"}) {
    microgeom::AssemblyParams p;
    p.assembly = assembly;
    p.resolution = 64;
    p.corr_cells = 4;
    int polls = 0;
    const auto never = [&] { return ++polls < 0; };
    EXPECT_EQ(microgeom::build_assembly(p, nullptr, {}, never).heights(), microgeom::build_assembly(p).heights())
        << assembly;
    EXPECT_GE(polls, 1) << assembly;
    for (const int stop_at : {1, polls}) {
      int calls = 0;
      EXPECT_THROW(microgeom::build_assembly(p, nullptr, {}, [&] { return ++calls >= stop_at; }),
                   microgeom::BuildCancelled)
          << assembly << " stopped at poll " << stop_at;
      EXPECT_EQ(calls, stop_at) << assembly;
    }
  }
}

TEST(CliInterrupt, TraceMaskingTableWhileBuildingSurfaces) {
  const fs::path dir = microsim::test::scratch_dir("interrupt", "table_build");
  // A 2048^2 surface takes seconds to build: 300 ms after the handler is installed the build is running.
  const auto r = run_and_interrupt(dir,
                                   "trace masking --table --assemblies smith --alphas 0.5 --thetas 30 --res 2048 "
                                   "--samples 100000 --vndf-rays 100000 --json t.json --markdown t.md",
                                   kAnyPhase, std::chrono::milliseconds(300));
  expect_interrupted(r, "trace masking --table");
  const auto j = read_json(dir / "t.json");
  EXPECT_EQ(j.value("partial", false), true);
  EXPECT_EQ(j.value("views_complete", -1), 0);
  EXPECT_NE(slurp(dir / "t.md").find("PARTIAL"), std::string::npos) << slurp(dir / "t.md");
  fs::remove_all(dir);
}

TEST(CliInterrupt, TraceMaskingTableWhileTracing) {
  const fs::path dir = microsim::test::scratch_dir("interrupt", "table_trace");
  // The first view's line on stderr: the second view (tens of millions of rays) is being traced.
  const auto r = run_and_interrupt(dir,
                                   "trace masking --table --assemblies beckmann --alphas 0.5 --thetas 30,60 --res 256 "
                                   "--samples 2000 --vndf-rays 5000000 --json t.json --markdown t.md",
                                   stderr_has(": TV "), std::chrono::milliseconds(300));
  expect_interrupted(r, "trace masking --table");
  const auto j = read_json(dir / "t.json");
  EXPECT_EQ(j.value("partial", false), true);
  EXPECT_EQ(j.value("views_complete", -1), 1);
  const std::string md = slurp(dir / "t.md");
  EXPECT_NE(md.find("PARTIAL"), std::string::npos) << md;
  EXPECT_NE(md.find("| beckmann | 0.5 | 30 |"), std::string::npos) << "the complete view is in the table: " << md;
  EXPECT_EQ(md.find("| beckmann | 0.5 | 60 |"), std::string::npos) << "the interrupted view is not: " << md;
  EXPECT_NE(r.out.find("PARTIAL"), std::string::npos) << r.out;
  fs::remove_all(dir);
}

TEST(CliInterrupt, ValidateAllMarksItsResultsPartial) {
  const fs::path dir = microsim::test::scratch_dir("interrupt", "validate_all");
  // Once the first row of the table is out, the batch is under way.
  const auto first_row = [](const std::string& out, const std::string&) { return out.find("\nndf ") != std::string::npos; };
  const auto r = run_and_interrupt(dir, "validate --all --samples 200000 --json all.json", first_row,
                                   std::chrono::milliseconds(0));
  expect_interrupted(r, "validate --all");
  const auto j = read_json(dir / "all.json");
  EXPECT_EQ(j.value("verdict", ""), "interrupted");
  EXPECT_EQ(j.value("partial", false), true);
  EXPECT_GE(j["results"].size(), 1u);
  EXPECT_LT(j["results"].size(), j.value("validations_requested", 0u));
  EXPECT_NE(r.out.find("INTERRUPTED"), std::string::npos) << r.out;
  fs::remove_all(dir);
}

// An albedo table keeps its complete alphas: interrupted during the second one (its line on stderr says the
// first is done), the files hold the first, marked partial.
TEST(CliInterrupt, AlbedoTableKeepsTheCompleteAlphas) {
  const fs::path dir = microsim::test::scratch_dir("interrupt", "albedo");
  const auto r = run_and_interrupt(dir,
                                   "albedo --model smith-walk --alphas 0.5,1 --mus 2 --rays 1500000 --out t.exr "
                                   "--csv t.csv --json t.json",
                                   stderr_has("albedo: alpha 0.5 done"), std::chrono::milliseconds(0));
  expect_interrupted(r, "albedo");
  const auto j = read_json(dir / "t.json");
  EXPECT_EQ(j.value("partial", false), true);
  EXPECT_EQ(j["alphas"].size(), 1u);
  EXPECT_NE(slurp(dir / "t.csv").find("# PARTIAL"), std::string::npos);
  EXPECT_NE(r.out.find("PARTIAL"), std::string::npos) << r.out;
  fs::remove_all(dir);
}

// Commands with no partial result to keep: Ctrl-C stops them with nothing written, said on stderr.
struct NothingWrittenCase {
  std::string name, args;
};
std::ostream& operator<<(std::ostream& os, const NothingWrittenCase& c) { return os << c.name; }

class InterruptWritesNothing : public ::testing::TestWithParam<NothingWrittenCase> {};

TEST_P(InterruptWritesNothing, ExitsInterruptedAndLeavesNoFile) {
  const NothingWrittenCase& c = GetParam();
  const fs::path dir = microsim::test::scratch_dir("interrupt", c.name);
  const auto r = run_and_interrupt(dir, c.args, kAnyPhase, std::chrono::milliseconds(300));
  expect_interrupted(r, c.args);
  EXPECT_NE(r.err.find("nothing written"), std::string::npos) << r.err;
  EXPECT_EQ(microsim::test::file_count(dir), 0u) << "no output and no temporary may be left";
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(
    CliInterrupt, InterruptWritesNothing,
    ::testing::Values(
        NothingWrittenCase{"ValidateAgainstEllipsoid", "validate --sampler heitz2018 --alpha 0.5 --theta 30 --against "
                                                       "ellipsoid --rays 400000000 --json v.json"},
        // The sampling has no check (the signal takes effect at its end): tens of seconds of it, so that it
        // cannot finish before the signal on an idle machine.
        NothingWrittenCase{"ValidateSampler", "validate --sampler heitz2018 --alpha 0.5 --theta 30 --samples 40000000 "
                                              "--json v.json"},
        NothingWrittenCase{"SurfaceBuild", "surface build --assembly smith --alpha 0.5 --res 2048 --out s.exr --json s.json"},
        NothingWrittenCase{"Stability", "stability --json st.json"},
        // Interrupted during its first alpha: no complete row.
        NothingWrittenCase{"AlbedoFirstAlpha", "albedo --model smith-walk --alphas 1 --mus 2 --rays 100000000 "
                                               "--out t.exr --csv t.csv --json t.json"}),
    [](const auto& info) { return info.param.name; });

// Commands that keep what they measured: Ctrl-C mid-trace writes it, JSON (and histogram) marked partial.
struct PartialCase {
  std::string name, args;
  std::string phase;      // stderr text printed just before the long trace starts
  std::string histogram;  // the histogram EXR written, if any
  std::string scatter;    // the scatter EXR written, if any
};
std::ostream& operator<<(std::ostream& os, const PartialCase& c) { return os << c.name; }

class InterruptWritesPartial : public ::testing::TestWithParam<PartialCase> {};

TEST_P(InterruptWritesPartial, ExitsInterruptedWithResultsMarkedPartial) {
  const PartialCase& c = GetParam();
  const fs::path dir = microsim::test::scratch_dir("interrupt", c.name);
  put_heightmap(dir);
  const auto r = run_and_interrupt(dir, c.args, stderr_has(c.phase), std::chrono::milliseconds(300));
  expect_interrupted(r, c.args);
  EXPECT_EQ(read_json(dir / "r.json").value("partial", false), true);
  if (!c.histogram.empty()) {
    EXPECT_TRUE(microsim::read_histogram_exr(dir / c.histogram).partial);
  }
  if (!c.scatter.empty()) {
    EXPECT_TRUE(microsim::read_scatter_exr(dir / c.scatter).histogram.partial);
  }
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(
    CliInterrupt, InterruptWritesPartial,
    ::testing::Values(
        PartialCase{"TraceVndfEllipsoid", "trace vndf --alpha 0.5 --theta 30 --rays 400000000 --out h.exr --json r.json",
                    "trace vndf: ellipsoid", "h.exr", ""},
        PartialCase{"TraceVndfHeightfield",
                    "trace vndf --surface s.exr --theta 30 --rays 400000000 --out h.exr --json r.json",
                    "trace vndf: heightfield", "h.exr", ""},
        PartialCase{"TraceMasking", "trace masking --surface s.exr --theta 30 --samples 400000000 --json r.json",
                    "trace masking:", "", ""},
        PartialCase{"ScatterSmithWalk",
                    "scatter --model smith-walk --alpha 0.5 --theta 30 --rays 400000000 --out h.exr --json r.json",
                    "scatter: Smith random walk", "", "h.exr"},
        PartialCase{"ScatterSurface", "scatter --surface s.exr --theta 30 --rays 400000000 --out h.exr --json r.json",
                    "scatter: surface", "", "h.exr"}),
    [](const auto& info) { return info.param.name; });

}  // namespace

}  // namespace test_interrupt_cli
