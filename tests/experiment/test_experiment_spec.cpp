// Experiment specs (src/experiment/spec.h): good specs in TOML and JSON read into the same content, and
// every bad spec is a SpecError naming the key path and the line where it is.
#include "experiment/spec.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <ostream>
#include <string>

// Its own namespace: the file shares a unity batch with others (CMakeLists.txt, microsim_unity).
namespace test_experiment_spec {

namespace {

using namespace microsim::experiment;

const char* kGood = R"(name = "good"
seed = 5

[[material]]
name = "gold"
ndf = "ggx"
alphas = [0.1, 0.5, [0.2, 0.4]]
type = "conductor"
eta = [0.2, 0.4]
k = [3.9, 2.4]

[[material]]
name = "glass"
alpha = 0.3
type = "dielectric"
eta = 1.5

[[quantity]]
kind = "vndf"
material = "gold"
theta = [0, 45]
phi = [0, 90]
target_tv = 0.01

[[quantity]]
kind = "albedo"
material = "glass"
orders = "all"
inside = true
target_relative_error = 1e-3

[[quantity]]
kind = "scattering"
material = "glass"
theta_range = { from = 100, to = 170, count = 3 }
target_tv = 0.01

[[quantity]]
kind = "validation"
material = "gold"
sampler = "heitz2018"
theta = [30]
detect_tv = 0.001
)";

TEST(ExperimentSpec, ReadsAGoodTomlSpec) {
  const ExperimentSpec s = parse_spec_toml(kGood, "good.toml");
  EXPECT_EQ(s.name, "good");
  EXPECT_EQ(s.seed, 5u);
  ASSERT_EQ(s.materials.size(), 2u);
  ASSERT_EQ(s.materials[0].alphas.size(), 3u);
  EXPECT_EQ(s.materials[0].alphas[2], (std::pair<double, double>{0.2, 0.4}));
  EXPECT_EQ(s.materials[0].facet.kind(), microsim::MaterialKind::conductor);
  EXPECT_EQ(s.materials[0].facet.channels(), 2);
  EXPECT_EQ(s.materials[0].line, 4);
  EXPECT_EQ(s.materials[1].facet.eta(), 1.5);
  ASSERT_EQ(s.quantities.size(), 4u);
  EXPECT_EQ(s.quantities[0].directions.size(), 4u);  // theta x phi
  EXPECT_EQ(s.quantities[0].line, 18);
  EXPECT_EQ(s.quantities[1].orders, Orders::all);
  EXPECT_TRUE(s.quantities[1].inside);
  ASSERT_EQ(s.quantities[2].directions.size(), 3u);
  EXPECT_DOUBLE_EQ(s.quantities[2].directions[1].theta_deg, 135);  // from inside the glass
  EXPECT_EQ(s.quantities[3].sampler, "heitz2018");
  EXPECT_DOUBLE_EQ(s.quantities[3].power, 0.9);
}

TEST(ExperimentSpec, JsonOfTheSameStructureIsTheSameSpec) {
  const std::string json = R"({"name": "good", "seed": 5,
  "material": [{"name": "gold", "ndf": "ggx", "alphas": [0.1, 0.5, [0.2, 0.4]], "type": "conductor",
                "eta": [0.2, 0.4], "k": [3.9, 2.4]},
               {"name": "glass", "alpha": 0.3, "type": "dielectric", "eta": 1.5}],
  "quantity": [{"kind": "vndf", "material": "gold", "theta": [0, 45], "phi": [0, 90], "target_tv": 0.01},
               {"kind": "albedo", "material": "glass", "orders": "all", "inside": true, "target_relative_error": 1e-3},
               {"kind": "scattering", "material": "glass", "theta_range": {"from": 100, "to": 170, "count": 3},
                "target_tv": 0.01},
               {"kind": "validation", "material": "gold", "sampler": "heitz2018", "theta": [30], "detect_tv": 0.001}]})";
  const ExperimentSpec a = parse_spec_toml(kGood, "good.toml"), b = parse_spec_json(json, "good.json");
  EXPECT_EQ(canonical_spec(a), canonical_spec(b));
  EXPECT_EQ(spec_digest(a), spec_digest(b));
  ExperimentSpec c = a;
  c.quantities[1].target = 2e-3;  // the digest sees a change of target
  EXPECT_NE(spec_digest(a), spec_digest(c));
}

