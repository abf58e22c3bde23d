// End to end: `microsim check-bsdf --plugin` loads the worked plugin of examples/plugins/rough_ggx.c (a rough GGX
// conductor, anisotropic, and dielectric in the radiance convention, written from the math) and passes it whole
// (level 0.01, fixed seed; the anisotropic one at views off the axes too); the same plugin with a planted eval()
// bug (the radiance factor forgotten in eval only; built against the header of ABI version 1, so that an old
// plugin is seen to load) is rejected by the eval, consistency and reciprocity tests while its sampling tests
// still pass; the anisotropic plugin with its roughnesses swapped is rejected; the Smith multiple-scattering
// plugin (examples/plugins/smith_walk.c, ABI 2, stochastic eval, no pdf) passes against the walk and the
// Kulla-Conty plugin against itself, and their planted bugs are rejected; bad plugins are exit 2.
#include "cli_helpers.h"
#include "sample_dumps.h"

#include "core/random.h"
#include "microfacet/bsdf.h"
#include "microfacet/bsdf_samplers.h"
#include "validate/sample_io.h"

#include <fmt/core.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <set>
#include <string>

namespace microsim::test {
namespace {

std::string check(const char* plugin, const std::string& claims) {
  return std::string("check-bsdf --plugin ") + plugin + " " + claims + " --samples 100000 --json c.json";
}

const std::string kPluginGlass = "--param kind=dielectric --param alpha=0.3 --param eta=1.5 --bsdf dielectric:1.5 --alpha 0.3";
const std::string kPluginGold = "--param kind=conductor --param alpha_x=0.2 --param alpha_y=0.4 --param eta=0.2 --param k=3.9 "
                                "--bsdf conductor:0.2,3.9 --alpha 0.2,0.4";

TEST(CheckBsdfCli, TheWorkedPluginsPassWhole) {
  const fs::path dir = scratch_dir("check_bsdf", "good");
  for (const std::string& claims : {kPluginGlass, kPluginGold}) {
    const CliRun r = run_cli(dir, check(MICROSIM_PLUGIN_GOOD, claims));
    EXPECT_EQ(r.exit_code, 0) << claims << "\n" << r.out << r.err;
    const nlohmann::json j = nlohmann::json::parse(slurp(dir / "c.json"));
    EXPECT_EQ(j["verdict"], "pass");
    EXPECT_GE(j["tests"].size(), 12u);  // sampling and consistency per view, eval and reciprocity
    EXPECT_EQ(j["tests"].back()["test"], "reciprocity");
    std::set<std::string> views;
    for (const nlohmann::json& t : j["tests"]) views.insert(t["view"].get<std::string>());
    EXPECT_EQ(views.count("60 deg phi 30"), claims == kPluginGold ? 1u : 0u) << claims;
  }
  fs::remove_all(dir);
}

TEST(CheckBsdfCli, APlantedEvalBugIsRejectedByTheEvalAndConsistencyTests) {
  const fs::path dir = scratch_dir("check_bsdf", "bug");
  const CliRun r = run_cli(dir, check(MICROSIM_PLUGIN_EVAL_BUG, kPluginGlass));
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  const nlohmann::json j = nlohmann::json::parse(slurp(dir / "c.json"));
  for (const nlohmann::json& t : j["tests"]) {
    const std::string test = t["test"];
    if (test == "sampling") {
      EXPECT_TRUE(t["passed"].get<bool>()) << t.dump();
    }
    if (test == "eval" || test == "reciprocity") {
      EXPECT_FALSE(t["passed"].get<bool>()) << t.dump();
    }
    if (test == "consistency" && t["view"] == "60 deg") {
      EXPECT_FALSE(t["passed"].get<bool>()) << t.dump();
    }
  }
  // The conductor has no refraction: the bug does not touch it (isotropic: the turned views cost time and add
  // nothing here).
  const std::string isotropic_gold = "--param kind=conductor --param alpha=0.3 --param eta=0.2 --param k=3.9 --bsdf "
                                     "conductor:0.2,3.9 --alpha 0.3";
  EXPECT_EQ(run_cli(dir, check(MICROSIM_PLUGIN_EVAL_BUG, isotropic_gold)).exit_code, 0);
  // The anisotropic conductor with alpha_x and alpha_y swapped against its claim: rejected by its samples at a
  // view on the axis and one turned off it (a small budget: two views).
  const CliRun swapped = run_cli(dir, std::string("check-bsdf --plugin ") + MICROSIM_PLUGIN_GOOD +
                                          " --param kind=conductor --param alpha_x=0.4 --param alpha_y=0.2 --param eta=0.2"
                                          " --param k=3.9 --bsdf conductor:0.2,3.9 --alpha 0.2,0.4 --samples 20000"
                                          " --view 60 --view 60,30 --json s.json");
  EXPECT_EQ(swapped.exit_code, 1) << swapped.out << swapped.err;
  const nlohmann::json s = nlohmann::json::parse(slurp(dir / "s.json"));
  for (const nlohmann::json& t : s["tests"]) {
    if (t["test"] == "sampling" || t["test"] == "eval") {
      EXPECT_FALSE(t["passed"].get<bool>()) << t.dump();
    }
  }
  fs::remove_all(dir);
}

// The Smith multiple-scattering GGX mirror of examples/plugins/smith_walk.c (ABI 2: a stochastic eval() by the
// next-event estimator of Heitz et al. 2016, no pdf()) against the Smith walk of microsim: passes its samples,
// its eval() (averaged over repeated calls) and its reciprocity (two views, a small budget); its planted eval
// bug is rejected.
TEST(CheckBsdfCli, TheSmithWalkPluginPassesAgainstTheWalk) {
  const fs::path dir = scratch_dir("check_bsdf", "walk");
  const CliRun r = run_cli(dir, std::string("check-bsdf --plugin ") + MICROSIM_PLUGIN_SMITH_WALK +
                                    " --param alpha=0.8 --param eta=0 --bsdf mirror --alpha 0.8 --reference smith-walk"
                                    " --samples 20000 --view 0 --view 60 --json w.json");
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  std::set<std::string> tests;
  const nlohmann::json j = nlohmann::json::parse(slurp(dir / "w.json"));
  for (const nlohmann::json& t : j["tests"]) tests.insert(t["test"].get<std::string>());
  EXPECT_TRUE(j["eval"].is_null());  // the exact eval check: not run against the walk
  EXPECT_EQ(tests, (std::set<std::string>{"sampling", "integral", "furnace", "eval", "reciprocity"}));
  // The negative control: its eval() summing orders 1 and 2 only (a planted bug of the plugin's) is rejected by
  // the eval test against the walk and the furnace, while its samples pass.
  const CliRun bug = run_cli(dir, std::string("check-bsdf --plugin ") + MICROSIM_PLUGIN_SMITH_WALK +
                                      " --param alpha=0.8 --param eta=0 --param eval_orders=2 --bsdf mirror --alpha 0.8"
                                      " --reference smith-walk --samples 20000 --view 0 --view 60 --json b.json");
  EXPECT_EQ(bug.exit_code, 1) << bug.out << bug.err;
  const nlohmann::json b = nlohmann::json::parse(slurp(dir / "b.json"));
  for (const nlohmann::json& t : b["tests"]) {
    if (t["test"] == "sampling") {
      EXPECT_TRUE(t["passed"].get<bool>()) << t.dump();
    }
    if (t["test"] == "eval" || t["test"] == "furnace") {
      EXPECT_FALSE(t["passed"].get<bool>()) << t.dump();
    }
  }
  fs::remove_all(dir);
}

// The Kulla-Conty compensated GGX mirror of examples/plugins/kulla_conty.c claims no exact reference: with
// --reference none it passes the tests against itself; its planted non-reciprocal lobe ((1 - E(mu_i))^2) keeps its
// energy and its sampling consistent and is rejected by reciprocity alone (one view, a small budget).
TEST(CheckBsdfCli, TheKullaContyPluginPassesAgainstItselfAndItsNonReciprocalLobeIsRejected) {
  const fs::path dir = scratch_dir("check_bsdf", "kulla_conty");
  const std::string args = std::string("check-bsdf --plugin ") + MICROSIM_PLUGIN_KULLA_CONTY +
                           " --param alpha=0.5 --bsdf mirror --alpha 0.5 --reference none --samples 20000 --view 60 --json k.json";
  CliRun r = run_cli(dir, args);
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  r = run_cli(dir, args + " --param bug=non-reciprocal");
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  const nlohmann::json j = nlohmann::json::parse(slurp(dir / "k.json"));
  for (const nlohmann::json& t : j["tests"]) EXPECT_EQ(t["passed"].get<bool>(), t["test"] != "reciprocity") << t.dump();
  fs::remove_all(dir);
}

// --html: one self-contained page (no external resource: the only URL is the SVG namespace) with the table and a
// residual map per view and cell test (one view, 60 deg: the page is what is tested here).
TEST(CheckBsdfCli, TheHtmlReportIsSelfContainedWithTheResidualMaps) {
  const fs::path dir = scratch_dir("check_bsdf", "html");
  CliRun r = run_cli(dir, check(MICROSIM_PLUGIN_GOOD, kPluginGlass) + " --view 60 --html r.html");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  std::string page = slurp(dir / "r.html");
  EXPECT_EQ(page.rfind("<!DOCTYPE html>", 0), 0u);
  std::size_t svgs = 0, urls = 0;
  for (std::size_t at = page.find("<svg"); at != std::string::npos; at = page.find("<svg", at + 1)) ++svgs;
  for (std::size_t at = page.find("http"); at != std::string::npos; at = page.find("http", at + 1))
    urls += page.compare(at, 26, "http://www.w3.org/2000/svg") != 0;
  EXPECT_EQ(svgs, 2u);  // density and integral at the one view
  EXPECT_EQ(urls, 0u);
  EXPECT_EQ(page.find(" src="), std::string::npos);
  EXPECT_EQ(page.find("REJECTED"), std::string::npos);
  fs::remove_all(dir);
}

// A rejected plugin's page says so (the sanitizer gate runs the page test above only), and --reference none (a
// compensated BSDF's claim: only the tests against itself) runs no sampling or eval test against a reference.
TEST(CheckBsdfCli, ARejectedPluginsPageSaysSoAndReferenceNoneRunsNoReferenceTest) {
  const fs::path dir = scratch_dir("check_bsdf", "html_rejected");
  CliRun r = run_cli(dir, check(MICROSIM_PLUGIN_EVAL_BUG, kPluginGlass) + " --view 60 --html bug.html");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(slurp(dir / "bug.html").find("REJECTED"), std::string::npos);
  r = run_cli(dir, check(MICROSIM_PLUGIN_GOOD, kPluginGlass) + " --view 60 --reference none");
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  const nlohmann::json none = nlohmann::json::parse(slurp(dir / "c.json"));  // kept alive over the loop
  for (const nlohmann::json& t : none["tests"]) {
    EXPECT_NE(t["test"], "sampling");
    EXPECT_NE(t["test"], "eval");
  }
  fs::remove_all(dir);
}

// check-bsdf-files: the zoo's GGX conductor (alpha 0.3, eta 0.2 + 3.9i) sampled at 30 deg, its dump (x y z pdf
// weight) and its eval file at the same rows: passes (fixed seed, level 0.01), with the cell tests too when its
// eval file at the cell points of `bsdf-queries --cells` is given; its weights scaled by 1.01 are rejected by the
// consistency test; an albedo of 1 claimed for it (it absorbs) by the furnace; rows that do not match, or a cells
// file that is not the cell points, are exit 2. Returns the samples lost below the horizon (not in the dump).
std::uint64_t write_conductor_files(const fs::path& dir, double weight_scale) {
  return write_conductor_bsdf_files(dir / "d.txt", dir / "e.txt", weight_scale);
}

// The conductor's eval file at the cell points `bsdf-queries --cells` wrote to q.npy, as c.txt.
void fill_in_cells(const fs::path& dir) {
  const GGX<double> ggx(0.3, 0.3);
  DirectionSampleReader wi_r(dir / "q.npy", SampleColumns::parse("x,y,z,-,-,-")),
      wo_r(dir / "q.npy", SampleColumns::parse("-,-,-,x,y,z"));
  std::vector<Vec3<double>> wi(kSampleFileBlock), wo(kSampleFileBlock);
  std::ofstream c(dir / "c.txt");
  for (std::size_t n; (n = wi_r.read(wi)) > 0;) {
    wo_r.read(std::span(wo.data(), n));
    for (std::size_t i = 0; i < n; ++i)
      c << fmt::format("{:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g} {:.17g}\n", wi[i].x(), wi[i].y(), wi[i].z(),
                       wo[i].x(), wo[i].y(), wo[i].z(), conductor_brdf(ggx, kZooConductorIor, wi[i], wo[i]) * std::abs(wo[i].z()),
                       conductor_vndf_pdf(ggx, kZooConductorIor, wi[i], wo[i]));
  }
}

TEST(CheckBsdfCli, FilesOfOneBsdfAgainstEachOther) {
  const fs::path dir = scratch_dir("check_bsdf", "files");
  const std::uint64_t lost = write_conductor_files(dir, 1.0);
  CliRun r = run_cli(dir, "check-bsdf-files d.txt e.txt --theta 30 --json f.json");
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_EQ(nlohmann::json::parse(slurp(dir / "f.json"))["verdict"], "pass");
  // Without --albedo the furnace only reports the mean weight: it tested nothing, and says so, not "pass".
  for (const auto& t : nlohmann::json::parse(slurp(dir / "f.json"))["tests"])
    EXPECT_EQ(t["tested"], t["test"] != "furnace") << t.dump();
  EXPECT_NE(r.out.find("reported"), std::string::npos) << r.out;
  r = run_cli(dir, "bsdf-queries --cells --theta 30 --points-per-cell 16 --out q.npy");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  fill_in_cells(dir);
  r = run_cli(dir, fmt::format("check-bsdf-files d.txt e.txt --theta 30 --lost {} --cells c.txt --json f.json", lost));
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  std::set<std::string> tests;
  const nlohmann::json report = nlohmann::json::parse(slurp(dir / "f.json"));
  for (const auto& t : report["tests"]) tests.insert(t["test"].get<std::string>());
  EXPECT_EQ(tests, (std::set<std::string>{"consistency", "density", "integral", "furnace"}));
  r = run_cli(dir, "check-bsdf-files d.txt e.txt --theta 30 --cells e.txt");
  EXPECT_EQ(r.exit_code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("bsdf-queries --cells"), std::string::npos) << r.err;
  r = run_cli(dir, "check-bsdf-files d.txt e.txt --theta 30 --albedo 1");
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_NE(r.out.find("furnace"), std::string::npos);
  r = run_cli(dir, "check-bsdf-files d.txt e.txt --theta 60");
  EXPECT_EQ(r.exit_code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("is not the view (0.866025, 0, 0.5)"), std::string::npos) << r.err;  // the view named
  write_conductor_files(dir, 1.01);
  r = run_cli(dir, "check-bsdf-files d.txt e.txt --theta 30");
  EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_NE(r.out.find("rows disagree"), std::string::npos) << r.out;
  fs::remove_all(dir);
}

// A rough GGX conductor drawing its normals from D(m) cos (Walter 2007; Mitsuba 3's sample_visible = false) passes
// when its plugin says so (MICROSIM_BSDF_NDF_SAMPLING; the default grid without 89.9 deg), and the report names
// the convention; the same plugin not saying it is rejected by the sampling test at the tilted views.
TEST(CheckBsdfCli, APluginSamplingNormalsFromTheNdfIsTestedAgainstThatDensity) {
  const fs::path dir = scratch_dir("check_bsdf", "ndf");
  const std::string gold = "--param kind=conductor --param alpha=0.3 --param eta=0.2 --param k=3.9 --bsdf conductor:0.2,3.9 "
                           "--alpha 0.3";
  const CliRun declared = run_cli(dir, check(MICROSIM_PLUGIN_NDF, gold));
  EXPECT_EQ(declared.exit_code, 0) << declared.out << declared.err;
  EXPECT_NE(declared.out.find("convention: radiance transport (camera paths), height-correlated G2, normals sampled from "
                              "D(m) cos"), std::string::npos) << declared.out;
  const nlohmann::json j = nlohmann::json::parse(slurp(dir / "c.json"));
  EXPECT_NE(j["convention"].get<std::string>().find("D(m) cos"), std::string::npos);
  std::set<std::string> views;
  for (const nlohmann::json& t : j["tests"]) views.insert(t["view"].get<std::string>());
  EXPECT_EQ(views.count("80 deg"), 1u);
  EXPECT_EQ(views.count("89.9 deg"), 0u);
  const CliRun undeclared = run_cli(dir, check(MICROSIM_PLUGIN_NDF_UNDECLARED, gold));
  EXPECT_EQ(undeclared.exit_code, 1) << undeclared.out << undeclared.err;
  int rejected = 0;
  const nlohmann::json u = nlohmann::json::parse(slurp(dir / "c.json"));
  for (const nlohmann::json& t : u["tests"])
    if (t["test"] == "sampling" && !t["passed"].get<bool>()) ++rejected;
  EXPECT_GE(rejected, 3) << "the sampling test at the tilted views";
  fs::remove_all(dir);
}

TEST(CheckBsdfCli, BadPluginsAreExit2) {
  const fs::path dir = scratch_dir("check_bsdf", "usage");
  const std::pair<std::string, std::string> cases[] = {
      {"check-bsdf --plugin no-such.so --bsdf mirror --alpha 0.3", "--plugin 'no-such.so'"},
      {std::string("check-bsdf --plugin ") + MICROSIM_BUILT_BINARY + " --bsdf mirror --alpha 0.3", "--plugin"},
      {std::string("check-bsdf --plugin ") + MICROSIM_PLUGIN_GOOD + " --param colour=red --bsdf mirror --alpha 0.3",
       "refused the parameters"},
      {std::string("check-bsdf --plugin ") + MICROSIM_PLUGIN_GOOD + " --bsdf lambertian --alpha 0.3", "--bsdf"},
      {std::string("check-bsdf --plugin ") + MICROSIM_PLUGIN_GOOD + " --bsdf mirror --alpha 0.3 --reference walk",
       "--reference"},
      {std::string("check-bsdf --plugin ") + MICROSIM_PLUGIN_GOOD + " --bsdf mirror --alpha 0.3 --html " +
       MICROSIM_PLUGIN_GOOD, "--html"},
      {std::string("check-bsdf --plugin ") + MICROSIM_PLUGIN_SMITH_WALK + " --bsdf mirror --alpha 0.3",
       "needs a deterministic eval"},
      {std::string("check-bsdf --plugin ") + MICROSIM_PLUGIN_GOOD + " --bsdf mirror --alpha 0.3 --view 120",
       "from inside"},
      {std::string("check-bsdf --plugin ") + MICROSIM_PLUGIN_GOOD + " --bsdf mirror --alpha 0.3 --view 10,20,30",
       "--view"},
      {std::string("check-bsdf --plugin ") + MICROSIM_PLUGIN_NDF + " " + kPluginGlass, "heavy-tailed"},
      {std::string("check-bsdf --plugin ") + MICROSIM_PLUGIN_GOOD + " --bsdf mirror --alpha 0.3 --level 0", "--level"},
      {std::string("check-bsdf --plugin ") + MICROSIM_PLUGIN_GOOD + " --bsdf mirror --alpha 0.3 --level 1", "--level"},
      {"check-bsdf-files d.npy e.npy --theta 60 --level 0", "--level '0': outside (0, 1)"},
  };
  for (const auto& [args, message] : cases) {
    const CliRun r = run_cli(dir, args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.err;
    EXPECT_NE(r.err.find(message), std::string::npos) << args << "\n" << r.err;
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace microsim::test
