// Tests of `microsim validate` as a user runs it: exit codes 0 (pass) / 1 (rejected) / 2 (bad usage or
// input), the JSON keys, --from with sample files, and nothing written on bad input.
#include "cli_helpers.h"
#include "sample_dumps.h"
#include "core/random.h"
#include "validate/sample_io.h"
#include "microfacet/bsdf_samplers.h"
#include "microfacet/samplers.h"

#include <fmt/core.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_cli_validate {

using namespace microsim;
namespace fs = std::filesystem;

namespace {

using microsim::test::CliRun;
using microsim::test::slurp;

// One directory for the whole test program, made once (tests write sample files there before running the
// command on them) and removed when the program exits (scratch_dir.h).
fs::path scratch_dir() {
  static const fs::path dir = microsim::test::scratch_dir("cli_validate", "files");
  return dir;
}

CliRun run(const std::string& args) { return microsim::test::run_cli(scratch_dir(), "validate " + args); }

// Directions from a sampler of the zoo (reflected with `reflected`), for --from files.
std::vector<Vec3<double>> samples_of(const char* name, double alpha, double theta, int n, bool reflected = false) {
  const SamplerInfo* s = find_sampler(name);
  const GGX<double> ggx(alpha);
  const Vec3<double> wi = direction_from_degrees(theta, 0.0);
  std::vector<Vec3<double>> out;
  for (int i = 0; i < n; ++i) {
    CounterRng rng(42, std::uint64_t(i));
    const auto r = s->sample_double(ggx, wi, Vec2<double>(rng.uniform(), rng.uniform()));
    if (r) out.push_back(reflected ? reflect(wi, r->direction) : r->direction);
  }
  return out;
}

}  // namespace

TEST(CliValidate, PassRejectAndJson) {
  const fs::path json = scratch_dir() / "pass.json";
  fs::remove(json);
  const CliRun ok = run("--sampler heitz2018 --alpha 0.3 --theta 30 --samples 100000 --seed 3 --json '" + json.string() + "'");
  EXPECT_EQ(ok.exit_code, 0) << ok.out << ok.err;
  EXPECT_NE(ok.out.find("verdict: PASS"), std::string::npos) << ok.out;
  EXPECT_NE(ok.out.find("worst cells"), std::string::npos);
  ASSERT_TRUE(fs::exists(json));
  const nlohmann::json j = nlohmann::json::parse(slurp(json));
  for (const char* key : {"verdict", "p_value", "statistic", "dof", "samples", "tests"}) EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["verdict"], "pass");
  EXPECT_EQ(j["samples"], 100000);
  EXPECT_FALSE(fs::exists(json.string() + ".partial"));

  const CliRun bad = run("--sampler heitz2018-talk --alpha 0.3 --theta 30 --samples 100000");
  EXPECT_EQ(bad.exit_code, 1) << bad.out << bad.err;
  EXPECT_NE(bad.out.find("verdict: FAIL"), std::string::npos);

  const CliRun aniso = run("--sampler dupuy2023 --alpha 0.05,0.5 --theta 60 --phi 30 --samples 50000 --float");
  EXPECT_EQ(aniso.exit_code, 0) << aniso.out << aniso.err;
}

TEST(CliValidate, BadUsageExitsTwoAndWritesNothing) {
  const fs::path json = scratch_dir() / "never.json";
  fs::remove(json);
  const std::string j = " --json '" + json.string() + "'";
  const CliRun unknown = run("--sampler nope --alpha 0.3 --theta 30" + j);
  EXPECT_EQ(unknown.exit_code, 2);
  EXPECT_NE(unknown.err.find("nope"), std::string::npos) << unknown.err;
  EXPECT_NE(unknown.err.find("heitz2018"), std::string::npos) << "the valid names are listed: " << unknown.err;
  for (const std::string& args : {std::string("--sampler ndf --alpha 0 --theta 30"), std::string("--sampler ndf --alpha -1 --theta 30"),
                                  std::string("--sampler ndf --alpha nan --theta 30"), std::string("--sampler ndf --alpha 0.3,inf --theta 30"),
                                  std::string("--sampler ndf --alpha 0.3x --theta 30"), std::string("--sampler ndf --alpha 0.3 --theta 90"),
                                  std::string("--sampler ndf --alpha 0.3 --theta -1"), std::string("--sampler ndf --alpha 0.3 --theta 30 --samples 0"),
                                  std::string("--sampler ndf --alpha 0.3 --theta 30 --samples -5"), std::string("--alpha 0.3 --theta 30"),
                                  std::string("--sampler ndf --theta 30"), std::string("--sampler ndf --alpha 0.3"),
                                  std::string("--sampler ndf --from x.txt --alpha 0.3 --theta 30"),
                                  std::string("--sampler ndf --alpha 0.3 --theta 30 --reflected"),
                                  std::string("--all --alpha 0.3"), std::string("--sampler ndf --alpha 0.3 --theta 30 --rows 30")}) {
    const CliRun r = run(args + j);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.out << r.err;
    EXPECT_FALSE(r.err.empty()) << args;
  }
  EXPECT_FALSE(fs::exists(json));
}