struct BadSpec {
  std::string name, text, key;
  int line;
  std::string words;  // part of the message
};

std::ostream& operator<<(std::ostream& os, const BadSpec& c) { return os << c.name; }

// A valid one-material, one-quantity spec with `material_extra` and `quantity_extra` appended to its tables.
std::string spec_with(const std::string& material, const std::string& quantity) {
  return "name = \"t\"\n\n[[material]]\nname = \"m\"\n" + material + "\n\n[[quantity]]\n" + quantity + "\n";
}
const std::string kMirror = "alpha = 0.3\ntype = \"mirror\"";                    // material lines 5-6
const std::string kVndf = "kind = \"vndf\"\nmaterial = \"m\"\ntheta = [30]\ntarget_tv = 0.01";  // lines 9-12
const std::string kValidation = "kind = \"validation\"\nmaterial = \"m\"\ntheta = [30]\ndetect_tv = 0.01";  // lines 9-12
const std::string kDump = MICROSIM_TEST_DATA "/npy_samples_f8.npy";  // an existing sample file

class BadSpecs : public ::testing::TestWithParam<BadSpec> {};

TEST_P(BadSpecs, NameTheKeyAndTheLine) {
  const BadSpec& c = GetParam();
  try {
    parse_spec_toml(c.text, "bad.toml");
    FAIL() << c.name << ": accepted";
  } catch (const SpecError& e) {
    EXPECT_EQ(e.key(), c.key) << e.what();
    EXPECT_EQ(e.line(), c.line) << e.what();
    const std::string what = e.what();
    const std::string where = c.line > 0 ? "bad.toml:" + std::to_string(c.line) : "bad.toml";
    EXPECT_NE(what.find(where + ": " + c.key), std::string::npos) << what;
    EXPECT_NE(what.find(c.words), std::string::npos) << what;
    const std::invalid_argument& bad_input = e;  // the project's bad input: exit 2
    (void)bad_input;
  }
}

