// `microsim albedo` end to end: a small table of each model is written (EXR, CSV, JSON) and agrees with the
// library; the bad-input table: each case exits 2 naming the bad value and writes nothing.
#include "cli_helpers.h"

#include "microgeom/exr_io.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

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

const std::string kAlbedo = "albedo --model analytic --out o.exr ";

std::vector<BadInputCase> albedo_cli_cases() {
  return {
      {"model_unknown", "albedo --model walk --out o.exr", 2, "--model 'walk'"},
      {"model_missing", "albedo --out o.exr", 2, "--model"},
      {"material_unknown", kAlbedo + "--material gold", 2, "'gold': unknown material"},
      {"material_conductor", kAlbedo + "--material conductor:0.2,3.9", 2,
       "'conductor:0.2,3.9': conductor tables are not computed yet; use --material mirror (F = 1) for the Kulla-Conty "
       "E(mu) of a conductor's microsurface"},
      {"material_lambertian", kAlbedo + "--material lambertian", 2, "mirror or dielectric:ETA"},
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
  };
}

class BadInputsAlbedo : public ::testing::TestWithParam<BadInputCase> {};

TEST_P(BadInputsAlbedo, ExitsTwoNamingTheValueAndWritesNothing) {
  microsim::test::expect_bad_input(GetParam(), "bad_albedo");
}

INSTANTIATE_TEST_SUITE_P(Cases, BadInputsAlbedo, ::testing::ValuesIn(albedo_cli_cases()),
                         [](const auto& info) { return info.param.name; });

}  // namespace