TEST(CliValidate, FromFile) {
  const fs::path dir = scratch_dir();
  const fs::path good = dir / "good.txt", talk = dir / "talk.txt", reflected = dir / "reflected.txt";
  write_text_samples(good, samples_of("heitz2018", 0.3, 40, 100000));
  write_text_samples(talk, samples_of("heitz2018-talk", 0.3, 40, 100000));
  write_text_samples(reflected, samples_of("heitz2018", 0.3, 40, 100000, true));

  const CliRun ok = run("--from '" + good.string() + "' --alpha 0.3 --theta 40");
  EXPECT_EQ(ok.exit_code, 0) << ok.out << ok.err;
  const CliRun rejected = run("--from '" + talk.string() + "' --alpha 0.3 --theta 40");
  EXPECT_EQ(rejected.exit_code, 1) << rejected.out << rejected.err;
  // The same normals seen from another view are rejected too.
  const CliRun wrong_view = run("--from '" + good.string() + "' --alpha 0.3 --theta 60");
  EXPECT_EQ(wrong_view.exit_code, 1) << wrong_view.out;
  const CliRun refl = run("--from '" + reflected.string() + "' --reflected --alpha 0.3 --theta 40");
  EXPECT_EQ(refl.exit_code, 0) << refl.out << refl.err;
  const CliRun refl_as_normals = run("--from '" + reflected.string() + "' --alpha 0.3 --theta 40");
  EXPECT_EQ(refl_as_normals.exit_code, 1) << refl_as_normals.out;

  // Malformed, non-unit and missing files: exit 2 with a message naming the line.
  const fs::path malformed = dir / "malformed.txt", non_unit = dir / "non_unit.txt";
  {
    std::ofstream(malformed) << "0 0 1\n0.6 0.8\n";
    std::ofstream(non_unit) << "# normals\n0 0 1\n0 0 2\n";
  }
  const CliRun m = run("--from '" + malformed.string() + "' --alpha 0.3 --theta 40");
  EXPECT_EQ(m.exit_code, 2);
  EXPECT_NE(m.err.find("2"), std::string::npos) << m.err;
  const CliRun n = run("--from '" + non_unit.string() + "' --alpha 0.3 --theta 40");
  EXPECT_EQ(n.exit_code, 2);
  EXPECT_NE(n.err.find("3"), std::string::npos) << n.err;
  const CliRun missing = run("--from '" + (dir / "missing.txt").string() + "' --alpha 0.3 --theta 40");
  EXPECT_EQ(missing.exit_code, 2);
}

