// microsim trace masking: masking and masking-shadowing of an explicit heightfield, measured by ray
// tracing, beside Smith's predictions with the analytic NDF and with the surface's own NDF
// (src/trace/masking.h, src/trace/smith_prediction.h; the measurement: src/measure/masking.h; the
// report: masking_report.h, shared with `microsim merge`).
//
//   trace masking --surface SURF.exr --theta DEG [--phi DEG] [--samples N] [--seed S] [--theta-l DEG
//                 [--phi-l DEG]] [--cone DEG] [--bins K] [--vndf-rays N] [--geometry triangles|grid]
//                 [--tile-size L] [--threads T] [--grazing-share Q] [--json PATH] [--shard K/N]
//   With --shard K/N only block range K of N of the run is sampled and --json holds the partial result
//   (provenance and exact sums) that `microsim merge` joins with the other shards into the whole run.
//   trace masking --table [--assemblies a,b,..] [--alphas 0.1,0.5,1] [--thetas 30,60,75,85] [--phi DEG]
//                 [--res N] [--corr-cells C] [--seed S | --seeds S1,S2,..] [--samples N] [--vndf-rays N]
//                 [--grazing-share Q] [--markdown PATH] [--json PATH]
//   With --seeds each table cell is the mean over the surface realisations ± its standard error across
//   them, beside the Monte Carlo error of that mean.
//
// Exit codes: 0 done; 1 the leak test failed (the weighted visible fraction / cos(theta_v) is more than
// kLeakSigmas standard errors from 1, or a ray leaked through the surface); 2 bad usage or input (nothing
// written); 130 interrupted (what was measured is written, marked partial).
#include "command.h"
#include "masking_report.h"
#include "masking_table_report.h"
#include "surface_input.h"
#include "number_options.h"

#include "microgeom/assembly.h"
#include "microgeom/heightfield.h"
#include "stats/histogram_io.h"
#include "measure/masking.h"
#include "measure/masking_table.h"
#include "progress_bar.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <new>
#include <optional>
#include <string>
#include <vector>

