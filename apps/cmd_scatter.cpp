// microsim scatter: what light does on a microsurface, bounce by bounce, histogrammed per order
// (1, 2, 3, 4, 5+) over the hemispheres binning (reflection above, transmission below) and written as a
// scatter EXR (stats/scatter_io.h; with --shard K/N the part as JSON, stats/scatter_merge.h) with a JSON
// summary. Models:
//   --model analytic     the single-scattering BSDF (GGX or Beckmann) binned by cubature: the exact expectation
//                        of order 1, for compare-scattering
//   --model smith-walk   the Smith random walk (Heitz et al. 2016), GGX or Beckmann; --walk-kernel lanes walks
//                        its paths in SIMD lanes (GGX, uniform heights, not Lambertian: other numbers, the
//                        same walk; the kernel is part of the run's measurement, so its shards merge only
//                        with its own)
//   --surface SURF.exr   an explicit heightfield, every bounce traced with Embree
// each one call of measure/scatter.h, as an experiment's scattering quantity measures them.
// The view: --theta in [0, 90) from above, (90, 180] from below (light inside a dielectric), --phi.
//
// Exit codes: 0 done, 2 bad usage or input (nothing written), 130 interrupted (a sampled run writes what it
// measured, marked partial; the analytic model writes nothing).
#include "command.h"
#include "number_options.h"
#include "progress_bar.h"
#include "scatter_report.h"

#include "measure/scatter.h"
#include "microfacet/material.h"
#include "microfacet/roughness.h"
#include "scatter/scatter_setup.h"
#include "surface_input.h"

#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>