// A renderer's float32 dump: the report says so and names no seed (nothing was drawn); rows with NaN or the
// zero vector are the sampler's failures: exit 1 (rejected), not 2 (bad input), naming the first rows.
TEST(CliValidate, FromDumpReportsItsStorageAndRejectsNanRowsNamingThem) {
  const fs::path dir = scratch_dir();
  const fs::path good = dir / "good.npy", garbage = dir / "garbage.npy", json = dir / "v.json";
  std::vector<Vec3<double>> samples = samples_of("heitz2018", 0.3, 40, 100000);
  write_npy(good, samples, /*as_float32=*/true);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t row : {7, 4000, 4001}) samples[row] = Vec3<double>(nan, nan, nan);
  samples[90000] = Vec3<double>::Zero();
  write_npy(garbage, samples, /*as_float32=*/true);

  const CliRun ok = run("--from '" + good.string() + "' --alpha 0.3 --theta 40 --json '" + json.string() + "'");
  EXPECT_EQ(ok.exit_code, 0) << ok.out << ok.err;
  EXPECT_NE(ok.out.find("samples (float32 .npy)"), std::string::npos) << ok.out;
  EXPECT_EQ(ok.out.find("seed"), std::string::npos) << ok.out;
  const nlohmann::json j = nlohmann::json::parse(slurp(json));
  EXPECT_TRUE(j["seed"].is_null());
  EXPECT_EQ(j["storage"], "float32 .npy");
  EXPECT_EQ(j["invalid_rows"]["count"], 0);

  const CliRun bad = run("--from '" + garbage.string() + "' --alpha 0.3 --theta 40 --json '" + json.string() + "'");
  EXPECT_EQ(bad.exit_code, 1) << bad.out << bad.err;
  for (const char* row : {"4 row(s)", "row 7 (0-based)", "row 4000 (0-based)", "row 4001 (0-based)", "row 90000 (0-based)"})
    EXPECT_NE(bad.out.find(row), std::string::npos) << row << "\n" << bad.out;
  const nlohmann::json jb = nlohmann::json::parse(slurp(json));
  EXPECT_EQ(jb["verdict"], "fail");
  EXPECT_EQ(jb["invalid_rows"]["count"], 4);
  EXPECT_EQ(jb["outside_domain"], 4);
}

namespace {

// An NPY 1.0 file of float64 `rows` (each of the same length) in C order or in Fortran order (column by
// column, as np.save writes a transposed or column-indexed array).
void write_npy_rows(const fs::path& path, const std::vector<std::vector<double>>& rows, bool fortran) {
  std::string header = fmt::format("{{'descr': '<f8', 'fortran_order': {}, 'shape': ({}, {}), }}",
                                   fortran ? "True" : "False", rows.size(), rows.front().size());
  header.append((10 + header.size() + 1 + 63) / 64 * 64 - 10 - header.size() - 1, ' ');
  header.push_back('\n');
  std::string bytes = "\x93NUMPY\x01";
  bytes.push_back('\0');
  bytes.push_back(char(header.size() & 0xFF));
  bytes.push_back(char(header.size() >> 8));
  bytes += header;
  const auto put = [&](double v) { bytes.append(reinterpret_cast<const char*>(&v), sizeof v); };  // little-endian host
  if (!fortran)
    for (const auto& row : rows)
      for (const double v : row) put(v);
  for (std::size_t c = 0; fortran && c < rows.front().size(); ++c)
    for (const auto& row : rows) put(row[c]);
  std::ofstream(path, std::ios::binary) << bytes;
}

}  // namespace

// A dump saved in Fortran order (np.save of m[:, [0, 2, 1]] or of a transposed stack) is the same array: its
// validation is the C-order file's, test for test.
TEST(CliValidate, FortranOrderNpyValidatesAsTheCOrderFile) {
  const fs::path dir = scratch_dir();
  const SamplerInfo* s = find_sampler("heitz2018");
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(40.0, 0.0);
  std::vector<std::vector<double>> rows;
  for (int i = 0; i < 100000; ++i) {
    CounterRng rng(42, std::uint64_t(i));
    if (const auto r = s->sample_double(ggx, wi, Vec2<double>(rng.uniform(), rng.uniform())))
      rows.push_back({r->direction.x(), r->pdf, r->direction.z(), r->direction.y()});
  }
  write_npy_rows(dir / "c_order.npy", rows, false);
  write_npy_rows(dir / "f_order.npy", rows, true);
  nlohmann::json report[2];
  for (const bool fortran : {false, true}) {
    const fs::path json = dir / (fortran ? "f.json" : "c.json");
    const CliRun r = run("--from '" + (dir / (fortran ? "f_order.npy" : "c_order.npy")).string() +
                         "' --alpha 0.3 --theta 40 --columns x,pdf,z,y --json '" + json.string() + "'");
    EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
    report[fortran] = nlohmann::json::parse(slurp(json));
  }
  for (const char* key : {"tests", "p_value", "statistic", "dof", "verdict", "samples", "failures", "storage"})
    EXPECT_EQ(report[1][key], report[0][key]) << key;
  EXPECT_EQ(report[1]["storage"], "float64 .npy");
}

