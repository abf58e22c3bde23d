// `mpirun -n 2` and `mpirun -n 3` (an uneven split) of `microsim run` on a small spec (a VNDF and a per-order
// scattering measurement, split over the ranks; an analytic albedo table, run by rank 0 alone) against the
// one-process run: results.json's measured values (timings and the host's rates aside) and every histogram
// (vndf-K.exr, scattering-K.exr) and table (albedo-K.csv) equal, bit for bit; stdout printed once, by rank 0.
// The comparison can fail: a run with another seed differs. Per-order lobes on an assembly's tile: the ranks
// trace rank 0's tile, the one-process results again. Under mpirun a bad spec is one message and exit 2, and
// a rejected validation exit 1 (rank 0 decides the code and the other ranks return it).
// Built only with MPI and mpirun (CMakeLists.txt); the library-level tests of the split are
// tests/experiment/test_experiment_split.cpp (ranks as threads, with the negative controls of a wrong combination).
#include "../run_directory_contents.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <string>

namespace {

namespace fs = std::filesystem;
using microsim::test::run_cli;
using microsim::test::scratch_dir;
using microsim::test::slurp;


// mpirun's options for a test: as root too (containers), more ranks than cores, shared memory only.
std::string mpirun(int ranks) {
  return std::string(MICROSIM_MPIEXEC) + " --allow-run-as-root --oversubscribe --mca btl self,vader -n " +
         std::to_string(ranks) + " ";
}

// Runs `microsim run ../split.toml --out out --threads 1 EXTRA` in DIR/NAME (every run directory is `out`:
// the same command, recorded in results.json), under `launcher` (empty: alone); the exit code, stdout, stderr.
microsim::test::CliRun run_in(const fs::path& dir, const std::string& name, const std::string& launcher,
                              const std::string& extra = "") {
  fs::create_directory(dir / name);
  const std::string cmd = "cd '" + (dir / name).string() + "' && " + launcher + "'" + microsim::test::microsim_binary() +
                          "' run ../split.toml --out out --threads 1" + extra + " > run.stdout 2> run.stderr";
  const int status = std::system(cmd.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(dir / name / "run.stdout"), slurp(dir / name / "run.stderr")};
}

TEST(RunMpi, TwoAndThreeRanksWriteTheOneProcessResultsBitForBit) {
  const fs::path dir = scratch_dir("run_mpi", "bit_for_bit");
  std::ofstream(dir / "split.toml") << microsim::test::split_spec("split", 7);
  const auto alone = run_in(dir, "alone", "");
  ASSERT_EQ(alone.exit_code, 0) << alone.err;
  const std::string expected = microsim::test::run_directory_contents(dir / "alone" / "out");
  ASSERT_NE(expected.find("scattering-1.exr"), std::string::npos);
  ASSERT_NE(expected.find("vndf-0.exr"), std::string::npos);
  ASSERT_NE(expected.find("albedo-2.csv"), std::string::npos);
  EXPECT_TRUE(microsim::test::has_uneven_round(dir / "alone" / "out", 3)) << "3 ranks: an uneven split";
  for (int ranks : {2, 3}) {
    const std::string name = "ranks" + std::to_string(ranks);
    const auto r = run_in(dir, name, mpirun(ranks));
    ASSERT_EQ(r.exit_code, 0) << ranks << " ranks: " << r.err;
    EXPECT_EQ(microsim::test::run_directory_contents(dir / name / "out"), expected) << ranks << " ranks";
    EXPECT_EQ(r.out.find("plan of split"), r.out.rfind("plan of split")) << "stdout printed once: " << r.out;
    EXPECT_NE(r.out.find("plan of split"), std::string::npos) << r.out;
  }
  const auto other_seed = run_in(dir, "seed8", "", " --seed 8");
  ASSERT_EQ(other_seed.exit_code, 0) << other_seed.err;
  EXPECT_NE(microsim::test::run_directory_contents(dir / "seed8" / "out"), expected)
      << "negative control: the comparison sees another seed";
}

// Per-order lobes on smith's tile and a validation of heitz2018 against another smith tile's traced visible
// normals (built by rank 0's plan in out/surfaces; the other rank reads them there, and writes nothing; the
// validation's rays are split too): `mpirun -n 2` writes the one-process run directory, bit for bit.
TEST(RunMpi, TheRanksTraceRankZerosTileAndWriteTheOneProcessResults) {
  const fs::path dir = scratch_dir("run_mpi", "tile");
  std::ofstream(dir / "split.toml") << R"(name = "tile"
seed = 9
[[material]]
name = "m"
alphas = [0.5]
type = "mirror"
[[quantity]]
kind = "scattering"
material = "m"
surface = "smith"
orders = "all"
theta = [40]
target_tv = 0.2
[[quantity]]
kind = "validation"
material = "m"
surface = "smith"
sampler = "heitz2018"
theta = [40]
rows = 7
detect_tv = 0.2
)";
  const auto alone = run_in(dir, "alone", "");
  ASSERT_EQ(alone.exit_code, 0) << alone.err;
  const std::string expected = microsim::test::run_directory_contents(dir / "alone" / "out");
  ASSERT_NE(expected.find("scattering-0.exr"), std::string::npos);
  ASSERT_NE(expected.find("\"surface\""), std::string::npos) << "a heightfield decision";
  ASSERT_NE(expected.find("rays traced on assembly smith"), std::string::npos) << "a validation against a tile";
  EXPECT_TRUE(microsim::test::has_uneven_round(dir / "alone" / "out", 2)) << "an uneven split";
  const auto two = run_in(dir, "ranks2", mpirun(2));
  ASSERT_EQ(two.exit_code, 0) << two.err;
  EXPECT_EQ(microsim::test::run_directory_contents(dir / "ranks2" / "out"), expected);
  std::size_t tiles = 0;
  for (const auto& entry : fs::directory_iterator(dir / "ranks2" / "out" / "surfaces")) tiles += entry.is_regular_file();
  EXPECT_EQ(tiles, 2u) << "two tiles, rank 0's";
}