INSTANTIATE_TEST_SUITE_P(
    ExperimentSpec, BadSpecs,
    ::testing::Values(
        BadSpec{"unknown_top_key", "colour = 3\n" + spec_with(kMirror, kVndf), "colour", 1, "unknown key"},
        BadSpec{"unknown_quantity_key", spec_with(kMirror, kVndf + "\nrays = 5"), "quantity[0].rays", 13, "unknown key"},
        BadSpec{"wrong_target_for_kind", spec_with(kMirror, "kind = \"albedo\"\nmaterial = \"m\"\ntarget_tv = 0.1"),
                "quantity[0].target_tv", 11, "unknown key"},
        BadSpec{"target_zero", spec_with(kMirror, "kind = \"vndf\"\nmaterial = \"m\"\ntheta = [30]\ntarget_tv = 0"),
                "quantity[0].target_tv", 12, "must be > 0"},
        BadSpec{"target_negative", spec_with(kMirror, "kind = \"albedo\"\nmaterial = \"m\"\ntarget_relative_error = -1"),
                "quantity[0].target_relative_error", 11, "must be > 0"},
        BadSpec{"unknown_material", spec_with(kMirror, "kind = \"vndf\"\nmaterial = \"gold\"\ntheta = [30]\ntarget_tv = 0.1"),
                "quantity[0].material", 10, "no material named 'gold'"},
        BadSpec{"below_horizon", spec_with(kMirror, "kind = \"vndf\"\nmaterial = \"m\"\ntheta = [30, 95]\ntarget_tv = 0.1"),
                "quantity[0].theta", 11, "below the horizon"},
        BadSpec{"grazing_90", spec_with(kMirror, "kind = \"vndf\"\nmaterial = \"m\"\ntheta = [90]\ntarget_tv = 0.1"),
                "quantity[0].theta", 11, "at or below the horizon"},
        BadSpec{"inside_an_opaque_material",
                spec_with(kMirror, "kind = \"scattering\"\nmaterial = \"m\"\ntheta = [120]\ntarget_tv = 0.1"),
                "quantity[0].theta", 11, "below the horizon"},
        BadSpec{"unknown_ndf", spec_with("ndf = \"phong\"\n" + kMirror, kVndf), "material[0].ndf", 5, "not an NDF"},
        BadSpec{"alpha_out_of_range", spec_with("alpha = 20\ntype = \"mirror\"", kVndf), "material[0].alpha", 5, "alpha"},
        BadSpec{"dielectric_with_k", spec_with("alpha = 0.3\ntype = \"dielectric\"\neta = 1.5\nk = 1", kVndf),
                "material[0].k", 8, "eta only"},
        BadSpec{"conductor_channels", spec_with("alpha = 0.3\ntype = \"conductor\"\neta = [0.2, 0.3]\nk = [1]", kVndf),
                "material[0].k", 8, "one per channel"},
        BadSpec{"unknown_type", spec_with("alpha = 0.3\ntype = \"velvet\"", kVndf), "material[0].type", 6, "not a material type"},
        BadSpec{"albedo_alphas_decrease",
                spec_with("alphas = [0.5, 0.1]\ntype = \"mirror\"", "kind = \"albedo\"\nmaterial = \"m\"\ntarget_relative_error = 0.01"),
                "quantity[0].material", 10, "must increase"},
        BadSpec{"even_rows", spec_with(kMirror, kVndf + "\nrows = 30"), "quantity[0].rows", 13, "must be odd"},
        BadSpec{"repeated_view", spec_with(kMirror, "kind = \"vndf\"\nmaterial = \"m\"\ntheta = [40, 40]\ntarget_tv = 0.1"),
                "quantity[0].theta", 11, "theta 40 phi 0 is given twice"},
        BadSpec{"repeated_alpha", spec_with("alphas = [0.3, 0.5, 0.3]\ntype = \"mirror\"", kVndf), "material[0].alphas", 5,
                "alpha 0.3,0.3 is given twice"},
        BadSpec{"unknown_walk_kernel",
                spec_with(kMirror, "kind = \"scattering\"\nmaterial = \"m\"\ntheta = [30]\ntarget_tv = 0.1\nwalk_kernel = \"gpu\""),
                "quantity[0].walk_kernel", 13, "scalar or lanes"},
        BadSpec{"lanes_on_beckmann",
                spec_with("ndf = \"beckmann\"\n" + kMirror,
                          "kind = \"albedo\"\nmaterial = \"m\"\ntarget_relative_error = 0.01\nwalk_kernel = \"lanes\""),
                "quantity[0].walk_kernel", 13, "lanes walks GGX"},
        BadSpec{"unknown_sampler",
                spec_with(kMirror, "kind = \"validation\"\nmaterial = \"m\"\nsampler = \"nope\"\ntheta = [0]\ndetect_tv = 0.01"),
                "quantity[0].sampler", 11, "not a sampler of the zoo"},
        BadSpec{"sampler_and_dump", spec_with(kMirror, kValidation + "\nsampler = \"heitz2018\"\ndump = \"" + kDump + "\""),
                "quantity[0].sampler", 13, "exactly one of sampler"},
        BadSpec{"neither_sampler_nor_dump", spec_with(kMirror, kValidation), "quantity[0].sampler", 8, "exactly one of sampler"},
        BadSpec{"missing_dump", spec_with(kMirror, kValidation + "\ndump = \"no-such-dump.npy\""), "quantity[0].dump", 13,
                "no sample file"},
        BadSpec{"dump_at_two_alphas", spec_with("alphas = [0.3, 0.5]\ntype = \"mirror\"", kValidation + "\ndump = \"" + kDump + "\""),
                "quantity[0].dump", 13, "one alpha and one view (material 'm' has 2 alpha(s)"},
        BadSpec{"dump_at_two_views", spec_with(kMirror, "kind = \"validation\"\nmaterial = \"m\"\ntheta = [0, 30]\ndetect_tv = 0.01\ndump = \"" + kDump + "\""),
                "quantity[0].dump", 13, "the quantity 2 view(s)"},
        BadSpec{"dump_transport_without_a_bsdf", spec_with(kMirror, kValidation + "\ndump = \"" + kDump + "\"\ntransport = \"radiance\""),
                "quantity[0].transport", 14, "the convention of a BSDF's weights"},
        BadSpec{"dump_unknown_transport", spec_with(kMirror, kValidation + "\ndump = \"" + kDump + "\"\npdf = \"bsdf\"\ntransport = \"flux\""),
                "quantity[0].transport", 15, "importance"},
        BadSpec{"dump_unknown_masking", spec_with(kMirror, kValidation + "\ndump = \"" + kDump + "\"\npdf = \"bsdf\"\nmasking = \"smith\""),
                "quantity[0].masking", 15, "separable"},
        BadSpec{"dump_bad_columns", spec_with(kMirror, kValidation + "\ndump = \"" + kDump + "\"\ncolumns = \"x,y,q\""),
                "quantity[0].columns", 14, "q"},
        BadSpec{"dump_bad_frame", spec_with(kMirror, kValidation + "\ndump = \"" + kDump + "\"\nframe = \"x-up\""),
                "quantity[0].frame", 14, "not a frame"},
        BadSpec{"dump_dropped_without_above_horizon", spec_with(kMirror, kValidation + "\ndump = \"" + kDump + "\"\ndropped = 5"),
                "quantity[0].dropped", 14, "above_horizon"},
        BadSpec{"dump_from_inside_without_a_bsdf",
                spec_with("alpha = 0.3\ntype = \"dielectric\"\neta = 1.5",
                          "kind = \"validation\"\nmaterial = \"m\"\ntheta = [120]\ndump = \"" + kDump + "\""),
                "quantity[0].theta", 12, "light from inside a dielectric"},
        BadSpec{"sampler_with_columns", spec_with(kMirror, kValidation + "\nsampler = \"heitz2018\"\ncolumns = \"x,y,z\""),
                "quantity[0].columns", 14, "applies to a dump"},
        BadSpec{"dump_unknown_pdf", spec_with(kMirror, kValidation + "\ndump = \"" + kDump + "\"\npdf = \"ggx\""),
                "quantity[0].pdf", 14, "vndf"},
        BadSpec{"dump_normals_above_horizon", spec_with(kMirror, kValidation + "\ndump = \"" + kDump + "\"\nabove_horizon = true"),
                "quantity[0].above_horizon", 14, "a density of normals"},
        BadSpec{"sampler_with_pdf", spec_with(kMirror, kValidation + "\nsampler = \"heitz2018\"\npdf = \"ndf\""),
                "quantity[0].pdf", 14, "applies to a dump"},
        BadSpec{"dump_on_a_surface_without_detect_tv",  // the tile is sized from it
                spec_with(kMirror, "kind = \"validation\"\nmaterial = \"m\"\ntheta = [30]\nsurface = \"smith\"\ndump = \"" +
                                       kDump + "\""),
                "quantity[0].detect_tv", 8, "missing (required)"},
        BadSpec{"unknown_surface", spec_with(kMirror, kVndf + "\nsurface = \"moon\""), "quantity[0].surface", 13,
                "neither auto"},
        BadSpec{"missing_heightmap", spec_with(kMirror, kVndf + "\nsurface = \"no-such-file.exr\""), "quantity[0].surface",
                13, "no heightmap file"},
        BadSpec{"target_a_string", spec_with(kMirror, "kind = \"vndf\"\nmaterial = \"m\"\ntheta = [30]\ntarget_tv = \"small\""),
                "quantity[0].target_tv", 12, "must be a number"},
        BadSpec{"no_quantity", "name = \"t\"\n[[material]]\nname = \"m\"\n" + kMirror + "\n", "quantity", 0, "missing"},
        BadSpec{"syntax", spec_with(kMirror, kVndf) + "oops = [1, \n", "(syntax)", 13, ""}),
    [](const auto& info) { return info.param.name; });