// A 4-column dump given 3 column names: exit 2, the counts named and a --columns that matches suggested
// ('-' ignores the extra column), with which it passes.
TEST(CliValidate, AColumnCountMismatchSuggestsMatchingColumns) {
  const fs::path dir = scratch_dir();
  std::vector<std::vector<double>> rows;
  for (const Vec3<double>& m : samples_of("heitz2018", 0.3, 40, 20000)) rows.push_back({m.x(), m.y(), m.z(), 1.0});
  write_npy_rows(dir / "four.npy", rows, false);
  const std::string from = "--from '" + (dir / "four.npy").string() + "' --alpha 0.3 --theta 40 ";
  const CliRun wrong = run(from + "--columns x,y,z");
  EXPECT_EQ(wrong.exit_code, 2) << wrong.err;
  EXPECT_NE(wrong.err.find("the file has 4 column(s), --columns x,y,z (the default) names 3: give --columns x,y,z,-"),
            std::string::npos) << wrong.err;
  const CliRun skipped = run(from + "--columns x,y,z,-");
  EXPECT_EQ(skipped.exit_code, 0) << skipped.out << skipped.err;
}

// A renderer's reflected dump without the reflections below the horizon: the plain test rejects it and
// says why; --above-horizon passes it, --dropped N tests the count; misuse is exit 2.
TEST(CliValidate, AboveHorizonTestsARendererStyleReflectedDump) {
  const fs::path dir = scratch_dir();
  const fs::path dump = dir / "upper.npy";
  std::vector<Vec3<double>> upper;
  for (const Vec3<double>& wo : samples_of("heitz2018", 0.3, 60, 300000, true))
    if (wo.z() > 0) upper.push_back(wo.normalized());
  const std::size_t dropped = 300000 - upper.size();
  write_npy(dump, upper, /*as_float32=*/true);
  const std::string base = "--from '" + dump.string() + "' --reflected --alpha 0.3 --theta 60";
  const CliRun full = run(base);
  EXPECT_EQ(full.exit_code, 1) << full.out << full.err;
  EXPECT_NE(full.out.find("no sample below the horizon"), std::string::npos) << full.out;
  const CliRun conditioned = run(base + " --above-horizon");
  EXPECT_EQ(conditioned.exit_code, 0) << conditioned.out << conditioned.err;
  const CliRun counted = run(base + " --above-horizon --dropped " + std::to_string(dropped));
  EXPECT_EQ(counted.exit_code, 0) << counted.out << counted.err;
  const CliRun miscounted = run(base + " --above-horizon --dropped " + std::to_string(dropped / 2));
  EXPECT_EQ(miscounted.exit_code, 1) << miscounted.out << miscounted.err;
  EXPECT_NE(miscounted.out.find("dropped fraction"), std::string::npos) << miscounted.out;
  for (const std::string& bad : {"--from '" + dump.string() + "' --alpha 0.3 --theta 60 --above-horizon",
                                 base + " --dropped 10", base + " --above-horizon --against ellipsoid"}) {
    const CliRun r = run(bad);
    EXPECT_EQ(r.exit_code, 2) << bad << "\n" << r.err;
  }
}