namespace microsim::app {

namespace {

namespace fs = std::filesystem;

// "a,b,c": the list rules of the number parser (no empty item).
std::vector<std::string> split_names(const std::string& option, const std::string& text) {
  std::vector<std::string> names;
  for (const std::string_view item : split_list(option, text)) names.emplace_back(item);
  return names;
}


void check_grazing_share(double share) {
  if (!(share > 0 && share < 0.5))
    throw UsageError(fmt::format("--grazing-share {}: must be in (0, 0.5)", share));
}




// ---- single surface -------------------------------------------------------------------------------------------

struct MaskingArgs {
  std::string surface;
  std::optional<double> tile_size;
  double theta = std::nan(""), phi = 0;
  std::optional<double> theta_l;
  double phi_l = 0;
  double cone = 5.0;
  long long samples = 1'000'000;
  long long vndf_rays = 0;
  unsigned long long seed = 1;
  int threads = 0;
  int bins = 10;
  double grazing_share = 0.02;
  std::string geometry = to_string(kDefaultHeightfieldGeometry);
  std::string json;
  std::string shard;  // "K/N": only block range K of N (single surface)
  // table mode
  bool table = false;
  std::string assemblies = microgeom::assembly_names(",");
  std::string alphas = "0.1,0.5,1";
  std::string thetas = "30,60,75,85";
  double table_phi = 30;
  int res = 1024;
  double corr_cells = 0;
  long long table_vndf_rays = 2'000'000;
  std::string markdown;
  std::string seeds;  // table: several realisations per cell ("1,2,3"); empty: --seed only
  std::string ndf_match = "radial";  // table: how the surfaces' NDF is matched
};

// The request of a single-surface run; --shard K/N: block range K of N of the run's blocks of
// kSamplesPerBlock points.
MaskingRequest masking_request(const MaskingArgs& a, const std::shared_ptr<CliProgress>& progress) {
  MaskingRequest r;
  r.theta_deg = a.theta;
  r.phi_deg = a.phi;
  r.theta_l_deg = a.theta_l;
  r.phi_l_deg = a.phi_l;
  r.cone_deg = a.cone;
  r.samples = std::uint64_t(a.samples);
  r.seed = a.seed;
  r.bins = a.bins;
  r.grazing_share = a.grazing_share;
  r.vndf_rays = std::uint64_t(a.vndf_rays);
  r.run = cli_run_control(a.threads, progress);
  if (!a.shard.empty()) {
    const BlockPlan plan{r.samples, kSamplesPerBlock};
    const ShardSpec s = parse_shard("--shard", a.shard, plan.blocks());  // ParseError: exit 2
    r.blocks = shard_range(plan.blocks(), s.index, s.count);
  }
  return r;
}

// --shard: a partial result is written to --json; the VNDF is sharded by trace vndf.
void check_shard(const MaskingArgs& a) {
  if (a.shard.empty()) return;
  if (a.vndf_rays > 0)
    throw UsageError(fmt::format("--shard {} with --vndf-rays: the VNDF is not sharded here; shard it with "
                                 "`trace vndf --surface {} --shard K/N` (and the masking without --vndf-rays)",
                                 a.shard, a.surface.empty() ? "S" : a.surface));
  if (a.json.empty())
    throw UsageError(fmt::format("--shard {}: needs --json PART.json (the partial result for `microsim merge`)", a.shard));
}

HeightfieldGeometry check_masking_args(const MaskingArgs& a) {
  check_distinct_outputs({{"--surface", a.surface}}, {{"--json", a.json}});
  if (a.surface.empty()) throw UsageError("--surface is required (or --table)");
  check_theta("--theta", a.theta);
  if (!std::isfinite(a.phi)) throw UsageError(fmt::format("--phi {}: must be finite", a.phi));
  if (a.theta_l) check_theta("--theta-l", *a.theta_l);
  if (!std::isfinite(a.phi_l)) throw UsageError(fmt::format("--phi-l {}: must be finite", a.phi_l));
  check_grazing_share(a.grazing_share);
  if (!(a.cone > 0 && a.cone <= 90)) throw UsageError(fmt::format("--cone {}: must be in (0, 90] degrees", a.cone));
  HeightfieldGeometry geometry;
  try {
    geometry = heightfield_geometry_from_string(a.geometry);
  } catch (const std::invalid_argument& e) {
    throw UsageError(fmt::format("--geometry: {}", e.what()));
  }
  check_shard(a);
  check_output("--json", a.json);
  return geometry;
}

int run_masking(const MaskingArgs& a) {
  // ---- validate everything before any work ----
  const HeightfieldGeometry geometry = check_masking_args(a);
  const auto progress = std::make_shared<CliProgress>(true);
  const MaskingRequest request = masking_request(a, progress);
  const microgeom::Heightfield field = load_surface(a.surface, a.tile_size);

  // ---- trace ----
  install_interrupt_handler();
  const MaskingSurface surface(field, a.surface, geometry, /*trace=*/true);
  fmt::print(stderr, "trace masking: {} ({} x {}, tile {}), {} geometry built in {:.2f} s, theta {} phi {}, {} samples{}\n",
             a.surface, field.resolution(), field.resolution(), field.tile_size(), to_string(geometry),
             surface.scene->build_seconds(), a.theta, a.phi, a.samples, a.shard.empty() ? "" : ", shard " + a.shard);
  SurfaceMasking m = measure_masking(surface, request);
  progress->finish();
  if (request.vndf_rays > 0 && !interrupted()) {
    m.vndf = measure_masking_vndf(surface, request);
    progress->finish();
  }
  return report_surface_masking(m, surface, {a.json});
}

// ---- the table ---------------------------------------------------------------------------------------------------

std::vector<std::uint64_t> parse_seeds(const MaskingArgs& a) {
  if (a.seeds.empty()) return {a.seed};
  std::vector<std::uint64_t> seeds;
  for (const std::uint64_t s : parse_uint_list("--seeds", a.seeds)) {
    if (std::find(seeds.begin(), seeds.end(), s) != seeds.end())
      throw UsageError(fmt::format("--seeds {}: seed {} appears twice", quote_excerpt(a.seeds), s));
    seeds.push_back(s);
  }
  return seeds;
}

void check_table_lists(const MaskingTableRequest& r) {
  for (double t : r.thetas) check_theta("--thetas", t);
  for (double al : r.alphas)
    if (!(al >= microgeom::kMinAssemblyAlpha && al <= microgeom::kMaxAssemblyAlpha))
      throw UsageError(fmt::format("--alphas: {} outside [{}, {}]", al, microgeom::kMinAssemblyAlpha, microgeom::kMaxAssemblyAlpha));
  for (const auto& n : r.assemblies)
    if (!microgeom::find_assembly(n)) throw UsageError(fmt::format("--assemblies: unknown assembly '{}'", n));
}

// --res and --corr-cells as every assembly takes them.
void check_table_resolution(const MaskingTableRequest& r) {
  microgeom::AssemblyParams p;
  p.resolution = r.resolution;
  p.corr_cells = r.corr_cells;
  try {
    microgeom::validate(p);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
}

// The table's request from the options, checked (UsageError naming the bad option).
MaskingTableRequest table_request(const MaskingArgs& a) {
  check_distinct_outputs({}, {{"--json", a.json}, {"--markdown", a.markdown}});
  MaskingTableRequest r;
  r.alphas = parse_double_list("--alphas", a.alphas);
  r.thetas = parse_double_list("--thetas", a.thetas);
  r.assemblies = split_names("--assemblies", a.assemblies);
  r.seeds = parse_seeds(a);
  const auto match = microgeom::ndf_match_from_string(a.ndf_match);
  if (!match) throw UsageError(fmt::format("--ndf-match '{}' must be radial or joint", a.ndf_match));
  r.ndf_match = *match;
  check_table_lists(r);
  if (a.table_vndf_rays <= 0) throw UsageError(fmt::format("--vndf-rays {}: must be positive", a.table_vndf_rays));
  if (!std::isfinite(a.table_phi)) throw UsageError(fmt::format("--phi {}: must be finite", a.table_phi));
  check_grazing_share(a.grazing_share);
  r.phi_deg = a.table_phi;
  r.resolution = a.res;
  r.corr_cells = a.corr_cells;
  r.samples = std::uint64_t(a.samples);
  r.vndf_rays = std::uint64_t(a.table_vndf_rays);
  r.grazing_share = a.grazing_share;
  check_table_resolution(r);
  check_output("--json", a.json);
  check_output("--markdown", a.markdown);
  r.run = cli_run_control(a.threads, nullptr);  // each view's line on stderr is the progress
  return r;
}

int run_table(const MaskingArgs& a) {
  const MaskingTableRequest request = table_request(a);
  install_interrupt_handler();
  const MaskingTable table = measure_masking_table(request, print_table_view);
  return report_masking_table(table, {a.json, a.markdown});
}

}  // namespace

namespace {

// The options of a single-surface run (--surface S).
void add_surface_options(CLI::App* sub, MaskingArgs& a) {
  sub->add_option("--surface", a.surface, "heightmap EXR (microsim surface build/import)");
  add_number_option(sub, "--tile-size", a.tile_size, real(),
                    "physical tile size, for heightmaps without the microsim.tile_size attribute");
  add_number_option(sub, "--theta", a.theta, real(), "view polar angle in degrees, [0, 90)");
  add_number_option(sub, "--phi", a.phi, real(), "view azimuth in degrees (single surface; default 0)");
  add_number_option(sub, "--theta-l", a.theta_l, real(), "light polar angle in degrees, [0, 90): adds G2(v, l)");
  add_number_option(sub, "--phi-l", a.phi_l, real(), "light azimuth in degrees")
      ->default_str(fmt::format("{}", a.phi_l));
  add_number_option(sub, "--cone", a.cone, real(),
                    "half-angle (deg) of the mirror cone around the half vector for G2(v, l)")
      ->default_str(fmt::format("{}", a.cone));
  add_number_option(sub, "--samples", a.samples, whole(1, kMaxSamples),
                    at_most("surface points per view", kMaxSamples))
      ->default_str(std::to_string(a.samples));
  add_number_option(sub, "--vndf-rays", a.vndf_rays, whole(0, kMaxRays),
                    at_most("also trace the VNDF with this many rays (single surface; table: rays per view, "
                            "default 2e6)",
                            kMaxRays));
  add_number_option(sub, "--seed", a.seed, whole(), "random seed (same seed, same result, whatever --threads)")
      ->default_str(std::to_string(a.seed));
  add_number_option(sub, "--threads", a.threads, integer(0, kMaxThreads),
                    at_most("worker threads (0: all cores)", kMaxThreads))
      ->default_str(std::to_string(a.threads));
  add_number_option(sub, "--bins", a.bins, integer(1, 1000), "bins of <v, m> and of height, 1..1000")
      ->default_str(std::to_string(a.bins));
  add_number_option(sub, "--grazing-share", a.grazing_share, real(),
                    "share of the front-facing projected area in the fine near-grazing class of G1(v | m) "
                    "(the facets with the smallest <v, m>), in (0, 0.5)")
      ->default_str(fmt::format("{}", a.grazing_share));
  sub->add_option("--geometry", a.geometry, "the heightfield's tracer: Embree's triangles or grid, or pyramid (exact walk "
                  "over a min-max height pyramid; the same hits, no BVH)")->capture_default_str();
  sub->add_option("--json", a.json, "write the results as JSON");
}

// The options of the table (--table).
void add_table_options(CLI::App* sub, MaskingArgs& a) {
  sub->add_flag("--table", a.table, "build the assemblies and print the masking table (docs/reference/masking.md)");
  sub->add_option("--assemblies", a.assemblies, "table: assemblies")->capture_default_str();
  sub->add_option("--alphas", a.alphas, "table: roughnesses")->capture_default_str();
  sub->add_option("--thetas", a.thetas, "table: view angles (deg)")->capture_default_str();
  add_number_option(sub, "--table-phi", a.table_phi, real(), "table: view azimuth (deg), off the grid axes")
      ->default_str(fmt::format("{}", a.table_phi));
  add_number_option(sub, "--res", a.res,
                    power_of_two(microgeom::kMinAssemblyResolution, microgeom::kMaxAssemblyResolution),
                    "table: surface resolution N (a power of two, 16..8192)")
      ->default_str(std::to_string(a.res));
  add_number_option(sub, "--corr-cells", a.corr_cells, real(),
                    "table: correlation length in cells (0: assembly default)")
      ->default_str(fmt::format("{}", a.corr_cells));
  sub->add_option("--ndf-match", a.ndf_match, "table: radial or joint (microsim surface build --ndf-match)")
      ->capture_default_str();
  sub->add_option("--seeds", a.seeds,
                  "table: several surface realisations per cell, e.g. 1,2,3 (each cell: mean over the realisations "
                  "± its standard error across them, and the Monte Carlo error of the mean); default: --seed only");
  sub->add_option("--markdown", a.markdown, "table: also write the markdown table to this file");
}

int run_selected_mode(const MaskingArgs& args) {
  if (args.table && !args.shard.empty())
    throw UsageError(fmt::format("--shard {} with --table: the table is not sharded; shard a single surface's run "
                                 "(trace masking --surface S --shard K/N, or trace vndf --surface S --shard K/N)",
                                 args.shard));
  if (args.table) {
    MaskingArgs a = args;
    if (a.vndf_rays > 0) a.table_vndf_rays = a.vndf_rays;
    return run_table(a);
  }
  return run_masking(args);
}

CommandRegistration trace_masking_registration{"trace masking", [](CLI::App& app) {
  CLI::App* trace = get_or_add_subcommand(app, "trace", "Ray-trace microsurfaces (the exact oracle)");
  auto args = std::make_shared<MaskingArgs>();
  auto* sub = trace->add_subcommand(
      "masking",
      "Masking of an explicit heightfield (an EXR from `microsim surface build`), by ray tracing: surface "
      "points uniform in (x, y) weighted by <v,m>+/mz, each with a shadow ray toward v. Reports the leak test "
      "(weighted visible fraction / cos(theta_v), must be 1), G1(v), G1(v | m) in equal-area bins of <v, m> "
      "(grazing .. facing v), G1(v | h) in height bins, and G2 in the mirror configuration (l = reflect(v, m)) "
      "and for a light --theta-l/--phi-l; every estimate with its standard error, beside Smith's predictions "
      "with the analytic NDF and with the surface's own measured NDF. --vndf-rays also traces the VNDF. "
      "--table builds the assemblies and prints the masking table of docs/records/masking-table.md. Exit 0 done, 1 leak test "
      "failed, 2 bad input, 130 interrupted.");
  add_surface_options(sub, *args);
  add_table_options(sub, *args);
  sub->add_option("--shard", args->shard,
                  "single surface: sample only shard K of N of the run (K/N, 1-based: a contiguous range of its blocks "
                  "of 4096 points) and write the partial result to --json, for `microsim merge`");
  on_selected(sub, [args] { return run_selected_mode(*args); });
}};

}  // namespace

}  // namespace microsim::app