// walk_kernel = "lanes" is a setting of the quantity (its digest changes); "scalar", the default, leaves the spec
// as it was without the key.
TEST(ExperimentSpec, TheWalkKernelIsRecordedOnlyWhenLanes) {
  const std::string albedo = "kind = \"albedo\"\nmaterial = \"m\"\norders = \"all\"\ntarget_relative_error = 0.01";
  const ExperimentSpec plain = parse_spec_toml(spec_with(kMirror, albedo), "a.toml");
  const ExperimentSpec scalar = parse_spec_toml(spec_with(kMirror, albedo + "\nwalk_kernel = \"scalar\""), "a.toml");
  const ExperimentSpec lanes = parse_spec_toml(spec_with(kMirror, albedo + "\nwalk_kernel = \"lanes\""), "a.toml");
  EXPECT_EQ(spec_digest(plain), spec_digest(scalar));
  EXPECT_NE(spec_digest(plain), spec_digest(lanes));
  EXPECT_EQ(lanes.quantities[0].settings.value("walk_kernel", ""), "lanes");
}

TEST(ExperimentSpec, JsonErrorsNameTheLineOfTheKey) {
  const std::string json = "{\n  \"material\": [{\"name\": \"m\", \"alpha\": 0.3, \"type\": \"mirror\"}],\n"
                           "  \"quantity\": [\n    {\"kind\": \"vndf\", \"material\": \"m\", \"theta\": [30],\n"
                           "     \"target_tv\": -0.5}\n  ]\n}\n";
  try {
    parse_spec_json(json, "bad.json");
    FAIL() << "accepted";
  } catch (const SpecError& e) {
    EXPECT_EQ(e.key(), "quantity[0].target_tv");
    EXPECT_EQ(e.line(), 5) << e.what();
  }
}