// Frames: a dump from a y-up renderer (normal along +y) is rejected with the hint to give --frame y-up, and
// passes with it; a negated dump gets the negated hint; a wrong sampler's dump (in the right frame) gets no
// frame hint; an unknown frame is exit 2.
TEST(CliValidate, FrameMistakesGetAHintAndYUpDumpsPassWithFrameYUp) {
  const fs::path dir = scratch_dir();
  const fs::path yup = dir / "yup.npy", negated = dir / "negated.npy", talk = dir / "talk.npy";
  std::vector<Vec3<double>> y_up_rows, negated_rows;
  for (const Vec3<double>& m : samples_of("heitz2018", 0.3, 40, 100000)) {
    y_up_rows.emplace_back(m.x(), m.z(), -m.y());  // to_z_up(y_up, .) gives m back
    negated_rows.push_back(-m);
  }
  write_npy(yup, y_up_rows, /*as_float32=*/false);
  write_npy(negated, negated_rows, /*as_float32=*/false);
  write_npy(talk, samples_of("heitz2018-talk", 0.3, 40, 100000), false);
  EXPECT_EQ(to_z_up(SampleFrame::y_up, Vec3<double>(0.6, 0.8, 0.0)), Vec3<double>(0.6, 0.0, 0.8));  // +y -> +z

  const CliRun y = run("--from '" + yup.string() + "' --alpha 0.3 --theta 40");
  EXPECT_EQ(y.exit_code, 1) << y.out << y.err;
  EXPECT_NE(y.out.find("give --frame y-up"), std::string::npos) << y.out;
  EXPECT_NE(y.out.find("they pass"), std::string::npos) << y.out;
  const CliRun fixed = run("--from '" + yup.string() + "' --alpha 0.3 --theta 40 --frame y-up");
  EXPECT_EQ(fixed.exit_code, 0) << fixed.out << fixed.err;
  const CliRun n = run("--from '" + negated.string() + "' --alpha 0.3 --theta 40");
  EXPECT_EQ(n.exit_code, 1) << n.out;
  EXPECT_NE(n.out.find("read negated (the directions flipped) they pass"), std::string::npos) << n.out;
  const CliRun t = run("--from '" + talk.string() + "' --alpha 0.3 --theta 40");
  EXPECT_EQ(t.exit_code, 1) << t.out;
  EXPECT_EQ(t.out.find("frame"), std::string::npos) << t.out;
  // A y-up renderer's reflections with those below the horizon dropped: the hint names both fixes.
  const fs::path reflections = dir / "yup_reflections.npy";
  std::vector<Vec3<double>> kept;
  for (const Vec3<double>& wo : samples_of("heitz2018", 0.3, 60, 100000, /*reflected=*/true))
    if (wo.z() > 0) kept.emplace_back(wo.x(), wo.z(), -wo.y());
  write_npy(reflections, kept, false);
  const std::string dropped = std::to_string(100000 - kept.size());
  const CliRun d = run("--from '" + reflections.string() + "' --alpha 0.3 --theta 60 --reflected");
  EXPECT_EQ(d.exit_code, 1) << d.out << d.err;
  EXPECT_NE(d.out.find("give --frame y-up (Python: frame='y-up'); read so, "), std::string::npos) << d.out;
  EXPECT_NE(d.out.find("--above-horizon"), std::string::npos) << d.out;
  const CliRun both = run("--from '" + reflections.string() +
                          "' --alpha 0.3 --theta 60 --reflected --frame y-up --above-horizon --dropped " + dropped);
  EXPECT_EQ(both.exit_code, 0) << both.out << both.err;
  for (const std::string& bad : {"--from '" + yup.string() + "' --alpha 0.3 --theta 40 --frame x-up",
                                 std::string("--sampler heitz2018 --alpha 0.3 --theta 40 --frame y-up")}) {
    const CliRun r = run(bad);
    EXPECT_EQ(r.exit_code, 2) << bad << "\n" << r.err;
    EXPECT_NE(r.err.find("--frame"), std::string::npos) << r.err;
  }
}

// A theta given in radians (1.2 for 68.75 deg) is read in degrees: the rejection says what was probably meant;
// the same dump at its view passes, and a rejection at an ordinary view gets no such hint.
TEST(CliValidate, AThetaThatLooksLikeRadiansGetsAHint) {
  const fs::path dir = scratch_dir();
  const fs::path dump = dir / "vndf.npy";
  write_npy(dump, samples_of("heitz2018", 0.5, 1.2 * 180 / kPi<double>, 100000), false);
  const CliRun r = run("--from '" + dump.string() + "' --alpha 0.5 --theta 1.2");
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_NE(r.out.find("if 1.2 was meant in radians, give --theta 68.75"), std::string::npos) << r.out;
  const CliRun ok = run("--from '" + dump.string() + "' --alpha 0.5 --theta 68.7549354");
  EXPECT_EQ(ok.exit_code, 0) << ok.out << ok.err;
  EXPECT_EQ(ok.out.find("radians"), std::string::npos) << ok.out;
  const CliRun other = run("--from '" + dump.string() + "' --alpha 0.5 --theta 40");
  EXPECT_EQ(other.exit_code, 1) << other.out;
  EXPECT_EQ(other.out.find("radians"), std::string::npos) << other.out;
}