namespace microsim::app {
namespace {

// Every option of every model: the models that are not wired yet find theirs here.
struct ScatterArgs {
  std::string surface;        // --surface SURF.exr: an explicit heightfield
  std::string model;          // --model analytic | smith-walk
  std::optional<double> tile_size;  // --tile-size L: an imported heightmap's tile
  std::string ndf = "ggx";    // --ndf ggx | beckmann (the Smith walk's and the analytic model's NDF)
  std::string heights = "uniform";  // --heights uniform | gaussian (the Smith walk's height distribution)
  std::string walk_kernel = "scalar";  // --walk-kernel scalar | lanes (the code that walks the Smith walk's paths)
  std::string alpha;          // --alpha AX[,AY]
  std::string material = "mirror";
  double theta = std::nan("");
  double phi = 0;
  std::uint64_t rays = 1'000'000;
  int max_order = kDefaultMaxOrder;
  int rows = 16;  // per hemisphere
  std::uint64_t seed = 1;
  int threads = 0;
  std::string shard, out, json;
  std::string geometry = to_string(kDefaultHeightfieldGeometry);  // --geometry: the heightfield's tracer (--surface)
  std::set<std::string> given;  // the options given on the command line
};

// --ndf: the NDF of --model analytic and smith-walk.
NdfKind scatter_ndf(const ScatterArgs& a) {
  if (const std::optional<NdfKind> ndf = ndf_kind_from_string(a.ndf)) return *ndf;
  throw UsageError(fmt::format("--ndf {}: unknown (ggx or beckmann)", a.ndf));
}

// wi of --theta (degrees from +z: below 90 light from above, above 90 from below) and --phi.
Vec3<double> scatter_view(double theta, double phi) {
  if (!std::isfinite(theta) || theta < 0 || theta > 180 || theta == 90)
    throw UsageError(fmt::format("--theta {}: the view must be in [0, 90) (from above) or (90, 180] (from below)", theta));
  if (!std::isfinite(phi)) throw UsageError(fmt::format("--phi {}: must be finite", phi));
  const double t = theta * kPi<double> / 180, p = phi * kPi<double> / 180;
  return {std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t)};
}

Material scatter_material(const std::string& text) {
  try {
    return parse_material("--material", text);
  } catch (const std::invalid_argument& e) {  // ParseError, or a constructor's check
    throw UsageError(e.what());
  }
}

// The options every model shares (the sampled models' ScatterOptions; the analytic model uses wi,
// material and rows).
ScatterOptions scatter_options(const ScatterArgs& a, const Material& material) {
  ScatterOptions o;
  o.wi = scatter_view(a.theta, a.phi);
  o.material = material;
  if (o.wi.z() < 0 && !material.transmits())
    throw UsageError(fmt::format("--theta {}: light from below needs a dielectric (--material {} is opaque)", a.theta,
                                 material.describe()));
  o.paths = a.rays;
  o.seed = a.seed;
  o.max_order = a.max_order;
  o.rows = a.rows;
  if (!a.shard.empty()) {
    const BlockPlan plan{o.paths, kPathsPerBlock};
    const ShardSpec s = parse_shard("--shard", a.shard, plan.blocks());  // ParseError: exit 2
    o.blocks = shard_range(plan.blocks(), s.index, s.count);
  }
  try {
    check_scatter_options(o);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  return o;
}

// What the file records of the run for people and for compare-scattering --analytic; an empty ndf or alpha
// (a surface file that records none) is left out.
std::map<std::string, std::string> scatter_notes(const ScatterArgs& a, const std::string& ndf, const std::string& alpha,
                                                 const Material& m) {
  std::map<std::string, std::string> notes{{"model", a.model.empty() ? "surface" : a.model},
                                           {"theta", fmt::format("{}", a.theta)},
                                           {"phi", fmt::format("{}", a.phi)},
                                           {"material", m.describe()}};
  if (!ndf.empty()) notes["ndf"] = ndf;
  if (!alpha.empty()) notes["alpha"] = alpha;
  return notes;
}

std::string alpha_note(double ax, double ay) { return fmt::format("{},{}", ax, ay); }

// --walk-kernel, checked against the walk it is asked for before any work: the lanes kernel walks GGX with
// uniform heights on every material but the Lambertian (scatter/smith_walk.h, smith_walk_lanes_support).
WalkKernel scatter_walk_kernel(const ScatterArgs& a, const SmithMicrosurface& surface, const ScatterOptions& o) {
  WalkKernel kernel = WalkKernel::scalar;
  try {
    kernel = parse_walk_kernel("--walk-kernel", a.walk_kernel);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  if (kernel == WalkKernel::scalar || smith_walk_lanes_support(surface, o)) return kernel;
  std::string unsupported;
  if (surface.ndf != NdfKind::ggx) unsupported = "--ndf " + to_string(surface.ndf);
  else if (surface.heights != HeightDistribution::uniform) unsupported = "--heights " + to_string(surface.heights);
  else unsupported = "--material " + o.material.describe();
  throw UsageError(fmt::format("{}: not supported by --walk-kernel lanes (it walks GGX with uniform heights on a "
                               "mirror, a conductor or a dielectric); --walk-kernel scalar walks every case",
                               unsupported));
}

// Options that the sampled models do not take from the command line because they are not theirs.
void refuse_options(const ScatterArgs& a, std::initializer_list<const char*> options, const std::string& why) {
  for (const char* option : options)
    if (a.given.count(option)) throw UsageError(fmt::format("{} {}", option, why));
}

// --out: the scatter EXR; with --shard, the part (JSON, stats/scatter_merge.h) that `microsim merge` joins.
void check_scatter_outputs(const ScatterArgs& a) {
  const std::string ext = std::filesystem::path(a.out).extension().string();
  if (a.shard.empty() && ext != ".exr") throw UsageError(fmt::format("--out '{}': must be an .exr file", a.out));
  if (!a.shard.empty() && ext != ".json")
    throw UsageError(fmt::format("--out '{}': with --shard {} it is the part for `microsim merge`, a JSON file "
                                 "(--out PART.json)", a.out, a.shard));
  check_output("--out", a.out);
  check_output("--json", a.json);
}

int run_analytic(const ScatterArgs& a) {
  refuse_options(a, {"--walk-kernel"}, "applies to --model smith-walk only");
  refuse_options(a, {"--rays", "--seed", "--max-order", "--shard", "--heights", "--tile-size", "--geometry"},
                 "applies to the sampled models (--model smith-walk, --surface) only: --model analytic is the exact "
                 "single-scattering expectation");
  if (!a.given.count("--alpha")) throw UsageError("--alpha is required for --model analytic");
  const auto [ax, ay] = parse_alpha("--alpha", a.alpha);
  const Material material = scatter_material(a.material);
  const ScatterOptions o = scatter_options(a, material);
  check_scatter_outputs(a);
  install_interrupt_handler();
  const RunControl run = cli_run_control(a.threads, nullptr);
  fmt::print(stderr, "scatter: analytic single scattering, {} alpha ({}, {}), {}, theta {} phi {}, {} rows per hemisphere\n",
             a.ndf, ax, ay, material.describe(), a.theta, a.phi, a.rows);
  ScatterExpectation e;
  try {
    e = measure_analytic_scatter(scatter_ndf(a), {ax, ay}, o.wi, material, o.rows, run);
  } catch (const Cancelled&) {
    return interrupted_nothing_written("scatter", "during the cubature");
  }
  return report_scatter(e, scatter_notes(a, a.ndf, alpha_note(ax, ay), material), {a.out, a.json});
}

int run_walk(const ScatterArgs& a) {
  refuse_options(a, {"--tile-size", "--geometry"}, "applies to --surface only");
  if (!a.given.count("--alpha")) throw UsageError("--alpha is required for --model smith-walk");
  SmithMicrosurface surface;
  const auto [ax, ay] = parse_alpha("--alpha", a.alpha);
  surface.alpha_x = ax;
  surface.alpha_y = ay;
  surface.ndf = scatter_ndf(a);
  const Material material = scatter_material(a.material);
  ScatterOptions o = scatter_options(a, material);
  try {
    surface.heights = parse_height_distribution("--heights", a.heights);
    check_smith_microsurface(surface);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  const WalkKernel kernel = scatter_walk_kernel(a, surface, o);
  check_scatter_outputs(a);
  install_interrupt_handler();
  const auto progress = std::make_shared<CliProgress>(true);
  o.run = cli_run_control(a.threads, progress);
  fmt::print(stderr, "scatter: Smith random walk ({} kernel), {}, {}, theta {} phi {}, {} paths, order cap {}{}\n",
             to_string(kernel), describe(surface), material.describe(), a.theta, a.phi, a.rays, a.max_order,
             a.shard.empty() ? "" : ", shard " + a.shard);
  const ScatterHistogram h = smith_walk_paths(surface, kernel)(o);
  progress->finish();
  std::map<std::string, std::string> notes = scatter_notes(a, a.ndf, alpha_note(ax, ay), material);
  notes["walk_kernel"] = to_string(kernel);
  return report_scatter(h, notes, {a.out, a.json, !a.shard.empty()});
}

// The NDF and roughness a surface file records (assembly metadata), for the notes; "" when it records none.
std::pair<std::string, std::string> surface_ndf_and_alpha(const microgeom::Heightfield& field) {
  const auto get = [&](const char* key) {
    const auto it = field.metadata.find(key);
    return it == field.metadata.end() ? std::string() : it->second;
  };
  const std::string ax = get("alpha_x"), ay = get("alpha_y");
  return {get("reference_ndf"), ax.empty() || ay.empty() ? std::string() : ax + "," + ay};
}

HeightfieldGeometry scatter_geometry(const std::string& text) {
  try {
    return heightfield_geometry_from_string(text);
  } catch (const std::invalid_argument& e) {
    throw UsageError(fmt::format("--geometry: {}", e.what()));
  }
}

int run_surface(const ScatterArgs& a) {
  refuse_options(a, {"--walk-kernel"}, "applies to --model smith-walk only");
  refuse_options(a, {"--alpha", "--ndf", "--heights"},
                 "applies to --model only: a traced surface has its own facets (its file records its assembly)");
  const Material material = scatter_material(a.material);
  ScatterOptions o = scatter_options(a, material);
  check_scatter_outputs(a);
  const microgeom::Heightfield field = load_surface(a.surface, a.tile_size);
  install_interrupt_handler();
  const auto progress = std::make_shared<CliProgress>(true);
  o.run = cli_run_control(a.threads, progress);
  const HeightfieldScene scene(field, scatter_geometry(a.geometry));
  fmt::print(stderr, "scatter: surface {} ({} x {}, tile {}), {}, theta {} phi {}, {} paths, order cap {}{}\n", a.surface,
             field.resolution(), field.resolution(), field.tile_size(), material.describe(), a.theta, a.phi, a.rays,
             a.max_order, a.shard.empty() ? "" : ", shard " + a.shard);
  SurfaceScatterDiagnostics d;
  const ScatterHistogram h = surface_paths(scene, &d)(o);
  progress->finish();
  fmt::print(stderr, "scatter: {} bounces traced, {} convex-edge grazes passed, {} paths lost\n", d.facet_events,
             d.edge_grazes, d.lost());
  const auto [ndf, alpha] = surface_ndf_and_alpha(field);
  std::map<std::string, std::string> notes = scatter_notes(a, ndf, alpha, material);
  notes["surface"] = a.surface;
  for (const char* key : {"assembly", "seed"})
    if (field.metadata.count(key)) notes[std::string("surface_") + key] = field.metadata.at(key);
  return report_scatter(h, notes, {a.out, a.json, !a.shard.empty()});
}

int run_scatter(const ScatterArgs& a) {
  check_distinct_outputs({{"--surface", a.surface}}, {{"--out", a.out}, {"--json", a.json}});
  scatter_ndf(a);  // an unknown --ndf is bad usage whatever the model
  if (!a.surface.empty() && !a.model.empty())
    throw UsageError(fmt::format("--surface and --model {} exclude each other (a surface is traced, a model is not)", a.model));
  if (a.model == "analytic") return run_analytic(a);
  if (a.model == "smith-walk") return run_walk(a);
  if (!a.model.empty())
    throw UsageError(fmt::format("--model {}: unknown model (analytic or smith-walk)", quote_excerpt(a.model)));
  if (!a.surface.empty()) return run_surface(a);
  throw UsageError("scatter needs --model analytic|smith-walk or --surface SURF.exr");
}

CommandRegistration scatter_registration{"scatter", [](CLI::App& app) {
  auto args = std::make_shared<ScatterArgs>();
  auto* sub = app.add_subcommand(
      "scatter",
      "Scatter light arriving along -wi off a microsurface and histogram where it leaves, per bounce order (1, 2, 3, "
      "4, 5+) and in total, over equal-area bins of the upper (reflection) and lower (transmission) hemispheres, with "
      "standard errors. Writes a scatter EXR and a JSON summary. --model analytic: the exact single-scattering "
      "expectation (GGX or Beckmann BSDF binned by cubature); --model smith-walk: the Smith random walk (Heitz et al. 2016); "
      "--surface SURF.exr: every bounce traced on an explicit heightfield. Exit 0 done, 2 bad input (nothing written), 130 "
      "interrupted (what was traced is written, marked partial).");
  sub->add_option("--surface", args->surface, "an explicit heightfield (heightmap EXR) to trace");
  sub->add_option("--model", args->model, "analytic (single-scattering expectation) or smith-walk");
  add_number_option(sub, "--tile-size", args->tile_size, real(), "an imported heightmap's tile size (as trace masking)");
  sub->add_option("--geometry", args->geometry, "--surface: its tracer: pyramid (exact walk over a min-max height "
                  "pyramid), or Embree's triangles or grid (the same hits)")->capture_default_str();
  sub->add_option("--ndf", args->ndf, "ggx or beckmann (--model)")->capture_default_str();
  sub->add_option("--heights", args->heights, "the Smith walk's height distribution: uniform or gaussian (the result "
                  "does not depend on it)")->capture_default_str();
  sub->add_option("--walk-kernel", args->walk_kernel, "--model smith-walk: the code that walks its paths: scalar (one "
                  "path after another, the reference) or lanes (paths in SIMD lanes, several times faster; GGX with "
                  "uniform heights, not Lambertian; the same walk, other random numbers: its shards merge only with "
                  "its own)")->capture_default_str();
  sub->add_option("--alpha", args->alpha, "roughness AX[,AY], each in [1e-4, 10], anisotropy at most 1:1000");
  sub->add_option("--material", args->material,
                  "mirror, conductor:ETA,K[;ETA,K...] (one channel each), dielectric:ETA or lambertian[:ALBEDO]")
      ->capture_default_str();
  add_number_option(sub, "--theta", args->theta, real(),
                    "view polar angle in degrees: [0, 90) from above, (90, 180] from below (inside a dielectric)")
      ->required();
  add_number_option(sub, "--phi", args->phi, real(), "view azimuth in degrees")->default_str("0");
  add_number_option(sub, "--rays", args->rays, whole(1, kMaxRays), at_most("paths to launch", kMaxRays))
      ->default_str(std::to_string(args->rays));
  add_number_option(sub, "--max-order", args->max_order, integer(1, kMaxOrderCap),
                    fmt::format("order cap: facet events per path, 1..{} (the weight left is reported as unfinished)",
                                kMaxOrderCap))
      ->default_str(std::to_string(args->max_order));
  add_number_option(sub, "--rows", args->rows, integer(1, kMaxBinningRows / 2),
                    fmt::format("rows per hemisphere of the equal-area binning, 1..{} (cols = 4 rows)", kMaxBinningRows / 2))
      ->default_str(std::to_string(args->rows));
  add_number_option(sub, "--seed", args->seed, whole(), "random seed (same seed, same histogram, whatever --threads)")
      ->default_str(std::to_string(args->seed));
  add_number_option(sub, "--threads", args->threads, integer(0, kMaxThreads),
                    at_most("worker threads (0: all cores)", kMaxThreads))
      ->default_str(std::to_string(args->threads));
  sub->add_option("--shard", args->shard,
                  "run only shard K of N (K/N, 1-based) and write its part, --out PART.json (exact sums); `microsim "
                  "merge` joins the parts");
  sub->add_option("--out", args->out, "scatter EXR to write")->required();
  sub->add_option("--json", args->json, "also write the JSON summary");
  on_selected(sub, [args, sub] {
    for (const CLI::Option* o : sub->get_options())
      if (o->count() > 0) args->given.insert(o->get_name());
    return run_scatter(*args);
  });
}};

}  // namespace
}  // namespace microsim::app