// A key given twice in one JSON object is refused (TOML refuses it too): the parser would keep the last silently.
TEST(ExperimentSpec, AJsonKeyGivenTwiceIsASpecError) {
  const std::string once = "{\"material\": [{\"name\": \"m\", \"alpha\": 0.3, \"type\": \"mirror\"}],\n"
                           "\"quantity\": [{\"kind\": \"validation\", \"material\": \"m\", \"sampler\": \"ndf\", "
                           "\"theta\": [30], \"detect_tv\": 0.05, \"significance\": 0.01";
  EXPECT_NO_THROW(parse_spec_json(once + "}]}", "once.json"));
  try {
    parse_spec_json(once + ", \"significance\": 0.4}]}", "twice.json");
    FAIL() << "accepted";
  } catch (const SpecError& e) {
    EXPECT_EQ(e.key(), "significance");
    EXPECT_NE(std::string(e.what()).find("given twice"), std::string::npos) << e.what();
  }
}

TEST(ExperimentSpec, TheExamplesAreGoodSpecs) {
  const std::filesystem::path examples = std::filesystem::path(MICROSIM_TEST_DATA) / ".." / ".." / "examples";
  int read = 0;
  for (const auto& e : std::filesystem::directory_iterator(examples))
    if (e.path().extension() == ".toml" || e.path().extension() == ".json") {
      EXPECT_NO_THROW(load_spec(e.path())) << e.path();
      ++read;
    }
  EXPECT_GE(read, 1);
}

TEST(ExperimentSpec, AnUnreadableFileIsASpecError) {
  EXPECT_THROW(load_spec("/nonexistent/spec.toml"), SpecError);
}

}  // namespace

}  // namespace test_experiment_spec