// A renderer-style dump with the pdf its sampler returned: --columns x,y,z,pdf turns on the returned-pdf
// check and the E[weight] test; a pdf 5% too high is rejected by them, though the directions are right.
TEST(CliValidate, DumpsWithAPdfColumnGetTheReturnedPdfCheck) {
  const fs::path dir = scratch_dir();
  const SamplerInfo* s = find_sampler("heitz2018");
  const GGX<double> ggx(0.3);
  const Vec3<double> wi = direction_from_degrees(40.0, 0.0);
  std::ofstream good(dir / "good.txt"), high(dir / "high.txt");
  for (int i = 0; i < 200000; ++i) {
    CounterRng rng(42, std::uint64_t(i));
    const auto r = s->sample_double(ggx, wi, Vec2<double>(rng.uniform(), rng.uniform()));
    if (!r) continue;
    const Vec3<double>& m = r->direction;
    good << fmt::format("{:.17g} {:.17g} {:.17g} {:.17g}\n", m.x(), m.y(), m.z(), r->pdf);
    high << fmt::format("{:.17g} {:.17g} {:.17g} {:.17g}\n", m.x(), m.y(), m.z(), 1.05 * r->pdf);
  }
  good.close();
  high.close();
  const std::string args = " --alpha 0.3 --theta 40 --columns x,y,z,pdf";
  const CliRun ok = run("--from '" + (dir / "good.txt").string() + "'" + args);
  EXPECT_EQ(ok.exit_code, 0) << ok.out << ok.err;
  EXPECT_EQ(ok.out.find("n/a"), std::string::npos) << "every check applies with a pdf column\n" << ok.out;
  const CliRun bad = run("--from '" + (dir / "high.txt").string() + "'" + args);
  EXPECT_EQ(bad.exit_code, 1) << bad.out;
  EXPECT_NE(bad.out.find("returned pdf"), std::string::npos) << bad.out;
  const CliRun plain = run("--from '" + (dir / "good.txt").string() + "' --alpha 0.3 --theta 40");
  EXPECT_EQ(plain.exit_code, 2) << "four columns without --columns are bad input\n" << plain.err;
  EXPECT_NE(plain.err.find("found 4 numbers, --columns x,y,z (the default) names 3: give --columns x,y,z,-"),
            std::string::npos) << plain.err;
  const CliRun spec = run("--from '" + (dir / "good.txt").string() + "' --alpha 0.3 --theta 40 --columns x,y,pdf");
  EXPECT_EQ(spec.exit_code, 2) << spec.err;
  EXPECT_NE(spec.err.find("--columns"), std::string::npos) << spec.err;
}

