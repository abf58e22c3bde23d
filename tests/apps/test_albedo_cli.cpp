// `microsim albedo` end to end: a small table of each model is written (EXR, CSV, JSON) and agrees with the
// library; a walk table's shards merged (`microsim merge`) are the single run bit for bit, and not with a part of
// the lanes kernel (--walk-kernel lanes: another table of the same walk, within its errors); the bad-input
// table: each case exits 2 naming the bad value and writes nothing.
#include "cli_helpers.h"

#include "microgeom/exr_io.h"

#include <fmt/core.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_albedo_cli {

namespace {

namespace fs = std::filesystem;
using microsim::test::BadInputCase;
using microsim::test::run_cli;
using microsim::test::scratch_dir;
using microsim::test::slurp;

TEST(AlbedoCli, AnalyticTableIsWrittenAsExrCsvAndJson) {
  const fs::path dir = scratch_dir("albedo_cli", "analytic");
  const auto r = run_cli(dir, "albedo --model analytic --alphas 0.5,1 --mus 4 --out t.exr --csv t.csv --json t.json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("E1_avg"), std::string::npos) << r.out;
  const microgeom::ExrImage image = microgeom::read_exr(dir / "t.exr");
  EXPECT_EQ(image.width, 4);
  EXPECT_EQ(image.height, 2);
  EXPECT_EQ(image.attributes.at("kind"), "albedo table");
  EXPECT_EQ(image.attributes.at("partial"), "false");
  const nlohmann::json j = nlohmann::json::parse(slurp(dir / "t.json"));
  EXPECT_EQ(j["alphas"], (std::vector<double>{0.5, 1.0}));
  EXPECT_NEAR(j["quantities"]["E1"]["average"][0].get<double>(), 0.700, 1e-3);
  EXPECT_FLOAT_EQ(image.find("E1.value")->data[4 + 3], float(j["quantities"]["E1"]["value"][1][3].get<double>()));
  const std::string csv = slurp(dir / "t.csv");
  EXPECT_EQ(csv.find("alpha,mu,mu_weight,E1,E1_error,E1_avg,E1_avg_error\n"), 0u) << csv;
  fs::remove_all(dir);
}

TEST(AlbedoCli, ConductorTableHoldsItsFresnelAverage) {
  const fs::path dir = scratch_dir("albedo_cli", "conductor");
  const auto r = run_cli(dir, "albedo --model analytic --material conductor:0.2,3.9 --alphas 0.5 --mus 4 --out c.exr "
                              "--csv c.csv --json c.json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("F_avg = "), std::string::npos) << r.out;
  const nlohmann::json j = nlohmann::json::parse(slurp(dir / "c.json"));
  EXPECT_GT(j["F_avg"].get<double>(), 0.9);
  EXPECT_EQ(microgeom::read_exr(dir / "c.exr").attributes.count("F_avg"), 1u);
  EXPECT_NE(slurp(dir / "c.csv").find("# F_avg "), std::string::npos);
  fs::remove_all(dir);
}

TEST(AlbedoCli, SampledModelsWriteTheirQuantities) {
  const fs::path dir = scratch_dir("albedo_cli", "sampled");
  const auto walk = run_cli(dir, "albedo --model smith-walk --material dielectric:1.5 --inside --alphas 0.7 --mus 2 "
                                 "--rays 5000 --out w.exr --json w.json");
  ASSERT_EQ(walk.exit_code, 0) << walk.err;
  const nlohmann::json w = nlohmann::json::parse(slurp(dir / "w.json"));
  EXPECT_EQ(w["side"], "inside");
  EXPECT_EQ(w["quantity_names"], (std::vector<std::string>{"E", "E_R", "E_T", "E1", "E1_R", "E1_T", "unfinished"}));
  const auto surface = run_cli(dir, "albedo --model surface --res 256 --alphas 0.5 --mus 2 --rays 2000 --out s.exr");
  ASSERT_EQ(surface.exit_code, 0) << surface.err;
  EXPECT_NE(microgeom::read_exr(dir / "s.exr").find("lost.value"), nullptr);
  fs::remove_all(dir);
}

// The JSON of a table without its timings (what differs between runs of the same seed).
nlohmann::json without_timings(nlohmann::json j) {
  j.erase("seconds");
  j.erase("row_seconds");
  return j;
}

// A walk table in two shards (given to merge out of order) merged: the single run's CSV and values, bit for bit.
// Negative control: a part of another seed is refused.
TEST(AlbedoCli, TwoShardsMergeIntoTheSingleRunsTableBitForBit) {
  const fs::path dir = scratch_dir("albedo_cli", "shards");
  const std::string walk = "albedo --model smith-walk --material dielectric:1.5 --alphas 0.3,0.8 --mus 3 --rays 600 "
                           "--seed 7 --threads 2 ";
  ASSERT_EQ(run_cli(dir, walk + "--out w.exr --csv w.csv --json w.json").exit_code, 0);
  for (const char* k : {"1", "2"}) {
    const auto r = run_cli(dir, walk + fmt::format("--shard {}/2 --out p{}.json", k, k));
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  const auto m = run_cli(dir, "merge p2.json p1.json --out m.exr --csv m.csv --json m.json");
  ASSERT_EQ(m.exit_code, 0) << m.err;
  EXPECT_EQ(slurp(dir / "m.csv"), slurp(dir / "w.csv"));
  EXPECT_EQ(without_timings(nlohmann::json::parse(slurp(dir / "m.json"))),
            without_timings(nlohmann::json::parse(slurp(dir / "w.json"))));
  ASSERT_EQ(run_cli(dir, "albedo --model smith-walk --material dielectric:1.5 --alphas 0.3,0.8 --mus 3 --rays 600 "
                         "--seed 8 --shard 2/2 --out q2.json").exit_code, 0);
  const auto refused = run_cli(dir, "merge p1.json q2.json --out n.exr");
  EXPECT_EQ(refused.exit_code, 2);
  EXPECT_NE(refused.err.find("seed"), std::string::npos) << refused.err;
  EXPECT_FALSE(fs::exists(dir / "n.exr"));
  // The lanes kernel's part of the same seed is a part of another run: refused, naming the kernel.
  ASSERT_EQ(run_cli(dir, walk + "--walk-kernel lanes --shard 2/2 --out l2.json").exit_code, 0);
  const auto mixed = run_cli(dir, "merge p1.json l2.json --out n.exr");
  EXPECT_EQ(mixed.exit_code, 2);
  EXPECT_NE(mixed.err.find("walk_kernel"), std::string::npos) << mixed.err;
  EXPECT_FALSE(fs::exists(dir / "n.exr"));
  fs::remove_all(dir);
}

// --walk-kernel lanes walks the table with the lanes kernel: it says so, and with the same seed its reflected
// albedos differ from the scalar walk's and agree with them within 4 standard errors of the difference per row
// (fixed seed; a false alarm has probability about 1e-4 over the two rows).
TEST(AlbedoCli, TheLanesKernelWalksTheSameTable) {
  const fs::path dir = scratch_dir("albedo_cli", "lanes");
  const std::string walk = "albedo --model smith-walk --material dielectric:1.5 --alphas 0.3,0.8 --mus 3 --rays 4000 ";
  ASSERT_EQ(run_cli(dir, walk + "--out s.exr --json s.json").exit_code, 0);
  const auto r = run_cli(dir, walk + "--walk-kernel lanes --out l.exr --csv l.csv --json l.json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json s = nlohmann::json::parse(slurp(dir / "s.json")), l = nlohmann::json::parse(slurp(dir / "l.json"));
  EXPECT_EQ(s["walk_kernel"], "scalar");
  EXPECT_EQ(l["walk_kernel"], "lanes");
  EXPECT_EQ(microgeom::read_exr(dir / "l.exr").attributes.at("walk_kernel"), "lanes");
  EXPECT_NE(slurp(dir / "l.csv").find("# walk_kernel lanes"), std::string::npos);
  // Its shards merge into it, bit for bit (the part records the kernel, the merge walks none).
  for (const char* k : {"1", "2"})
    ASSERT_EQ(run_cli(dir, walk + fmt::format("--walk-kernel lanes --shard {}/2 --out p{}.json", k, k)).exit_code, 0);
  const auto m = run_cli(dir, "merge p1.json p2.json --out m.exr --csv m.csv");
  ASSERT_EQ(m.exit_code, 0) << m.err;
  EXPECT_EQ(slurp(dir / "m.csv"), slurp(dir / "l.csv"));
  const nlohmann::json &es = s["quantities"]["E_R"], &el = l["quantities"]["E_R"];
  for (int row = 0; row < 2; ++row) {
    const double difference = el["average"][row].get<double>() - es["average"][row].get<double>();
    const double error = std::hypot(el["average_error"][row].get<double>(), es["average_error"][row].get<double>());
    EXPECT_NE(difference, 0.0) << row;
    EXPECT_LT(std::abs(difference), 4 * error) << row << ": " << difference << " +- " << error;
  }
  fs::remove_all(dir);
}

// A layout table: the Cycles layout (at a coarse quadrature tolerance, to keep the test short) is written as
// EXR, CSV, JSON and Cycles' own 6-decimal text; the anisotropic mirror's table, analytic and from the walk;
// and the walk's split on Cycles' glass nodes (the forms of the files, not their values: tests/scatter).
TEST(AlbedoCli, LayoutTableIsWrittenInTheRenderersFormsAndTheAnisotropicTableToo) {
  const fs::path dir = scratch_dir("albedo_cli", "layout");
  const auto r = run_cli(dir, "albedo --layout cycles --tolerance 1e-2 --out c.exr --csv c.csv --json c.json "
                              "--encoded c.txt --centres centres.csv");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("interpolation error at cell centres"), std::string::npos) << r.out;
  const microgeom::ExrImage image = microgeom::read_exr(dir / "c.exr");
  EXPECT_EQ(image.width, 32);
  EXPECT_EQ(image.height, 32);
  EXPECT_EQ(image.attributes.at("kind"), "albedo layout table");
  EXPECT_EQ(image.attributes.at("columns"), "roughness");
  const std::string csv = slurp(dir / "c.csv");
  EXPECT_EQ(csv.find("x,y,roughness,alpha,mu,E,E_error,E_encoded,E_avg,E_avg_error\n"), 0u) << csv.substr(0, 200);
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 1 + 5 + 1024);
  const std::string text = slurp(dir / "c.txt");
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 32);
  // The anisotropic mirror's table: one line per (alpha_x, alpha_y, mu, phi), E_avg printed.
  const auto aniso = run_cli(dir, "albedo --model analytic --alphas 0.5 --alphas-y 0.25,1 --mus 2 --phis 2 --csv a.csv");
  ASSERT_EQ(aniso.exit_code, 0) << aniso.err;
  EXPECT_NE(aniso.out.find("E_avg (rows alpha_x, columns alpha_y)"), std::string::npos) << aniso.out;
  const std::string a = slurp(dir / "a.csv");
  EXPECT_NE(a.find("alpha_x,alpha_y,mu,phi,E,E_error,E_avg,E_avg_error\n"), std::string::npos);
  EXPECT_EQ(std::count(a.begin(), a.end(), '\n'), 2 + 1 + 2 * 2 * 2);
  // Its walk table: per node E, E1, E_ms and unfinished with standard errors, and their averages.
  const auto walk = run_cli(dir, "albedo --model smith-walk --alphas 0.5 --alphas-y 0.25 --mus 2 --phis 1 --rays 2000 "
                                 "--walk-kernel lanes --csv w.csv --json w.json");
  ASSERT_EQ(walk.exit_code, 0) << walk.err;
  EXPECT_NE(walk.out.find("E1_avg"), std::string::npos) << walk.out;
  const std::string w = slurp(dir / "w.csv");
  EXPECT_NE(w.find("alpha_x,alpha_y,mu,phi,E,E_se,E1,E1_se,E_ms,E_ms_se,unfinished,unfinished_se,E_avg,"), std::string::npos);
  EXPECT_EQ(std::count(w.begin(), w.end(), '\n'), 2 + 1 + 2);
  EXPECT_NE(slurp(dir / "w.json").find("\"kind\": \"anisotropic walk table\""), std::string::npos);
  // The walk's split on Cycles' glass nodes (16 paths a node: the form, not the values).
  const auto glass = run_cli(dir, "albedo --layout cycles-glass --model smith-walk --rays 16 --walk-kernel lanes "
                                  "--csv g.csv --json g.json");
  ASSERT_EQ(glass.exit_code, 0) << glass.err;
  EXPECT_NE(glass.out.find("T share"), std::string::npos) << glass.out;
  const std::string g = slurp(dir / "g.csv");
  EXPECT_EQ(std::count(g.begin(), g.end(), '\n'), 3 + 1 + 4096);
  EXPECT_NE(slurp(dir / "g.json").find("\"kind\": \"glass walk table\""), std::string::npos);
  fs::remove_all(dir);
}

// A grade from the command line, on the uniform layout (normalised uint16: the reference the grade needs is a
// tenth of its rounding, 7.6e-7, where Cycles' 6 decimals need 5.3e-8): its table's CSV graded passes (exit 0),
// and the same CSV with one node moved by 0.05 fails (exit 1) naming that node. Its reference quadrature is
// the cost (left out of the sanitizer gate; the grade's library path runs there in AlbedoGradeInput).
TEST(AlbedoCliGrade, TheUniformTablePassesAndAPlantedErrorFails) {
  const fs::path dir = scratch_dir("albedo_cli", "grade");
  const auto u = run_cli(dir, "albedo --layout uniform --tolerance 1e-3 --out u.exr --csv u.csv");
  ASSERT_EQ(u.exit_code, 0) << u.err;
  const auto pass = run_cli(dir, "albedo --grade u.csv --layout uniform --tolerance 1e-2 --json g.json");
  EXPECT_EQ(pass.exit_code, 0) << pass.out << pass.err;
  EXPECT_NE(pass.out.find("PASS: 0 of 1024 nodes beyond the tolerance 0.01 (beyond the encoding's rounding)"), std::string::npos) << pass.out;
  EXPECT_NE(pass.out.find("quadrature tolerance 7.62951e-07"), std::string::npos) << pass.out;
  EXPECT_NEAR(nlohmann::json::parse(slurp(dir / "g.json"))["reference_tolerance"].get<double>(), 0.05 / 65535, 1e-12);
  // The CSV with E (its sixth column) raised by 0.05 on the data rows `raise` selects (x and y its first two).
  const std::string csv = slurp(dir / "u.csv");
  const auto raised = [&](const std::function<bool(const std::string& row)>& raise) {
    std::string out;
    std::istringstream lines(csv);
    for (std::string line; std::getline(lines, line);) {
      std::vector<std::string> f;
      std::istringstream fields(line);
      for (std::string x; std::getline(fields, x, ',');) f.push_back(x);
      if (f.size() > 5 && std::isdigit(static_cast<unsigned char>(f[0][0])) && raise(line)) {
        f[5] = std::to_string(std::stod(f[5]) + 0.05);
        line.clear();
        for (std::size_t i = 0; i < f.size(); ++i) line += (i ? "," : "") + f[i];
      }
      out += line + "\n";
    }
    return out;
  };
  // The planted error: node x = 20 (mu (20 + 0.5) / 32), y = 7 (alpha (7 + 0.5) / 32) raised by 0.05.
  std::ofstream(dir / "planted.csv") << raised([](const std::string& row) { return row.rfind("20,7,", 0) == 0; });
  const auto fail = run_cli(dir, "albedo --grade planted.csv --layout uniform --tolerance 1e-2");
  EXPECT_EQ(fail.exit_code, 1) << fail.out << fail.err;
  EXPECT_NE(fail.out.find("FAIL node (roughness 7, mu 20)"), std::string::npos) << fail.out;
  EXPECT_NE(fail.out.find("FAIL: 1 of 1024 nodes"), std::string::npos) << fail.out;
  // Every node off: the first 40 failing nodes listed, the rest counted (all in the JSON).
  std::ofstream(dir / "off.csv") << raised([](const std::string&) { return true; });
  const auto many = run_cli(dir, "albedo --grade off.csv --layout uniform --tolerance 1e-2");
  EXPECT_EQ(many.exit_code, 1) << many.out << many.err;
  EXPECT_NE(many.out.find("... and 984 more failing nodes"), std::string::npos) << many.out;
  fs::remove_all(dir);
}

// --ndf beckmann with --layout and --grade: the table says it holds a Beckmann mirror's E (the summary, the
// EXR attribute, the JSON), and graded against the Beckmann reference it passes, the grade saying which
// reference it used. The negative control (GGX's table graded against Beckmann fails, from the command line
// and from Python) is tests/python/test_tables.py's: a GGX grade here would cost the GGX reference's 2000 nodes.
TEST(AlbedoCli, ABeckmannLayoutTableIsGradedAgainstTheBeckmannReference) {
  const fs::path dir = scratch_dir("albedo_cli", "beckmann");
  const auto r = run_cli(dir, "albedo --layout uniform --ndf beckmann --tolerance 1e-3 --out b.exr --json b.json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("(beckmann mirror)"), std::string::npos) << r.out;
  EXPECT_EQ(microgeom::read_exr(dir / "b.exr").attributes.at("ndf"), "beckmann");
  EXPECT_EQ(nlohmann::json::parse(slurp(dir / "b.json")).at("ndf"), "beckmann");
  const auto pass = run_cli(dir, "albedo --grade b.exr --layout uniform --ndf beckmann --tolerance 1e-3 --json g.json");
  EXPECT_EQ(pass.exit_code, 0) << pass.out << pass.err;
  EXPECT_NE(pass.out.find("of a beckmann mirror"), std::string::npos) << pass.out;
  EXPECT_EQ(nlohmann::json::parse(slurp(dir / "g.json")).at("ndf"), "beckmann");
  fs::remove_all(dir);
}

const std::string kAlbedo = "albedo --model analytic --out o.exr ";

void write_text(const fs::path& path, const std::string& text) { std::ofstream(path) << text; }

std::vector<BadInputCase> albedo_cli_cases() {
  return {
      {"model_unknown", "albedo --model walk --out o.exr", 2, "--model 'walk'"},
      {"model_missing", "albedo --out o.exr", 2, "--model"},
      {"material_unknown", kAlbedo + "--material gold", 2, "'gold': unknown material"},
      {"material_conductor_channels", kAlbedo + "--material 'conductor:0.2,3.9;0.5,2.4'", 2,
       "one conductor index per table"},
      {"conductor_inside", kAlbedo + "--material conductor:0.2,3.9 --inside", 2, "--inside"},
      {"material_lambertian", kAlbedo + "--material lambertian", 2, "mirror, conductor:ETA,K or dielectric:ETA"},
      {"eta_zero", kAlbedo + "--material dielectric:0", 2, "'0'"},
      {"eta_negative", kAlbedo + "--material dielectric:-1.5", 2, "'-1.5'"},
      {"eta_infinite", kAlbedo + "--material dielectric:inf", 2, "'inf'"},
      {"eta_nan", kAlbedo + "--material dielectric:nan", 2, "'nan'"},
      {"inside_mirror", kAlbedo + "--inside", 2, "--inside"},
      {"alphas_too_small", kAlbedo + "--alphas 0.001", 2, "'0.001'"},
      {"alphas_too_large", kAlbedo + "--alphas 0.5,2.5", 2, "'2.5'"},
      {"alphas_zero", kAlbedo + "--alphas 0", 2, "--alphas"},
      {"alphas_empty_item", kAlbedo + "--alphas 0.1,,0.5", 2, "--alphas"},
      {"alphas_not_increasing", kAlbedo + "--alphas 0.5,0.3", 2, "must increase"},
      {"alphas_repeated", kAlbedo + "--alphas 0.5,0.5", 2, "must increase"},
      {"alphas_nan", kAlbedo + "--alphas nan", 2, "'nan'"},
      {"mus_one", kAlbedo + "--mus 1", 2, "--mus"},
      {"mus_too_many", kAlbedo + "--mus 257", 2, "'257'"},
      {"mus_real", kAlbedo + "--mus 2.5", 2, "'2.5'"},
      {"ndf_unknown", kAlbedo + "--ndf phong", 2, "'phong'"},
      {"rays_analytic", kAlbedo + "--rays 1000", 2, "--rays applies"},
      {"seed_analytic", kAlbedo + "--seed 3", 2, "--seed applies"},
      {"res_walk", "albedo --model smith-walk --res 256 --out o.exr", 2, "--res applies"},
      {"walk_kernel_analytic", kAlbedo + "--walk-kernel lanes", 2, "--walk-kernel applies to --model smith-walk"},
      {"walk_kernel_unknown", "albedo --model smith-walk --walk-kernel simd --out o.exr", 2, "--walk-kernel 'simd'"},
      {"walk_kernel_lanes_beckmann", "albedo --model smith-walk --ndf beckmann --walk-kernel lanes --out o.exr", 2,
       "--ndf beckmann: not supported by --walk-kernel lanes"},
      {"tolerance_walk", "albedo --model smith-walk --tolerance 1e-6 --out o.exr", 2, "--tolerance applies"},
      {"tolerance_zero", kAlbedo + "--tolerance 0", 2, "--tolerance"},
      {"rays_zero", "albedo --model smith-walk --rays 0 --out o.exr", 2, "--rays"},
      {"order_cap_zero", "albedo --model smith-walk --max-order 0 --out o.exr", 2, "--max-order"},
      {"res_unsupported", "albedo --model surface --res 64 --out o.exr", 2, "--res 64"},
      {"res_not_power", "albedo --model surface --res 300 --out o.exr", 2, "'300'"},
      {"seed_negative", "albedo --model smith-walk --seed -1 --out o.exr", 2, "'-1'"},
      {"threads_negative", kAlbedo + "--threads -1", 2, "'-1'"},
      {"out_not_exr", "albedo --model analytic --out o.png", 2, "--out 'o.png'"},
      {"out_missing", "albedo --model analytic", 2, "--out"},
      {"csv_not_csv", kAlbedo + "--csv o.txt", 2, "--csv 'o.txt'"},
      {"json_is_out", kAlbedo + "--json o.exr", 2, "o.exr"},
      {"out_no_directory", "albedo --model analytic --out nodir/o.exr", 2, "nodir"},
      {"layout_unknown", "albedo --layout unreal --out o.exr", 2, "--layout 'unreal': unknown layout"},
      {"layout_no_out", "albedo --layout cycles", 2, "--layout needs --out"},
      {"layout_walk", "albedo --layout cycles --model smith-walk --out o.exr", 2, "--model 'smith-walk'"},
      {"layout_alphas", "albedo --layout cycles --alphas 0.5 --out o.exr", 2, "--alphas does not apply to --layout"},
      {"layout_dielectric", "albedo --layout cycles --material dielectric:1.5 --out o.exr", 2, "--material mirror"},
      {"layout_out_not_exr", "albedo --layout cycles --out o.png", 2, "--out 'o.png'"},
      {"layout_encoded_is_out", "albedo --layout cycles --out o.exr --encoded o.exr", 2, "o.exr"},
      {"anisotropic_no_csv", "albedo --model analytic --alphas-y 0.5 --out o.exr", 2, "--out does not apply"},
      {"anisotropic_surface", "albedo --model surface --alphas-y 0.5 --csv a.csv", 2,
       "--model 'surface': --alphas-y needs --model analytic or smith-walk"},
      {"anisotropic_walk_tolerance", "albedo --model smith-walk --alphas-y 0.5 --tolerance 1e-6 --csv a.csv", 2,
       "--tolerance does not apply"},
      {"anisotropic_analytic_rays", "albedo --model analytic --alphas-y 0.5 --rays 10 --csv a.csv", 2,
       "--rays does not apply"},
      {"anisotropic_walk_kernel", "albedo --model smith-walk --alphas-y 0.5 --walk-kernel simd --csv a.csv", 2,
       "--walk-kernel 'simd'"},
      {"anisotropic_alpha_y", "albedo --model analytic --alphas-y 3 --csv a.csv", 2, "'3'"},
      {"phis_alone", kAlbedo + "--phis 4", 2, "--phis applies to --alphas-y only"},
      {"glass_walk_tolerance", "albedo --layout cycles-glass --model smith-walk --tolerance 1e-6 --csv g.csv", 2,
       "--tolerance does not apply"},
      {"glass_walk_encoded", "albedo --layout cycles-glass --model smith-walk --encoded g.txt", 2,
       "--encoded does not apply"},
      {"glass_walk_no_output", "albedo --layout cycles-glass-inv --model smith-walk", 2, "needs --csv or --json"},
      {"glass_layout_surface", "albedo --layout cycles-glass --model surface --csv g.csv", 2, "--model 'surface'"},
      {"glass_layout_out", "albedo --layout cycles-glass --out o.exr --csv g.csv", 2, "--out does not apply"},
      {"glass_layout_no_output", "albedo --layout cycles-glass-inv", 2, "needs --csv, --encoded or --json"},
      {"glass_layout_material", "albedo --layout cycles-glass --material dielectric:1.5 --csv g.csv", 2,
       "--material does not apply"},
      {"encoded_without_layout", kAlbedo + "--encoded e.bin", 2, "--encoded applies to --layout"},
      {"grade_no_layout", "albedo --grade t.csv", 2, "--grade needs --layout"},
      {"layout_ndf_unknown", "albedo --layout cycles --ndf phong --out o.exr", 2, "--ndf 'phong'"},
      {"glass_grade_ndf", "albedo --grade t.csv --layout cycles-glass --ndf beckmann", 2, "--ndf beckmann does not apply"},
      {"grade_missing", "albedo --grade none.csv --layout cycles", 2, "cannot be read"},
      {"grade_out", "albedo --grade t.csv --layout cycles --out o.exr", 2, "--out does not apply to --grade"},
      {"grade_samples_zero", "albedo --grade t.csv --layout cycles --table-samples 0", 2, "--table-samples"},
      {"grade_json_is_input", "albedo --grade t.csv --layout cycles --json t.csv", 2, "t.csv",
       [](const fs::path& d) { write_text(d / "t.csv", "x,y,E\n0,0,1\n"); }},
      {"grade_wrong_size", "albedo --grade t.csv --layout cycles", 2, "3 cells in the CSV; the cycles layout has 1024",
       [](const fs::path& d) { write_text(d / "t.csv", "x,y,E\n0,0,1\n1,0,1\n2,0,1\n"); }},
      {"grade_twice", "albedo --grade t.csv --layout cycles", 2, "cell (0, 0) given twice",
       [](const fs::path& d) { write_text(d / "t.csv", "x,y,E\n0,0,1\n0,0,1\n"); }},
      {"grade_no_column", "albedo --grade t.csv --layout cycles", 2, "no column 'E'",
       [](const fs::path& d) { write_text(d / "t.csv", "x,y,value\n0,0,1\n"); }},
      {"grade_nan", "albedo --grade t.csv --layout cycles", 2, "'nan'",
       [](const fs::path& d) { write_text(d / "t.csv", "x,y,E\n0,0,nan\n"); }},
      {"grade_outside_grid", "albedo --grade t.csv --layout cycles", 2, "'32'",
       [](const fs::path& d) { write_text(d / "t.csv", "x,y,E\n32,0,1\n"); }},
      {"grade_not_a_table", "albedo --grade t.json --layout cycles", 2, "an .exr, a .csv or a .txt",
       [](const fs::path& d) { write_text(d / "t.json", "1\n"); }},
      {"grade_text_too_short", "albedo --grade t.txt --layout cycles", 2, "1 values in the text; the cycles layout has 1024",
       [](const fs::path& d) { write_text(d / "t.txt", "1.000000f\n"); }},
      {"grade_not_exr", "albedo --grade t.exr --layout cycles", 2, "--grade 't.exr'",
       [](const fs::path& d) { write_text(d / "t.exr", "not an exr"); }},
      {"glass_grade_wrong_size", "albedo --grade g.csv --layout cycles-glass", 2,
       "2 nodes in the CSV; the cycles-glass layout has 4096",
       [](const fs::path& d) { write_text(d / "g.csv", "# a comment\nx,y,z,E\n0,0,0,0.5\n1,0,0,0.5\n"); }},
      {"glass_grade_text_count", "albedo --grade g.txt --layout cycles-glass-inv", 2,
       "3 values in the text; the cycles-glass-inv layout has 4096",
       [](const fs::path& d) { write_text(d / "g.txt", "0.5, 0.5,\n\n0.5\n"); }},
      {"glass_grade_no_z", "albedo --grade g.csv --layout cycles-glass", 2, "no column 'z'",
       [](const fs::path& d) { write_text(d / "g.csv", "x,y,E\n0,0,0.5\n"); }},
      {"glass_grade_exr", "albedo --grade g.exr --layout cycles-glass", 2, "a .csv or a .txt",
       [](const fs::path& d) { write_text(d / "g.exr", "x"); }},
      {"glass_grade_out", "albedo --grade g.csv --layout cycles-glass --csv o.csv", 2, "--csv does not apply to --grade"},
      {"shard_analytic", "albedo --model analytic --shard 1/2 --out p.json", 2, "--shard applies to --model smith-walk"},
      {"shard_surface", "albedo --model surface --shard 1/2 --out p.json", 2, "--shard applies to --model smith-walk"},
      {"shard_out_exr", "albedo --model smith-walk --shard 1/2 --out p.exr", 2, "--out 'p.exr': with --shard"},
      {"shard_csv", "albedo --model smith-walk --shard 1/2 --out p.json --csv p.csv", 2, "--csv does not apply to --shard"},
      {"shard_beyond", "albedo --model smith-walk --alphas 0.5 --mus 2 --shard 3/3 --out p.json", 2, "--shard"},
  };
}

class BadInputsAlbedo : public ::testing::TestWithParam<BadInputCase> {};

TEST_P(BadInputsAlbedo, ExitsTwoNamingTheValueAndWritesNothing) {
  microsim::test::expect_bad_input(GetParam(), "bad_albedo");
}

INSTANTIATE_TEST_SUITE_P(Cases, BadInputsAlbedo, ::testing::ValuesIn(albedo_cli_cases()),
                         [](const auto& info) { return info.param.name; });

}  // namespace

}  // namespace test_albedo_cli
