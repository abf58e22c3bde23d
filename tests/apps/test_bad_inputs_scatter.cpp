// Bad-input table for `scatter`, `compare-scattering` and `merge` of scatter parts: an unknown
// material, eta <= 0 or not finite, k < 0, an order cap < 1, a file that is not a scatter histogram, and
// the options' own rules. Each must exit 2 with stderr naming the bad value, and write nothing.
#include "cli_helpers.h"
#include "scatter_samples.h"

#include "microgeom/exr_io.h"
#include "stats/scatter_io.h"
#include "stats/scatter_merge.h"

#include <gtest/gtest.h>

#include <fstream>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_bad_inputs_scatter {

namespace {

using microsim::test::BadInputCase;
namespace fs = std::filesystem;

const std::string kAnalytic = "scatter --model analytic --alpha 0.5 --theta 30 --out o.exr ";
const std::string kWalk = "scatter --model smith-walk --alpha 0.5 --theta 30 --rays 4096 --out o.exr ";
const std::string kSurface = "scatter --surface hf.exr --theta 30 --rays 4096 --out o.exr ";

// A small analytic scatter file, written by `microsim scatter` once per build of the tests.
const fs::path& analytic_fixture() {
  static const fs::path path = microsim::test::shared_fixture_dir("bad_scatter", [](const fs::path& dir) {
    const auto r = microsim::test::run_cli(dir, kAnalytic + "--rows 2");
    EXPECT_EQ(r.exit_code, 0) << r.err;
  }) / "o.exr";
  return path;
}

// DIR gets the analytic fixture as a.exr, a small measured run's part as p.json, a heightmap as hf.exr, a text file
// as text.exr and a copy of the fixture with one attribute replaced as bad.exr.
void prepare_files(const fs::path& dir) {
  fs::copy_file(analytic_fixture(), dir / "a.exr");
  microsim::ScatterOptions o;
  o.paths = 1000;
  o.rows = 2;
  std::ofstream(dir / "p.json") << microsim::scatter_part_json(microsim::test::synthetic_scatter(o, 0.5), {}).dump();
  microgeom::ExrImage heightmap;
  heightmap.width = heightmap.height = 4;
  heightmap.add_channel("height");
  heightmap.attributes["microsim.tile_size"] = "1";
  microgeom::write_exr(dir / "hf.exr", heightmap);
  std::ofstream(dir / "text.exr") << "not an EXR file";
  microgeom::ExrImage bad = microgeom::read_exr(analytic_fixture());
  bad.attributes["c0.error_estimate"] = "-1";
  microgeom::write_exr(dir / "bad.exr", bad);
}

std::vector<BadInputCase> scatter_cases() {
  return {
      // materials
      {"unknown_material", kAnalytic + "--material gold", 2, "'gold': unknown material"},
      {"eta_zero", kAnalytic + "--material dielectric:0", 2, "'0'"},
      {"eta_negative", kAnalytic + "--material dielectric:-1.5", 2, "'-1.5'"},
      {"eta_infinite", kAnalytic + "--material dielectric:inf", 2, "'inf'"},
      {"eta_nan", kAnalytic + "--material dielectric:nan", 2, "'nan'"},
      {"eta_one", kAnalytic + "--material dielectric:1", 2, "eta 1"},
      {"conductor_eta_zero", kAnalytic + "--material conductor:0,3", 2, "'0'"},
      {"conductor_k_negative", kAnalytic + "--material 'conductor:0.2,3.9;0.5,-2.4'", 2, "'-2.4'"},
      {"conductor_k_missing", kAnalytic + "--material conductor:0.2", 2, "'0.2'"},
      {"lambertian_analytic", kAnalytic + "--material lambertian", 2, "lambertian"},
      // the order cap and the other numbers
      {"order_cap_zero", kAnalytic + "--max-order 0", 2, "--max-order"},
      {"order_cap_negative", kAnalytic + "--max-order -3", 2, "'-3'"},
      {"order_cap_real", kAnalytic + "--max-order 2.5", 2, "'2.5'"},
      {"rows_zero", kAnalytic + "--rows 0", 2, "--rows"},
      {"rows_too_many", kAnalytic + "--rows 251", 2, "'251'"},
      {"theta_horizon", "scatter --model analytic --alpha 0.5 --theta 90 --out o.exr", 2, "--theta 90"},
      {"theta_below_opaque", "scatter --model analytic --alpha 0.5 --theta 120 --out o.exr", 2, "--theta 120"},
      {"theta_beyond", "scatter --model analytic --alpha 0.5 --theta 181 --out o.exr", 2, "--theta 181"},
      {"alpha_zero", "scatter --model analytic --alpha 0 --theta 30 --out o.exr", 2, "--alpha"},
      {"alpha_missing", "scatter --model analytic --theta 30 --out o.exr", 2, "--alpha is required"},
      // options that do not apply, unknown models
      {"rays_analytic", kAnalytic + "--rays 1000", 2, "--rays applies to the sampled models"},
      {"shard_analytic", kAnalytic + "--shard 1/2", 2, "--shard applies"},
      {"ndf_unknown", kAnalytic + "--ndf phong", 2, "--ndf phong"},
      {"model_unknown", "scatter --model walk --alpha 0.5 --theta 30 --out o.exr", 2, "--model 'walk'"},
      {"out_not_exr", "scatter --model analytic --alpha 0.5 --theta 30 --out o.png", 2, "--out 'o.png'"},
      {"out_no_directory", "scatter --model analytic --alpha 0.5 --theta 30 --out nodir/o.exr", 2, "nodir"},
      // the Smith walk
      {"walk_alpha_missing", "scatter --model smith-walk --theta 30 --out o.exr", 2, "--alpha is required"},
      {"walk_alpha_too_large", "scatter --model smith-walk --alpha 20 --theta 30 --out o.exr", 2, "--alpha"},
      {"walk_heights_unknown", kWalk + "--heights normal", 2, "'normal'"},
      {"walk_tile_size", kWalk + "--tile-size 1", 2, "--tile-size applies to --surface"},
      {"walk_order_cap_zero", kWalk + "--max-order 0", 2, "--max-order"},
      {"walk_from_inside_a_mirror", "scatter --model smith-walk --alpha 0.5 --theta 120 --out o.exr", 2, "--theta 120"},
      {"walk_shard_beyond", kWalk + "--shard 2/1", 2, "--shard"},
      {"walk_eta_negative", kWalk + "--material dielectric:-2", 2, "'-2'"},
      {"walk_k_negative", kWalk + "--material conductor:1,-1", 2, "'-1'"},
      {"walk_kernel_unknown", kWalk + "--walk-kernel simd", 2, "--walk-kernel 'simd'"},
      {"walk_kernel_lanes_beckmann", kWalk + "--walk-kernel lanes --ndf beckmann", 2,
       "--ndf beckmann: not supported by --walk-kernel lanes"},
      {"walk_kernel_lanes_gaussian", kWalk + "--walk-kernel lanes --heights gaussian", 2,
       "--heights gaussian: not supported by --walk-kernel lanes"},
      {"walk_kernel_lanes_lambertian", kWalk + "--walk-kernel lanes --material lambertian:0.8", 2,
       "--material lambertian:0.8: not supported by --walk-kernel lanes"},
      {"analytic_walk_kernel", kAnalytic + "--walk-kernel lanes", 2, "--walk-kernel applies to --model smith-walk only"},
      // an explicit surface
      {"surface_missing", "scatter --surface none.exr --theta 30 --out o.exr", 2, "'none.exr'"},
      {"surface_is_a_scatter_file", "scatter --surface a.exr --theta 30 --out o.exr", 2, "a.exr", prepare_files},
      {"surface_is_text", "scatter --surface text.exr --theta 30 --out o.exr", 2, "text.exr", prepare_files},
      {"surface_with_alpha", kSurface + "--alpha 0.5", 2, "--alpha applies to --model only", prepare_files},
      {"surface_with_ndf", kSurface + "--ndf beckmann", 2, "--ndf applies to --model only", prepare_files},
      {"surface_walk_kernel", kSurface + "--walk-kernel lanes", 2, "--walk-kernel applies to --model smith-walk only", prepare_files},
      {"surface_and_model", kSurface + "--model smith-walk", 2, "exclude each other", prepare_files},
      {"surface_out_is_input", "scatter --surface hf.exr --theta 30 --out hf.exr", 2, "hf.exr", prepare_files},
      {"surface_order_cap_zero", kSurface + "--max-order 0", 2, "--max-order", prepare_files},
      {"surface_from_inside_a_mirror", "scatter --surface hf.exr --theta 120 --out o.exr", 2, "--theta 120", prepare_files},
      {"surface_unknown_material", kSurface + "--material silver", 2, "'silver'", prepare_files},
      // files that are not scatter histograms
      {"compare_heightmap", "compare-scattering hf.exr a.exr", 2, "not a microsim scatter file", prepare_files},
      {"compare_text", "compare-scattering a.exr text.exr --json c.json", 2, "text.exr", prepare_files},
      {"compare_missing", "compare-scattering a.exr none.exr", 2, "'none.exr': no such file", prepare_files},
      {"compare_bad_attribute", "compare-scattering a.exr bad.exr", 2, "attribute c0.error_estimate = '-1'", prepare_files},
      {"compare_two_expectations", "compare-scattering a.exr a.exr --json c.json", 2, "nothing random", prepare_files},
      {"compare_one_file", "compare-scattering a.exr", 2, "2 or 3 results", prepare_files},
      {"compare_four_files", "compare-scattering a.exr a.exr a.exr a.exr", 2, "2 or 3 results", prepare_files},
      {"compare_analytic_of_expectation", "compare-scattering a.exr --analytic", 2, "already an expectation", prepare_files},
      {"compare_orders_unknown", "compare-scattering a.exr a.exr --orders 1,6", 2, "unknown order '6'", prepare_files},
      {"compare_orders_twice", "compare-scattering a.exr a.exr --orders 1,1", 2, "given twice", prepare_files},
      {"compare_level", "compare-scattering a.exr a.exr --level 1.5", 2, "--level '1.5': outside (0, 1)", prepare_files},
      {"compare_svg_extension", "compare-scattering a.exr a.exr --svg f.png", 2, "--svg 'f.png'", prepare_files},
      {"compare_json_is_input", "compare-scattering a.exr hf.exr --json a.exr", 2, "a.exr", prepare_files},
      // merge of scatter parts
      {"merge_scatter_file", "merge a.exr --out m.exr", 2, "'a.exr' is an EXR file: parts are JSON now", prepare_files},
      {"merge_with_heightmap", "merge p.json hf.exr --out m.exr", 2, "'hf.exr' is an EXR file", prepare_files},
      {"merge_text", "merge p.json text.exr --out m.exr", 2, "'text.exr'", prepare_files},
      {"merge_no_out", "merge p.json", 2, "--out MERGED.exr is required", prepare_files},
  };
}

class BadInputsScatter : public ::testing::TestWithParam<BadInputCase> {};

TEST_P(BadInputsScatter, ExitsTwoNamingTheValueAndWritesNothing) {
  microsim::test::expect_bad_input(GetParam(), "bad_scatter");
}

INSTANTIATE_TEST_SUITE_P(Cases, BadInputsScatter, ::testing::ValuesIn(scatter_cases()),
                         [](const auto& info) { return info.param.name; });

}  // namespace

}  // namespace test_bad_inputs_scatter