// --bsdf: what it needs is checked before any work (exit 2, the option named).
TEST(CliValidate, BsdfMisuseIsBadUsage) {
  const fs::path dir = scratch_dir();
  const fs::path f = dir / "w.txt";
  std::ofstream(f) << "0 0 1 0.5\n";
  const std::string from = "--from '" + f.string() + "' --reflected --alpha 0.3 --theta 30 ";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {from + "--columns x,y,z,weight --bsdf gold", "--bsdf: unknown BSDF 'gold'"},
      {from + "--columns x,y,z,weight --bsdf conductor", "--bsdf conductor needs --eta and --k"},
      {from + "--columns x,y,z,weight --bsdf conductor --eta 0.2,0.4 --k 3.9", "--eta has 2 value(s) and --k 1"},
      {from + "--columns x,y,z,weight --bsdf conductor --eta 0 --k 3.9", "--eta"},
      {from + "--columns x,y,z,weight --bsdf conductor --eta 0.2 --k -1", "--k"},
      {from + "--columns x,y,z,weight --bsdf 'conductor:0.2,3.9;0.4,2.4'", "2 channel(s)"},
      {from + "--columns x,y,z,weight --bsdf mirror --eta 0.2", "--eta and --k apply to --bsdf conductor or dielectric"},
      {from + "--columns x,y,z,weight --eta 0.2 --k 3", "--eta and --k apply with --bsdf conductor or dielectric only"},
      {"--sampler heitz2018 --alpha 0.3 --theta 30 --bsdf mirror", "--bsdf applies to --from FILE"},
      {from + "--columns x,y,z,weight --bsdf dielectric", "--bsdf dielectric needs --eta"},
      {from + "--columns x,y,z,weight --bsdf dielectric --eta 1.5 --k 1", "a dielectric takes --eta only"},
      {from + "--columns x,y,z,weight --bsdf dielectric --eta 1.5,1.6", "--eta"},
      {"--from '" + f.string() + "' --pdf bsdf --alpha 0.3 --theta 30", "--pdf bsdf is the sampling density of a BSDF"},
      {from + "--columns x,y,z,weight --bsdf dielectric:1.5", "test them against its sampling density (--pdf bsdf"},
      {from + "--columns x,y,z,weight --bsdf mirror --transport camera", "--transport 'camera': unknown transport mode"},
      {from + "--columns x,y,z,weight --bsdf mirror --masking smith", "--masking 'smith': unknown masking-shadowing form"},
      {from + "--columns x,y,z,weight --transport importance", "--transport is the convention of a BSDF's weights"},
      {"--from '" + f.string() + "' --reflected --alpha 0.3 --theta 120 --columns x,y,z,weight --bsdf mirror",
       "light from inside a dielectric"},
      {"--from '" + f.string() + "' --alpha 0.3 --theta 120", "light from inside a dielectric"},
      {from + "--sampling ndf", "--sampling is how a BSDF's sample() draws its normals"},
      {"--from '" + f.string() + "' --alpha 0.3 --theta 30 --columns x,y,z,weight --bsdf mirror --sampling visible",
       "--sampling 'visible': unknown normal sampling"},
      // Weights need directions: named as --bsdf's, not as an option that was not given.
      {"--from '" + f.string() + "' --pdf ndf --alpha 0.3 --theta 30 --columns x,y,z,weight --bsdf mirror",
       "microsim: error: --bsdf: the weight test needs outgoing directions"},
  };
  for (const auto& [args, message] : cases) {
    const CliRun r = run(args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << args << "\n" << r.err;
    if (args.find("--above-horizon") == std::string::npos) {
      EXPECT_EQ(r.err.find("--above-horizon:"), std::string::npos) << args << "\n" << r.err;
    }
  }
}

