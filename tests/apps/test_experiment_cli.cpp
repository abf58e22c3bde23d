// `microsim plan` and `microsim run` end to end on a tiny spec (seconds): the plan table, results.json with
// every decision and target met, a rerun with another seed within the stated error (and the same check
// failing between two different materials: it can fail), bad specs (exit 2, key and line named, nothing run
// or written), and the results directory of another spec refused. The run's verdict (experiment/verdict.h):
// a rejected dump (the talk listing's samples) exits 1, named in results.json, on stdout and in the report's
// headline, and again when the finished or interrupted directory is resumed; a passing dump exits 0 (verdict
// pass), a run without a test has the verdict none; a BSDF plugin's rejected battery fails the run as well.
#include "cli_helpers.h"
#include "sample_dumps.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <csignal>
#include <fstream>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_experiment_cli {

namespace {

namespace fs = std::filesystem;
using microsim::test::run_cli;
using microsim::test::scratch_dir;
using microsim::test::slurp;

std::string tiny_spec(const std::string& alphas) {
  return "name = \"tiny\"\nseed = 3\n\n[[material]]\nname = \"m\"\nalphas = " + alphas +
         "\ntype = \"mirror\"\n\n[[quantity]]\nkind = \"albedo\"\nmaterial = \"m\"\norders = \"all\"\nmus = 4\n"
         "target_relative_error = 0.02\n\n[[quantity]]\nkind = \"albedo\"\nmaterial = \"m\"\nmus = 4\n"
         "target_relative_error = 0.001\n\n[[quantity]]\nkind = \"vndf\"\nmaterial = \"m\"\ntheta = [50]\nrows = 7\n"
         "target_tv = 0.05\n";
}

void write(const fs::path& path, const std::string& text) { std::ofstream(path) << text; }

nlohmann::json results_of(const fs::path& dir) { return nlohmann::json::parse(slurp(dir / "results.json")); }

// The walk's albedo tables of two runs agree within their errors: every cell and E_avg of every E quantity
// within 4 combined standard errors, and within 4 sqrt(2) times the relative target. Returns the failures.
int disagreements(const nlohmann::json& a, const nlohmann::json& b, double target) {
  int bad = 0;
  const nlohmann::json& qa = a["values"]["quantities"];
  const nlohmann::json& qb = b["values"]["quantities"];
  for (const auto& [name, va] : qa.items()) {
    if (name[0] != 'E') continue;
    const nlohmann::json& vb = qb[name];
    for (std::size_t r = 0; r < va["value"].size(); ++r)
      for (std::size_t c = 0; c < va["value"][r].size(); ++c) {
        const double x = va["value"][r][c], y = vb["value"][r][c];
        const double sx = va["error"][r][c], sy = vb["error"][r][c];
        const double diff = std::abs(x - y);
        bad += diff > 4 * std::hypot(sx, sy) + 1e-15 || diff > 4 * std::sqrt(2.0) * target * std::abs(x);
      }
  }
  return bad;
}

TEST(ExperimentCli, PlanPrintsOneDecisionPerMeasurement) {
  const fs::path dir = scratch_dir("experiment", "plan");
  write(dir / "tiny.toml", tiny_spec("[0.3, 0.8]"));
  const auto r = run_cli(dir, "plan tiny.toml --json plan.json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* word : {"smith-walk", "analytic", "ellipsoid-oracle", "paths per cell", "rays", "predicted"})
    EXPECT_NE(r.out.find(word), std::string::npos) << word << "\n" << r.out;
  const nlohmann::json plan = nlohmann::json::parse(slurp(dir / "plan.json"));
  ASSERT_EQ(plan["plan"]["decisions"].size(), 4u);  // two tables, then the VNDF at each of the two alphas
  EXPECT_GE(plan["plan"]["decisions"][0]["order_cap"].get<int>(), 4);
  EXPECT_FALSE(plan["plan"]["decisions"][2]["model_reason"].get<std::string>().empty());
  EXPECT_EQ(run_cli(dir, "plan --help").exit_code, 0);
  const auto dry = run_cli(dir, "run tiny.toml --out dry --dry-run");  // the plan, nothing written
  EXPECT_EQ(dry.exit_code, 0) << dry.err;
  EXPECT_NE(dry.out.find("predicted total"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir / "dry"));
  fs::remove_all(dir);
}

TEST(ExperimentCli, RunMeetsTheTargetsAndAnotherSeedAgrees) {
  const fs::path dir = scratch_dir("experiment", "run");
  write(dir / "tiny.toml", tiny_spec("[0.3, 0.8]"));
  write(dir / "other.toml", tiny_spec("[0.5, 1.0]"));
  const auto a = run_cli(dir, "run tiny.toml --out a");
  ASSERT_EQ(a.exit_code, 0) << a.err;
  const auto b = run_cli(dir, "run tiny.toml --out b --seed 11");
  ASSERT_EQ(b.exit_code, 0) << b.err;
  const nlohmann::json ra = results_of(dir / "a"), rb = results_of(dir / "b");
  EXPECT_TRUE(ra["results"]["all_targets_met"].get<bool>());
  EXPECT_FALSE(ra["partial"].get<bool>());
  EXPECT_NE(ra["command"].get<std::string>().find("microsim run tiny.toml --out a"), std::string::npos);
  for (const auto& m : ra["results"]["measurements"]) {
    EXPECT_TRUE(m["met"].get<bool>()) << m["measurement"];
    EXPECT_LE(m["achieved"].get<double>(), m["target"].get<double>());
    EXPECT_GT(m["cost"]["seconds"].get<double>(), 0);
  }
  EXPECT_TRUE(fs::exists(dir / "a" / "albedo-0.csv"));
  // The walk's table (measurement 0) and the analytic one (1): the other seed lands within the stated error.
  EXPECT_EQ(disagreements(ra["results"]["measurements"][0], rb["results"]["measurements"][0], 0.02), 0);
  EXPECT_EQ(disagreements(ra["results"]["measurements"][1], rb["results"]["measurements"][1], 0.001), 0);
  // The VNDF: each run's histogram within the resolved TV of the analytic D_v; its target is the spec's
  // target_tv, the achieved error the TV resolved (twice the noise floor).
  for (const nlohmann::json* r : {&ra, &rb})
    for (const std::size_t k : {2u, 3u}) {
      const nlohmann::json& m = (*r)["results"]["measurements"][k];
      EXPECT_LE(m["values"]["total_variation"].get<double>(), 0.05);
      EXPECT_EQ(m["target"].get<double>(), 0.05);
      EXPECT_EQ(m["achieved"].get<double>(), 2 * m["values"]["noise_floor_tv"].get<double>());
    }
  // Negative control: the same check between two materials (alphas 0.3, 0.8 against 0.5, 1) must fail.
  const auto c = run_cli(dir, "run other.toml --out c");
  ASSERT_EQ(c.exit_code, 0) << c.err;
  EXPECT_GT(disagreements(ra["results"]["measurements"][0], results_of(dir / "c")["results"]["measurements"][0], 0.02), 0);
  fs::remove_all(dir);
}

TEST(ExperimentCli, RefusesAnotherSpecsResultsAndRerunsItsOwn) {
  const fs::path dir = scratch_dir("experiment", "refuse");
  write(dir / "tiny.toml", "[[material]]\nname = \"m\"\nalphas = [0.3]\ntype = \"mirror\"\n[[quantity]]\nkind = \"albedo\"\n"
                           "material = \"m\"\nmus = 2\ntarget_relative_error = 0.01\n");
  write(dir / "other.toml", "[[material]]\nname = \"m\"\nalphas = [0.4]\ntype = \"mirror\"\n[[quantity]]\nkind = \"albedo\"\n"
                            "material = \"m\"\nmus = 2\ntarget_relative_error = 0.01\n");
  ASSERT_EQ(run_cli(dir, "run tiny.toml --out out").exit_code, 0);
  const std::string before = slurp(dir / "out" / "results.json");
  const auto other = run_cli(dir, "run other.toml --out out");
  EXPECT_EQ(other.exit_code, 2) << other.err;
  EXPECT_NE(other.err.find("another spec"), std::string::npos) << other.err;
  EXPECT_EQ(slurp(dir / "out" / "results.json"), before);
  EXPECT_EQ(run_cli(dir, "run tiny.toml --out out").exit_code, 0);  // its own results: a rerun
  fs::create_directories(dir / "full");
  write(dir / "full" / "notes.txt", "mine");
  EXPECT_EQ(run_cli(dir, "run tiny.toml --out full").exit_code, 2);
  fs::remove_all(dir);
}

TEST(ExperimentCli, BadSpecsNameKeyAndLineAndRunNothing) {
  const fs::path dir = scratch_dir("experiment", "bad");
  write(dir / "bad.toml", "[[material]]\nname = \"m\"\nalpha = 0.3\ntype = \"mirror\"\n\n[[quantity]]\nkind = \"vndf\"\n"
                          "material = \"m\"\ntheta = [30]\ntarget_tv = 0\n");
  for (const char* command : {"plan bad.toml", "run bad.toml --out out"}) {
    const auto r = run_cli(dir, command);
    EXPECT_EQ(r.exit_code, 2) << command;
    EXPECT_NE(r.err.find("bad.toml:10: quantity[0].target_tv"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "out"));
  }
  const auto missing = run_cli(dir, "plan nothing.toml");
  EXPECT_EQ(missing.exit_code, 2);
  fs::remove_all(dir);
}

// Whether the run's stderr (the file `err`) says its first measurement met its target.
bool first_met(const fs::path& err) { return slurp(err).find("met after") != std::string::npos; }

// `microsim run SPEC --out OUT` in dir, interrupted (SIGINT) `after_ms` after `ready` (by default: its first
// measurement met its target); the exit status (waitpid's) and the run's stderr.
int run_experiment_and_interrupt(const fs::path& dir, const std::string& spec, const std::string& out, int after_ms,
                                 std::string& stderr_text,
                                 const std::function<bool(const fs::path& err)>& ready = first_met) {
  const fs::path err = dir.parent_path() / (dir.filename().string() + "." + out + ".stderr");
  const std::string binary = microsim::test::microsim_binary();
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (::chdir(dir.c_str()) != 0) ::_exit(127);
    const int fe = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int fo = ::open("/dev/null", O_WRONLY);
    ::dup2(fo, 1);
    ::dup2(fe, 2);
    ::execl(binary.c_str(), binary.c_str(), "run", spec.c_str(), "--out", out.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (!ready(err) && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  std::this_thread::sleep_for(std::chrono::milliseconds(after_ms));
  ::kill(pid, SIGINT);
  int status = 0;
  ::waitpid(pid, &status, 0);
  stderr_text = slurp(err);
  fs::remove(err);
  return status;
}

// Ctrl-C once the first measurement is done and the second (a long VNDF) is running: exit 130, results.json
// written and marked partial, the finished measurement kept.
TEST(ExperimentCli, InterruptedRunWritesWhatWasDoneMarkedPartial) {
  const fs::path dir = scratch_dir("experiment", "interrupt");
  write(dir / "long.toml", "[[material]]\nname = \"m\"\nalpha = 0.3\ntype = \"mirror\"\n[[quantity]]\nkind = \"albedo\"\n"
                           "material = \"m\"\nmus = 2\ntarget_relative_error = 0.01\n[[quantity]]\nkind = \"vndf\"\n"
                           "material = \"m\"\ntheta = [40]\ntarget_tv = 0.001\n");
  std::string stderr_text;
  const int status = run_experiment_and_interrupt(dir, "long.toml", "out", 300, stderr_text);
  ASSERT_TRUE(WIFEXITED(status)) << stderr_text;
  EXPECT_EQ(WEXITSTATUS(status), 130) << stderr_text;
  ASSERT_TRUE(fs::exists(dir / "out" / "results.json")) << stderr_text;
  const nlohmann::json r = results_of(dir / "out");
  EXPECT_TRUE(r["partial"].get<bool>());
  EXPECT_FALSE(r["results"]["all_targets_met"].get<bool>());
  ASSERT_GE(r["results"]["measurements"].size(), 1u);
  EXPECT_TRUE(r["results"]["measurements"][0]["met"].get<bool>());
  fs::remove_all(dir);
}

// Ctrl-C while planning, after the first of two tiles was built (smith 256^2 for a VNDF at TV 0.42; the
// second, for TV 0.05, is 2048^2): exit 130, no results, and the message says the built tile is kept in
// DIR/surfaces (it is: not "nothing written").
TEST(ExperimentCli, InterruptedWhilePlanningKeepsTheTilesItBuilt) {
  const fs::path dir = scratch_dir("experiment", "interrupt_plan");
  write(dir / "tiles.toml", "[[material]]\nname = \"m\"\nalpha = 0.5\ntype = \"mirror\"\n"
                            "[[quantity]]\nkind = \"vndf\"\nmaterial = \"m\"\nsurface = \"smith\"\ntheta = [40]\n"
                            "target_tv = 0.42\n[[quantity]]\nkind = \"vndf\"\nmaterial = \"m\"\nsurface = \"smith\"\n"
                            "theta = [40]\ntarget_tv = 0.05\n");
  const auto tiles = [&] {
    std::size_t n = 0;
    if (fs::is_directory(dir / "out" / "surfaces"))
      for (const auto& e : fs::directory_iterator(dir / "out" / "surfaces")) n += e.path().extension() == ".exr";
    return n;
  };
  std::string stderr_text;
  const int status = run_experiment_and_interrupt(dir, "tiles.toml", "out", 0, stderr_text,
                                                  [&](const fs::path&) { return tiles() >= 1; });
  ASSERT_TRUE(WIFEXITED(status)) << stderr_text;
  EXPECT_EQ(WEXITSTATUS(status), 130) << stderr_text;
  EXPECT_FALSE(fs::exists(dir / "out" / "results.json"));
  ASSERT_GE(tiles(), 1u);
  EXPECT_NE(stderr_text.find("kept in"), std::string::npos) << stderr_text;
  EXPECT_EQ(stderr_text.find("nothing written"), std::string::npos) << stderr_text;
  fs::remove_all(dir);
}

// What a run measured, as results.json records it, without the timings.
nlohmann::json measured_values(const nlohmann::json& results) {
  nlohmann::json out = nlohmann::json::array();
  for (nlohmann::json m : results["results"]["measurements"]) {
    m.erase("cost");
    for (auto& r : m["rounds"]) r.erase("seconds");
    m["values"].erase("seconds");
    m["values"].erase("row_seconds");
    out.push_back(m);
  }
  return out;
}

// Ctrl-C in the middle of a VNDF round, then the same command again: it resumes (the finished measurement
// kept, the round traced on from its first missing block) and results.json holds the values of an
// uninterrupted run of the same seed, bit for bit; the report is written both times.
TEST(ExperimentCli, InterruptedThenResumedGivesTheUninterruptedResults) {
  const fs::path dir = scratch_dir("experiment", "resume");
  write(dir / "spec.toml", "seed = 4\n[[material]]\nname = \"m\"\nalpha = 0.4\ntype = \"mirror\"\n[[quantity]]\n"
                           "kind = \"albedo\"\nmaterial = \"m\"\nmus = 2\ntarget_relative_error = 0.01\n[[quantity]]\n"
                           "kind = \"vndf\"\nmaterial = \"m\"\ntheta = [40]\nrows = 7\ntarget_tv = 0.0015\n");
  const auto whole = run_cli(dir, "run spec.toml --out whole");
  ASSERT_EQ(whole.exit_code, 0) << whole.err;
  std::string first;
  const int status = run_experiment_and_interrupt(dir, "spec.toml", "cut", 200, first);
  ASSERT_TRUE(WIFEXITED(status)) << first;
  ASSERT_EQ(WEXITSTATUS(status), 130) << first;  // cut in the VNDF (if it ever finishes in 200 ms: raise its cost)
  EXPECT_TRUE(results_of(dir / "cut")["partial"].get<bool>());
  EXPECT_TRUE(fs::exists(dir / "cut" / "index.html"));
  const auto resumed = run_cli(dir, "run spec.toml --out cut");
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  EXPECT_NE(resumed.err.find("resuming: 1 of 2 measurements done"), std::string::npos) << resumed.err;
  const nlohmann::json a = results_of(dir / "whole"), b = results_of(dir / "cut");
  EXPECT_FALSE(b["partial"].get<bool>());
  EXPECT_EQ(measured_values(b).dump(), measured_values(a).dump());
  const auto other_seed = run_cli(dir, "run spec.toml --out cut --seed 5");  // another seed's run: refused
  EXPECT_EQ(other_seed.exit_code, 2);
  EXPECT_NE(other_seed.err.find("seed 4"), std::string::npos) << other_seed.err;
  fs::remove_all(dir);
}

// ---- the verdict: what the tests found, apart from enough samples --------------------------------------------

// A spec validating dumps at GGX alpha 0.3, theta 40 (rows 7, detect TV 0.05: planned below the dumps' 50000
// samples, so each meets its target), one quantity per dump, then `extra` (more quantities).
std::string dump_spec(const std::vector<std::string>& dumps, const std::string& extra = "") {
  std::string spec = "name = \"dumps\"\nseed = 5\n[[material]]\nname = \"m\"\nalpha = 0.3\ntype = \"mirror\"\n";
  for (const std::string& dump : dumps)
    spec += "[[quantity]]\nkind = \"validation\"\nmaterial = \"m\"\ndump = \"" + dump +
            "\"\ntheta = [40]\nrows = 7\ndetect_tv = 0.05\n";
  return spec + extra;
}

// The talk listing's samples (rejected) and heitz2018's (passing), as a renderer's dumps in dir.
void write_dumps(const fs::path& dir) {
  microsim::test::write_sampler_dump(dir / "talk.npy", "heitz2018-talk", 0.3, 40, 50000);
  microsim::test::write_sampler_dump(dir / "good.npy", "heitz2018", 0.3, 40, 50000);
}

// The report's body begins with the verdict's headline (id "verdict") of that class; returns the headline.
std::string headline(const fs::path& out, const std::string& verdict) {
  const std::string page = slurp(out / "index.html");
  const std::size_t body = page.find("<body>\n");
  EXPECT_NE(body, std::string::npos);
  const std::string first = "<p id=\"verdict\" class=\"verdict " + verdict + "\">";
  EXPECT_EQ(page.compare(body + 7, first.size(), first), 0) << page.substr(body, 300);
  return page.substr(body + 7, page.find("</p>", body) - body - 7);
}

// The verdict's members of results.json, as one string to compare between runs.
std::string verdict_of(const nlohmann::json& doc) {
  const nlohmann::json& r = doc["results"];
  return nlohmann::json{{"verdict", r["verdict"]}, {"rejected", r["rejected"]}, {"tested", r["tested"]}}.dump();
}

TEST(ExperimentCli, ARejectedDumpFailsTheRunNamedEverywhereAndAgainWhenRerun) {
  const fs::path dir = scratch_dir("experiment", "verdict_fail");
  write_dumps(dir);
  write(dir / "fail.toml", dump_spec({"talk.npy", "good.npy"}, "[[quantity]]\nkind = \"albedo\"\nmaterial = \"m\"\n"
                                                               "mus = 2\ntarget_relative_error = 0.01\n"));
  const auto run = run_cli(dir, "run fail.toml --out out");
  EXPECT_EQ(run.exit_code, 1) << run.out << run.err;
  const nlohmann::json doc = results_of(dir / "out");
  const nlohmann::json& r = doc["results"];
  ASSERT_EQ(r["measurements"].size(), 3u);
  const std::string talk = r["measurements"][0]["measurement"].get<std::string>();
  EXPECT_EQ(r["measurements"][0]["values"]["validation"]["verdict"], "fail");
  EXPECT_EQ(r["measurements"][1]["values"]["validation"]["verdict"], "pass");
  EXPECT_TRUE(r["all_targets_met"].get<bool>());  // enough samples: a separate question from the verdict
  EXPECT_EQ(r["verdict"], "fail");
  EXPECT_EQ(r["rejected"], nlohmann::json::array({talk}));
  EXPECT_EQ(r["tested"], 2);
  EXPECT_NE(run.out.find("All targets met: yes. Verdict: FAIL (rejected: " + talk + ")"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("| REJECTED |"), std::string::npos) << run.out;
  const std::string top = headline(dir / "out", "fail");
  EXPECT_NE(top.find("Verdict: FAIL"), std::string::npos) << top;
  EXPECT_NE(top.find(talk), std::string::npos) << top;
  EXPECT_EQ(top.find(r["measurements"][1]["measurement"].get<std::string>()), std::string::npos) << top;
  EXPECT_NE(slurp(dir / "out" / "index.html").find("<td><span class=\"notmet\">rejected</span></td>"), std::string::npos);
  // The same command on the finished directory: kept as it is, the same verdict and exit code.
  const auto again = run_cli(dir, "run fail.toml --out out");
  EXPECT_EQ(again.exit_code, 1) << again.err;
  EXPECT_NE(again.err.find("resuming: 3 of 3 measurements done"), std::string::npos) << again.err;
  EXPECT_EQ(verdict_of(results_of(dir / "out")), verdict_of(doc));
  EXPECT_NE(again.out.find("Verdict: FAIL (rejected: " + talk + ")"), std::string::npos) << again.out;
  fs::remove_all(dir);
}

// A bsdf quantity (a renderer's BSDF plugin through the battery of check-bsdf): the worked plugin with its planted
// eval() bug fails the run (exit 1), its battery's table in the report; a spec naming no plugin file is exit 2.
std::string bsdf_spec(const std::string& plugin) {
  return "[[material]]\nname = \"glass\"\nalpha = 0.3\ntype = \"dielectric\"\neta = 1.5\n\n[[quantity]]\n"
         "kind = \"bsdf\"\nmaterial = \"glass\"\nplugin = \"" + plugin + "\"\n"
         "params = { kind = \"dielectric\", alpha = 0.3, eta = 1.5 }\nviews = [60]\nsamples = 20000\n";
}

TEST(ExperimentCli, ARejectedBsdfPluginFailsTheRunAndAMissingOneIsABadSpec) {
  const fs::path dir = scratch_dir("experiment", "bsdf");
  write(dir / "bug.toml", bsdf_spec(MICROSIM_PLUGIN_EVAL_BUG));
  const auto run = run_cli(dir, "run bug.toml --out out");
  EXPECT_EQ(run.exit_code, 1) << run.out << run.err;
  const nlohmann::json r = results_of(dir / "out")["results"];
  EXPECT_EQ(r["measurements"][0]["values"]["battery"]["verdict"], "fail");
  EXPECT_EQ(r["verdict"], "fail");
  EXPECT_EQ(r["tested"], 1);
  const std::string page = slurp(dir / "out" / "index.html");
  EXPECT_NE(page.find("<th>test</th><th>view</th><th>p</th><th>verdict</th>"), std::string::npos);
  EXPECT_NE(page.find("<td>reciprocity</td>"), std::string::npos);
  write(dir / "missing.toml", bsdf_spec("no-such-plugin.so"));
  const auto missing = run_cli(dir, "run missing.toml --out missing");
  EXPECT_EQ(missing.exit_code, 2) << missing.err;
  EXPECT_NE(missing.err.find("missing.toml:10: quantity[0].plugin"), std::string::npos) << missing.err;
  EXPECT_FALSE(fs::exists(dir / "missing"));
  fs::remove_all(dir);
}

// No file a spec reads is ever written: `plan --json` naming its dump, a spec or a dump inside `run --out` (where
// the run writes its files) are exit 2 naming the key, and the files keep their bytes.
TEST(ExperimentCli, NoFileTheSpecReadsIsOverwritten) {
  const fs::path dir = scratch_dir("experiment", "inputs");
  write_dumps(dir);
  write(dir / "s.toml", dump_spec({"good.npy"}));
  const std::string dump = slurp(dir / "good.npy");
  const auto plan = run_cli(dir, "plan s.toml --json good.npy");
  EXPECT_EQ(plan.exit_code, 2) << plan.err;
  EXPECT_NE(plan.err.find("quantity[0].dump"), std::string::npos) << plan.err;
  EXPECT_EQ(slurp(dir / "good.npy"), dump);
  fs::create_directories(dir / "out");
  fs::copy_file(dir / "good.npy", dir / "out" / "good.npy");
  write(dir / "out" / "index.html", dump_spec({"good.npy"}));
  const auto spec_inside = run_cli(dir, "run out/index.html --out out");
  EXPECT_EQ(spec_inside.exit_code, 2) << spec_inside.err;
  EXPECT_NE(spec_inside.err.find("lies inside --out"), std::string::npos) << spec_inside.err;
  EXPECT_EQ(slurp(dir / "out" / "index.html"), dump_spec({"good.npy"}));
  write(dir / "t.toml", dump_spec({"out/good.npy"}));
  const auto dump_inside = run_cli(dir, "run t.toml --out out");
  EXPECT_EQ(dump_inside.exit_code, 2) << dump_inside.err;
  EXPECT_NE(dump_inside.err.find("quantity[0].dump"), std::string::npos) << dump_inside.err;
  EXPECT_FALSE(fs::exists(dir / "out" / "results.json"));
  fs::remove_all(dir);
}

// Running the command again on the same --out resumes only with the same input files: a dump replaced by one that
// the validation rejects (the negative control's samples) is refused, exit 2 naming the key, never the old pass.
TEST(ExperimentCli, AReplacedDumpIsNotGivenTheOldVerdict) {
  const fs::path dir = scratch_dir("experiment", "replaced_dump");
  write_dumps(dir);
  write(dir / "s.toml", dump_spec({"good.npy"}));
  ASSERT_EQ(run_cli(dir, "run s.toml --out out").exit_code, 0);
  EXPECT_EQ(run_cli(dir, "run s.toml --out out").exit_code, 0);  // the same files: the complete run again
  fs::copy_file(dir / "talk.npy", dir / "good.npy", fs::copy_options::overwrite_existing);
  const auto again = run_cli(dir, "run s.toml --out out");
  EXPECT_EQ(again.exit_code, 2) << again.out << again.err;
  EXPECT_NE(again.err.find("quantity[0].dump ('good.npy') changed since that run"), std::string::npos) << again.err;
  EXPECT_EQ(run_cli(dir, "run s.toml --out fresh").exit_code, 1);  // the replaced dump, measured: rejected
  fs::remove_all(dir);
}

// A job array's shards record the digests of the files the spec reads: a merge after one was replaced is refused
// (exit 2, naming the key), nothing written; with the files as the shards saw them the merge runs.
TEST(ExperimentCli, AMergeAfterADumpWasReplacedIsRefused) {
  const fs::path dir = scratch_dir("experiment", "replaced_dump_shards");
  write_dumps(dir);
  write(dir / "s.toml", dump_spec({"good.npy"}));
  for (const char* k : {"1", "2"})
    ASSERT_EQ(run_cli(dir, std::string("run s.toml --out p") + k + " --shard " + k + "/2").exit_code, 0);
  fs::copy_file(dir / "good.npy", dir / "kept.npy");
  fs::copy_file(dir / "talk.npy", dir / "good.npy", fs::copy_options::overwrite_existing);
  const auto refused = run_cli(dir, "run s.toml --out merged --merge p1 p2");
  EXPECT_EQ(refused.exit_code, 2) << refused.out << refused.err;
  EXPECT_NE(refused.err.find("quantity[0].dump"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("has changed since the shard ran"), std::string::npos) << refused.err;
  EXPECT_FALSE(fs::exists(dir / "merged" / "results.json"));
  fs::copy_file(dir / "kept.npy", dir / "good.npy", fs::copy_options::overwrite_existing);
  EXPECT_EQ(run_cli(dir, "run s.toml --out merged --merge p1 p2").exit_code, 0);
  fs::remove_all(dir);
}

TEST(ExperimentCli, APassingDumpPassesAndARunWithoutATestHasNoVerdict) {
  const fs::path dir = scratch_dir("experiment", "verdict_pass");
  write_dumps(dir);
  write(dir / "pass.toml", dump_spec({"good.npy"}));
  const auto run = run_cli(dir, "run pass.toml --out out");
  EXPECT_EQ(run.exit_code, 0) << run.out << run.err;
  const nlohmann::json doc = results_of(dir / "out");
  const nlohmann::json& r = doc["results"];
  EXPECT_EQ(r["verdict"], "pass");
  EXPECT_EQ(r["rejected"], nlohmann::json::array());
  EXPECT_EQ(r["tested"], 1);
  EXPECT_NE(run.out.find("All targets met: yes. Verdict: pass"), std::string::npos) << run.out;
  EXPECT_NE(headline(dir / "out", "pass").find("Verdict: pass"), std::string::npos);
  // The plan and the report say what is done with a dump: its rows, read from the file (detect_tv optional).
  EXPECT_NE(slurp(dir / "out" / "index.html").find("a renderer's dump (good.npy)"), std::string::npos);
  write(dir / "rows.toml", "[[material]]\nname = \"m\"\nalpha = 0.3\ntype = \"mirror\"\n[[quantity]]\nkind = \"validation\"\n"
                           "material = \"m\"\ndump = \"good.npy\"\ntheta = [40]\nrows = 7\n");
  const auto plan = run_cli(dir, "plan rows.toml");
  EXPECT_EQ(plan.exit_code, 0) << plan.err;
  for (const char* words : {"| 50000 samples |", "a renderer's dump (good.npy)", "the dump's 50000 rows (read from good.npy)",
                            "no detect_tv asked"})
    EXPECT_NE(plan.out.find(words), std::string::npos) << words << "\n" << plan.out;
  // No validation: nothing tested, nothing could reject.
  write(dir / "none.toml", "[[material]]\nname = \"m\"\nalpha = 0.3\ntype = \"mirror\"\n[[quantity]]\nkind = \"albedo\"\n"
                           "material = \"m\"\nmus = 2\ntarget_relative_error = 0.01\n");
  const auto none = run_cli(dir, "run none.toml --out none");
  EXPECT_EQ(none.exit_code, 0) << none.err;
  EXPECT_EQ(results_of(dir / "none")["results"]["verdict"], "none");
  EXPECT_EQ(results_of(dir / "none")["results"]["tested"], 0);
  EXPECT_NE(none.out.find("Verdict: none"), std::string::npos) << none.out;
  EXPECT_NE(headline(dir / "none", "none").find("No statistical test"), std::string::npos);
  // The passing dump beside a validation the plan cannot run (the ndf sampler against a tile: it does not claim
  // the visible normals): a test that did not run is not a pass, and the run names it.
  write(dir / "half.toml", dump_spec({"good.npy"}) + "[[quantity]]\nkind = \"validation\"\nmaterial = \"m\"\n"
                                                     "sampler = \"ndf\"\nsurface = \"smith\"\ntheta = [40]\nrows = 7\n"
                                                     "detect_tv = 0.2\n");
  const auto half = run_cli(dir, "run half.toml --out half");
  EXPECT_EQ(half.exit_code, 0) << half.out << half.err;
  const nlohmann::json half_doc = results_of(dir / "half");
  const nlohmann::json& h = half_doc["results"];
  EXPECT_EQ(h["verdict"], "none");
  EXPECT_EQ(h["tested"], 1);
  EXPECT_EQ(h["untested"].size(), 1u) << h["untested"].dump();
  EXPECT_NE(half.out.find("Verdict: none (1 test(s) ran, none rejected; no verdict from: quantity[1]"), std::string::npos)
      << half.out;
  EXPECT_NE(headline(dir / "half", "none").find("could not give a verdict"), std::string::npos);
  fs::remove_all(dir);
}

// A spec validates a renderer's BSDF dumps as `validate --from` does: pdf "bsdf" is the material's own BSDF, the
// columns, the transport mode, light from inside a dielectric (theta > 90, the rows of the mirrored view); each
// transport mode's correct dump passes in its mode, and is rejected in the other, as the radiance factor
// applied twice is (the zoo's negative control), level 0.01 per validation. Two tests (the passes; the
// rejections) of three dumps each: each dump's dielectric reference is the cost, and the sanitizer gate runs the
// first.
struct BsdfDumpCase {
  const char* file;
  const char* more;  // spec lines beyond the common ones
  int theta;
  const char* verdict;
};

void expect_bsdf_dump_verdicts(const char* name, const std::vector<BsdfDumpCase>& cases) {
  const fs::path dir = scratch_dir("experiment", name);
  const microsim::GGX<double> ggx(0.3, 0.3);
  const microsim::Vec3<double> wi = microsim::direction_from_degrees(50.0, 0.0);
  microsim::test::write_bsdf_dump(dir / "radiance.txt", "dielectric_vndf", ggx, 1.5, wi, 50000);
  microsim::test::write_bsdf_dump(dir / "importance.txt", "dielectric_vndf_importance", ggx, 1.5, wi, 50000);
  microsim::test::write_bsdf_dump(dir / "twice.txt", "diel_eta2_twice", ggx, 1.5, wi, 50000);
  // From inside (theta 130): the outside view of index 1 / 1.5, its rows mirrored in z.
  microsim::test::write_bsdf_dump(dir / "outside.txt", "dielectric_vndf", ggx, 1 / 1.5, wi, 50000);
  std::ifstream in(dir / "outside.txt");
  std::ofstream inside(dir / "inside.txt");
  for (double x, y, z, pdf, w; in >> x >> y >> z >> pdf >> w;) inside << fmt::format("{:.17g} {:.17g} {:.17g} {:.17g} {:.17g}\n", x, y, -z, pdf, w);
  inside.close();
  std::string spec = "[[material]]\nname = \"glass\"\nalpha = 0.3\ntype = \"dielectric\"\neta = 1.5\n";
  bool any_fail = false;
  for (const BsdfDumpCase& c : cases) {
    spec += fmt::format("[[quantity]]\nkind = \"validation\"\nmaterial = \"glass\"\ndump = \"{}\"\ntheta = [{}]\nrows = 11\n"
                        "pdf = \"bsdf\"\ncolumns = \"x,y,z,pdf,weight\"\nabove_horizon = true\n{}",
                        c.file, c.theta, c.more);
    any_fail = any_fail || std::string(c.verdict) == "fail";
  }
  write(dir / "bsdf.toml", spec);
  const auto run = run_cli(dir, "run bsdf.toml --out out");
  EXPECT_EQ(run.exit_code, any_fail ? 1 : 0) << run.out << run.err;
  const nlohmann::json doc = results_of(dir / "out");
  const nlohmann::json& r = doc["results"];
  ASSERT_EQ(r["measurements"].size(), cases.size());
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const nlohmann::json& v = r["measurements"][i]["values"]["validation"];
    EXPECT_EQ(v["verdict"], cases[i].verdict) << cases[i].file << ": " << v.dump().substr(0, 2000);
    EXPECT_TRUE(v["tests"].contains("bsdf_albedo")) << i;  // the weights were tested
    const std::string notes = v["notes"].dump();
    if (std::string(cases[i].verdict) != "pass") continue;  // the notes of a passing dump say how it was read
    if (std::string(cases[i].more).find("importance") != std::string::npos) {
      EXPECT_NE(notes.find("importance transport"), std::string::npos) << notes;
    }
    if (cases[i].theta > 90) {
      EXPECT_NE(notes.find("light from inside"), std::string::npos) << notes;
    }
  }
  EXPECT_EQ(r["tested"], int(cases.size()));
  fs::remove_all(dir);
}

TEST(ExperimentCli, ASpecValidatesBsdfDumpsInTheirTransportMode) {
  expect_bsdf_dump_verdicts("bsdf_dumps", {{"radiance.txt", "", 50, "pass"},
                                           {"importance.txt", "transport = \"importance\"\n", 50, "pass"},
                                           {"inside.txt", "", 130, "pass"}});
}

TEST(ExperimentCli, ASpecRejectsBsdfDumpsInTheWrongTransportMode) {
  expect_bsdf_dump_verdicts("bsdf_dumps_rejected", {{"importance.txt", "", 50, "fail"},  // radiance, the default
                                                    {"twice.txt", "", 50, "fail"},
                                                    {"twice.txt", "transport = \"importance\"\n", 50, "fail"}});
}

// Ctrl-C after the rejected dump, in a long VNDF: exit 130, the rejection already recorded (verdict fail); the
// same command resumes and exits 1 with the same verdict.
TEST(ExperimentCli, AnInterruptedRunKeepsItsRejectionAndTheResumedRunExits1) {
  const fs::path dir = scratch_dir("experiment", "verdict_resume");
  write_dumps(dir);
  write(dir / "cut.toml", dump_spec({"talk.npy"}, "[[quantity]]\nkind = \"vndf\"\nmaterial = \"m\"\ntheta = [40]\n"
                                                  "rows = 7\ntarget_tv = 0.003\n"));
  std::string first;
  const int status = run_experiment_and_interrupt(dir, "cut.toml", "out", 200, first);
  ASSERT_TRUE(WIFEXITED(status)) << first;
  ASSERT_EQ(WEXITSTATUS(status), 130) << first;  // cut in the VNDF (if it ever finishes in 200 ms: raise its cost)
  const nlohmann::json cut = results_of(dir / "out");
  EXPECT_TRUE(cut["partial"].get<bool>());
  EXPECT_EQ(cut["results"]["verdict"], "fail");
  EXPECT_NE(headline(dir / "out", "fail").find("Verdict: FAIL"), std::string::npos);
  const auto resumed = run_cli(dir, "run cut.toml --out out");
  EXPECT_EQ(resumed.exit_code, 1) << resumed.err;
  const nlohmann::json done = results_of(dir / "out");
  EXPECT_FALSE(done["partial"].get<bool>());
  EXPECT_EQ(verdict_of(done), verdict_of(cut));
  fs::remove_all(dir);
}

}  // namespace

}  // namespace test_experiment_cli