TEST(RunMpi, ABadSpecUnderMpirunIsOneMessageAndExit2NothingWritten) {
  const fs::path dir = scratch_dir("run_mpi", "bad_spec");
  std::ofstream(dir / "bad.toml") << "seed = 1\n[[material]]\nname = \"m\"\nalpha = 0.3\ntype = \"velvet\"\n";
  const std::string cmd = "cd '" + dir.string() + "' && " + mpirun(2) + "'" + microsim::test::microsim_binary() +
                          "' run bad.toml --out out > bad.stdout 2> bad.stderr";
  const int status = std::system(cmd.c_str());
  const std::string err = slurp(dir / "bad.stderr");
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 2) << err;
  EXPECT_NE(err.find("material[0].type"), std::string::npos) << err;
  EXPECT_EQ(err.find("material[0].type"), err.rfind("material[0].type")) << "one message, rank 0's: " << err;
  EXPECT_FALSE(fs::exists(dir / "out"));
}

// The talk listing validated with its samples split over the ranks: rank 0 decides the verdict, every rank
// returns its exit code, 1, and the directory is the one-process run's.
TEST(RunMpi, ARejectedValidationExits1UnderMpirunAsAlone) {
  const fs::path dir = scratch_dir("run_mpi", "rejected");
  std::ofstream(dir / "split.toml") << "name = \"talk\"\nseed = 2\n[[material]]\nname = \"m\"\nalpha = 0.3\n"
                                       "type = \"mirror\"\n[[quantity]]\nkind = \"validation\"\nmaterial = \"m\"\n"
                                       "sampler = \"heitz2018-talk\"\ntheta = [40]\nrows = 7\ndetect_tv = 0.01\n";
  const auto alone = run_in(dir, "alone", "");
  ASSERT_EQ(alone.exit_code, 1) << alone.err;
  const auto two = run_in(dir, "ranks2", mpirun(2));
  EXPECT_EQ(two.exit_code, 1) << two.err;
  EXPECT_NE(two.out.find("Verdict: FAIL (rejected: "), std::string::npos) << two.out;
  EXPECT_EQ(microsim::test::run_directory_contents(dir / "ranks2" / "out"),
            microsim::test::run_directory_contents(dir / "alone" / "out"));
  EXPECT_EQ(nlohmann::json::parse(slurp(dir / "ranks2" / "out" / "results.json"))["results"]["verdict"], "fail");
  fs::remove_all(dir);
}

}  // namespace