// A rough dielectric's sample() dumped as a renderer would (wo, pdf, weight per row, reflections and
// refractions): --pdf bsdf --bsdf dielectric tests the directions against its sampling density over the
// whole sphere and the weights against the BSDF in the dump's transport mode (radiance unless --transport
// says importance); the radiance factor applied twice (bsdf_samplers.h: diel_eta2_twice) is rejected with the
// same directions, and each mode's correct dump is rejected in the other mode.
TEST(CliValidate, DielectricDumpsAreTestedWithPdfBsdf) {
  const fs::path dir = scratch_dir();
  const GGX<double> ggx(0.3, 0.3);
  const Vec3<double> wi = direction_from_degrees(50.0, 0.0);
  const auto dump = [&](const char* name, const fs::path& path) {
    return microsim::test::write_bsdf_dump(path, name, ggx, std::complex<double>(1.5), wi, 50000);
  };
  const long long lost = dump("dielectric_vndf", dir / "glass.txt");
  ASSERT_GT(lost, 400) << "the view must lose samples for the conditioning to matter";
  dump("diel_eta2_twice", dir / "glass_eta2_twice.txt");
  dump("dielectric_vndf_importance", dir / "glass_importance.txt");
  // 11 rows: a coarse binning (the dielectric's reference cubature is the cost of each run).
  const std::string args = " --alpha 0.3 --theta 50 --rows 11 --pdf bsdf --columns x,y,z,pdf,weight --bsdf dielectric "
                           "--eta 1.5 --above-horizon";
  const std::string glass = "--from '" + (dir / "glass.txt").string() + "'";
  const CliRun ok = run(glass + args);
  EXPECT_EQ(ok.exit_code, 0) << ok.out << ok.err;
  const CliRun counted = run(glass + args + " --dropped " + std::to_string(lost));
  EXPECT_EQ(counted.exit_code, 0) << counted.out << counted.err;
  EXPECT_EQ(run(glass + args + " --dropped " + std::to_string(lost * 13 / 10)).exit_code, 1) << "30% too many lost";
  // Without --above-horizon the lost samples' share of the density is missing from the file: rejected, with a
  // hint naming --above-horizon (--bsdf implies --pdf bsdf).
  const CliRun no_kept = run(glass + " --alpha 0.3 --theta 50 --rows 11 --columns x,y,z,pdf,weight --bsdf dielectric:1.5");
  EXPECT_EQ(no_kept.exit_code, 1) << no_kept.out << no_kept.err;
  EXPECT_NE(no_kept.out.find("hint: the claimed density loses"), std::string::npos) << no_kept.out;
  EXPECT_NE(no_kept.out.find("--above-horizon"), std::string::npos) << no_kept.out;
  // Transport modes: the radiance dump is rejected as importance, the importance dump passes as importance
  // and is rejected as radiance (the default, said in the report).
  EXPECT_NE(ok.out.find("radiance transport (camera paths)"), std::string::npos) << ok.out;
  EXPECT_EQ(run(glass + args + " --transport importance").exit_code, 1);
  const std::string importance = "--from '" + (dir / "glass_importance.txt").string() + "'";
  const CliRun as_importance = run(importance + args + " --transport importance");
  EXPECT_EQ(as_importance.exit_code, 0) << as_importance.out << as_importance.err;
  EXPECT_EQ(run(importance + args).exit_code, 1);
  const CliRun bad = run("--from '" + (dir / "glass_eta2_twice.txt").string() + "'" + args);
  EXPECT_EQ(bad.exit_code, 1) << bad.out << bad.err;
  EXPECT_NE(bad.out.find("BSDF"), std::string::npos) << "rejected by a weight test\n" << bad.out;
  // Directions only (no weight column): the same density, no weight test.
  const CliRun directions =
      run(glass + " --alpha 0.3 --theta 50 --rows 11 --pdf bsdf --columns x,y,z,-,- --bsdf dielectric:1.5 --above-horizon");
  EXPECT_EQ(directions.exit_code, 0) << directions.out << directions.err;
  // The same dump claimed as a conductor's reflections: its refractions fall where that pdf is zero.
  EXPECT_EQ(run(glass + " --alpha 0.3 --theta 50 --rows 11 --reflected --above-horizon --columns x,y,z,-,-").exit_code, 1);
}

TEST(CliValidate, PlotWritesAFigureAndRejectsBadPaths) {
  const fs::path dir = scratch_dir();
  const fs::path svg = dir / "fig.svg";
  fs::remove(svg);
  const CliRun ok = run("--sampler heitz2018-talk --alpha 0.3 --theta 60 --samples 50000 --plot '" + svg.string() + "'");
  EXPECT_EQ(ok.exit_code, 1) << ok.err;  // rejected, and the figure shows why
  const std::string text = slurp(svg);
  EXPECT_NE(text.find("verdict FAIL"), std::string::npos);
  EXPECT_NE(text.find("lobe bins: analytic pdf"), std::string::npos);
  EXPECT_NE(text.find("</svg>"), std::string::npos);
  // Not .svg, a missing directory, or with --all: exit 2, nothing written.
  const fs::path png = dir / "fig.png";
  EXPECT_EQ(run("--sampler heitz2018 --alpha 0.3 --theta 60 --samples 1000 --plot '" + png.string() + "'").exit_code, 2);
  EXPECT_FALSE(fs::exists(png));
  EXPECT_EQ(run("--sampler heitz2018 --alpha 0.3 --theta 60 --samples 1000 --plot /nonexistent-dir/f.svg").exit_code, 2);
  EXPECT_EQ(run("--all --plot '" + (dir / "all.svg").string() + "'").exit_code, 2);
  EXPECT_FALSE(fs::exists(dir / "all.svg"));
}

}  // namespace test_cli_validate
