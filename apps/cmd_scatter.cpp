// microsim scatter: what light does on a microsurface, bounce by bounce, histogrammed per order
// (1, 2, 3, 4, 5+) over the hemispheres binning (reflection above, transmission below) and written as a
// scatter EXR (stats/scatter_io.h) with a JSON summary. Models:
//   --model analytic     the single-scattering BSDF (GGX or Beckmann) binned by cubature (analytic_scatter.h): the
//                        exact expectation of order 1, for compare-scattering
//   --model smith-walk   the Smith random walk (Heitz et al. 2016)          } options parsed here, to be
//   --surface SURF.exr   an explicit heightfield, traced                    } wired to their measurements
// The view: --theta in [0, 90) from above, (90, 180] from below (light inside a dielectric), --phi.
//
// Exit codes: 0 done, 2 bad usage or input (nothing written), 130 interrupted (a sampled run writes what it
// measured, marked partial; the analytic model writes nothing).
#include "command.h"
#include "number_options.h"
#include "progress_bar.h"
#include "scatter_report.h"

#include "microfacet/material.h"
#include "microfacet/roughness.h"
#include "scatter/analytic_scatter.h"
#include "scatter/scatter_setup.h"

#include <fmt/core.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <string>

namespace microsim::app {
namespace {

// Every option of every model: the models that are not wired yet find theirs here.
struct ScatterArgs {
  std::string surface;        // --surface SURF.exr: an explicit heightfield
  std::string model;          // --model analytic | smith-walk
  std::string ndf = "ggx";    // --ndf ggx | beckmann (the Smith walk's and the analytic model's NDF)
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
  std::set<std::string> given;  // the options given on the command line
};

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
ScatterOptions scatter_options(const ScatterArgs& a, const Material& material, const RunControl& run) {
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
  o.run = run;
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

// What the file records of the run for people and for compare-scattering --analytic.
std::map<std::string, std::string> scatter_notes(const ScatterArgs& a, double ax, double ay, const Material& m) {
  return {{"model", a.model.empty() ? "surface" : a.model},
          {"ndf", a.ndf},
          {"alpha", fmt::format("{},{}", ax, ay)},
          {"theta", fmt::format("{}", a.theta)},
          {"phi", fmt::format("{}", a.phi)},
          {"material", m.describe()}};
}

void check_scatter_outputs(const ScatterArgs& a) {
  if (std::filesystem::path(a.out).extension() != ".exr")
    throw UsageError(fmt::format("--out '{}': must be an .exr file", a.out));
  check_output("--out", a.out);
  check_output("--json", a.json);
}

int run_analytic(const ScatterArgs& a) {
  for (const char* option : {"--rays", "--seed", "--max-order", "--shard", "--surface"})
    if (a.given.count(option))
      throw UsageError(fmt::format("{} applies to the sampled models (--model smith-walk, --surface) only: --model "
                                   "analytic is the exact single-scattering expectation", option));
  if (!a.given.count("--alpha")) throw UsageError("--alpha is required for --model analytic");
  const auto [ax, ay] = parse_alpha("--alpha", a.alpha);
  const Material material = scatter_material(a.material);
  const ScatterOptions o = scatter_options(a, material, {});
  check_scatter_outputs(a);
  install_interrupt_handler();
  const RunControl run = cli_run_control(a.threads, nullptr);
  fmt::print(stderr, "scatter: analytic single scattering, {} alpha ({}, {}), {}, theta {} phi {}, {} rows per hemisphere\n",
             a.ndf, ax, ay, material.describe(), a.theta, a.phi, a.rows);
  ScatterExpectation e;
  try {
    e = a.ndf == "beckmann" ? analytic_single_scattering(Beckmann<double>(ax, ay), o.wi, material, o.rows, run)
                            : analytic_single_scattering(GGX<double>(ax, ay), o.wi, material, o.rows, run);
  } catch (const Cancelled&) {
    return interrupted_nothing_written("scatter", "during the cubature");
  }
  return report_scatter(e, scatter_notes(a, ax, ay, material), {a.out, a.json});
}

int run_scatter(const ScatterArgs& a) {
  check_distinct_outputs({{"--surface", a.surface}}, {{"--out", a.out}, {"--json", a.json}});
  if (a.ndf != "ggx" && a.ndf != "beckmann") throw UsageError(fmt::format("--ndf {}: unknown (ggx or beckmann)", a.ndf));
  if (!a.surface.empty() && !a.model.empty())
    throw UsageError(fmt::format("--surface and --model {} exclude each other (a surface is traced, a model is not)", a.model));
  if (a.model == "analytic") return run_analytic(a);
  if (a.model == "smith-walk")
    throw UsageError("--model smith-walk is not wired into this command yet (scatter/smith_walk.h)");
  if (!a.model.empty())
    throw UsageError(fmt::format("--model {}: unknown model (analytic or smith-walk)", quote_excerpt(a.model)));
  if (!a.surface.empty())
    throw UsageError("--surface is not wired into this command yet (scatter/surface_scatter.h)");
  throw UsageError("scatter needs --model analytic|smith-walk or --surface SURF.exr");
}

CommandRegistration reg{"scatter", [](CLI::App& app) {
  auto args = std::make_shared<ScatterArgs>();
  auto* sub = app.add_subcommand(
      "scatter",
      "Scatter light arriving along -wi off a microsurface and histogram where it leaves, per bounce order (1, 2, 3, "
      "4, 5+) and in total, over equal-area bins of the upper (reflection) and lower (transmission) hemispheres, with "
      "standard errors. Writes a scatter EXR and a JSON summary. --model analytic: the exact single-scattering "
      "expectation (GGX or Beckmann BSDF binned by cubature). Exit 0 done, 2 bad input (nothing written), 130 interrupted.");
  sub->add_option("--surface", args->surface, "an explicit heightfield (heightmap EXR) to trace");
  sub->add_option("--model", args->model, "analytic (single-scattering expectation) or smith-walk");
  sub->add_option("--ndf", args->ndf, "ggx or beckmann")->capture_default_str();
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
  sub->add_option("--shard", args->shard, "run only shard K of N (K/N, 1-based); `microsim merge` joins the parts");
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
