// microsim trace vndf: the exact VNDF oracle. Traces a parallel beam onto the GGX ellipsoid (exact
// quadric, or the mesh of a tessellation level), histograms the first-hit normals in the validator's
// sphere and lobe bins, writes the histogram as an EXR (src/stats/histogram_io.h; with --shard K/N the
// part as JSON, measure/vndf.h) and reports the distance to the analytic D_v (total variation and
// chi-square goodness of fit).
//
// Exit codes: 0 done (the fit is reported, not judged: a coarse mesh is expected to be biased),
// 2 bad usage or input (nothing written), 130 interrupted by Ctrl-C (what was measured is written,
// marked partial).
#include "command.h"
#include "number_options.h"
#include "microfacet/roughness.h"

#include "validate/compare.h"
#include "stats/histogram_io.h"
#include "progress_bar.h"
#include "surface_input.h"
#include "trace/trace_vndf.h"
#include "vndf_report.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>


namespace {

using microsim::app::UsageError;

struct TraceVndfArgs {
  std::string surface = "ellipsoid";
  int mesh_level = -1;
  std::string alpha;
  double theta = std::nan("");
  double phi = 0;
  long long rays = 10'000'000;
  unsigned long long seed = 1;
  int threads = 0;
  int rows = 31;
  std::string out, json, mesh_out, shard;
  std::string geometry = microsim::to_string(microsim::kDefaultHeightfieldGeometry);
  double tile_size = 0;
  bool alpha_given = false, tile_size_given = false, mesh_level_given = false;
};

// The request of a trace vndf run: the view, the run's rays and seed, and its shard (--shard K/N: block
// range K of N of the run's blocks of kRaysPerBlock rays).
microsim::VndfRequest vndf_request(const TraceVndfArgs& a, const std::shared_ptr<microsim::CliProgress>& progress) {
  namespace ms = microsim;
  ms::VndfRequest r;
  r.theta_deg = a.theta;
  r.phi_deg = a.phi;
  r.rays = std::uint64_t(a.rays);
  r.seed = a.seed;
  r.rows = a.rows;
  r.run = ms::cli_run_control(a.threads, progress);
  try {
    r.geometry = ms::heightfield_geometry_from_string(a.geometry);
  } catch (const std::invalid_argument& e) {
    throw UsageError(fmt::format("--geometry: {}", e.what()));
  }
  if (!a.shard.empty()) {
    const ms::BlockPlan plan{r.rays, ms::kRaysPerBlock};
    const ms::ShardSpec s = ms::parse_shard("--shard", a.shard, plan.blocks());  // ParseError: exit 2
    r.blocks = ms::shard_range(plan.blocks(), s.index, s.count);
  }
  return r;
}

// --out: the histogram EXR; with --shard, the part (JSON, measure/vndf.h) that `microsim merge` joins.
void check_out(const TraceVndfArgs& a) {
  const std::string ext = std::filesystem::path(a.out).extension().string();
  if (a.shard.empty() && ext != ".exr") throw UsageError(fmt::format("--out '{}': must be an .exr file", a.out));
  if (!a.shard.empty() && ext != ".json")
    throw UsageError(fmt::format("--out '{}': with --shard {} it is the part for `microsim merge`, a JSON file "
                                 "(--out PART.json)", a.out, a.shard));
  microsim::app::check_output("--out", a.out);
}

void warn_if_partial(const microsim::TraceResult& r, const microsim::VndfRequest& request) {
  if (!r.partial) return;
  const std::uint64_t wanted = microsim::BlockPlan{request.rays, microsim::kRaysPerBlock}.units_in(
      microsim::selected_blocks({request.rays, microsim::kRaysPerBlock}, request.blocks));
  fmt::print(stderr, "trace vndf: interrupted after {} of {} rays; writing a partial histogram (blocks {})\n", r.rays,
             wanted, r.blocks.to_string());
}

// `trace vndf --surface SURF.exr`: the heightfield counterpart of the ellipsoid oracle, same histogram EXR
// and JSON keys (total_variation, noise_floor_tv and p_value refer to the lobe bins and Smith's D_v with
// the surface's analytic reference NDF; the comparison with the surface's own NDF is added).
int run_trace_vndf_heightfield(const TraceVndfArgs& a) {
  namespace ms = microsim;
  namespace app = microsim::app;
  app::check_theta("--theta", a.theta);
  if (!std::isfinite(a.phi)) throw UsageError(fmt::format("--phi {}: must be finite", a.phi));
  check_out(a);
  app::check_output("--json", a.json);
  const microgeom::Heightfield field =
      app::load_surface(a.surface, a.tile_size_given ? std::optional<double>(a.tile_size) : std::nullopt);
  const auto progress = std::make_shared<ms::CliProgress>(true);
  const ms::VndfRequest request = vndf_request(a, progress);
  ms::install_interrupt_handler();
  fmt::print(stderr, "trace vndf: heightfield {} ({} x {}, tile {}), theta {} phi {}, {} rays, seed {}{}\n", a.surface,
             field.resolution(), field.resolution(), field.tile_size(), a.theta, a.phi, a.rays, a.seed,
             a.shard.empty() ? "" : ", shard " + a.shard);
  const ms::HeightfieldVndf m = ms::measure_heightfield_vndf(field, a.surface, request);
  progress->finish();
  warn_if_partial(m.trace, request);
  return app::report_heightfield_vndf(m, field, {a.out, a.json, !a.shard.empty()});
}

int run_trace_vndf(const TraceVndfArgs& a) {
  namespace ms = microsim;
  // ---- validate everything before any work --------------------------------------------------------------
  microsim::app::check_distinct_outputs({{"--surface", a.surface == "ellipsoid" ? "" : a.surface}},
                                        {{"--out", a.out}, {"--json", a.json}, {"--mesh-out", a.mesh_out}});
  const bool heightfield = a.surface.size() > 4 && a.surface.substr(a.surface.size() - 4) == ".exr";
  if (a.surface != "ellipsoid" && !heightfield)
    throw UsageError(fmt::format("--surface '{}': unknown surface (known: ellipsoid, or a heightmap .exr)", a.surface));
  if (heightfield) {
    if (a.alpha_given) throw UsageError("--alpha applies to --surface ellipsoid only (a heightfield has its own roughness)");
    if (a.mesh_level_given || !a.mesh_out.empty()) throw UsageError("--mesh-level/--mesh-out apply to --surface ellipsoid only");
    return run_trace_vndf_heightfield(a);
  }
  if (a.tile_size_given) throw UsageError("--tile-size applies to heightfield surfaces only");
  if (!a.alpha_given) throw UsageError("--alpha is required for --surface ellipsoid");
  const auto [ax, ay] = ms::parse_alpha("--alpha", a.alpha);
  if (!std::isfinite(a.theta) || a.theta < 0 || a.theta >= 90)
    throw UsageError(fmt::format("--theta {}: the view must be in [0, 90) degrees", a.theta));
  if (!std::isfinite(a.phi)) throw UsageError(fmt::format("--phi {}: must be finite", a.phi));
  if (!a.mesh_out.empty() && a.mesh_level < 0) throw UsageError("--mesh-out needs --mesh-level (the quadric has no mesh)");
  if (!a.mesh_out.empty()) {
    std::string ext = std::filesystem::path(a.mesh_out).extension().string();
    for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (ext != ".ply" && ext != ".obj") throw UsageError(fmt::format("--mesh-out '{}': use a .ply or .obj file", a.mesh_out));
  }
  check_out(a);
  microsim::app::check_output("--json", a.json);
  microsim::app::check_output("--mesh-out", a.mesh_out);

  // ---- trace ---------------------------------------------------------------------------------------------
  const auto progress = std::make_shared<ms::CliProgress>(true);
  const ms::VndfRequest request = vndf_request(a, progress);
  ms::install_interrupt_handler();
  const ms::EllipsoidTarget target(ax, ay, a.mesh_level);
  if (!a.mesh_out.empty()) microgeom::write_ellipsoid_mesh(*target.mesh(), a.mesh_out);
  fmt::print(stderr, "trace vndf: ellipsoid alpha ({}, {}), {}, theta {} phi {}, {} rays, seed {}{}\n", ax, ay,
             target.describe(), a.theta, a.phi, a.rays, a.seed, a.shard.empty() ? "" : ", shard " + a.shard);
  const ms::EllipsoidVndf m = ms::measure_ellipsoid_vndf(target, request);
  progress->finish();
  warn_if_partial(m.trace, request);
  return microsim::app::report_ellipsoid_vndf(m, target, {a.out, a.json, !a.shard.empty()});
}

microsim::app::CommandRegistration trace_registration{"trace", [](CLI::App& app) {
  CLI::App* trace = microsim::app::get_or_add_subcommand(app, "trace", "Ray-trace microsurfaces (the exact oracle)");
  auto args = std::make_shared<TraceVndfArgs>();
  auto* sub = trace->add_subcommand(
      "vndf",
      "Trace a parallel beam along -v onto the GGX ellipsoid (Heitz 2018): the first-hit normals with z >= 0 "
      "are distributed exactly as the visible normal distribution D_v. Writes the histogram (sphere and lobe "
      "bins, counts and standard errors) as EXR and reports its distance to the analytic D_v. Exit 0 done, "
      "2 bad input, 130 interrupted (partial histogram written).");
  sub->add_option("--surface", args->surface,
                  "surface to trace: ellipsoid (the exact oracle), or a heightmap EXR (microsim surface build)")
      ->capture_default_str();
  namespace ma = microsim::app;
  auto* mesh_level = ma::add_number_option(
      sub, "--mesh-level", args->mesh_level, ma::integer(0, microgeom::kMaxEllipsoidMeshLevel),
      fmt::format("trace the ellipsoid meshed at this tessellation level (0..{}) instead of the exact quadric",
                  microgeom::kMaxEllipsoidMeshLevel));
  auto* alpha = sub->add_option(
      "--alpha", args->alpha,
      "GGX roughness AX[,AY] of the ellipsoid (required for it), each in [1e-4, 10], anisotropy at most 1:1000");
  auto* tile_size = ma::add_number_option(sub, "--tile-size", args->tile_size, ma::real(),
                                           "heightfield only: tile size (default: from the file)");
  auto* geometry = sub->add_option("--geometry", args->geometry,
                                   "heightfield only: its tracer: pyramid (exact walk over a min-max height pyramid), or "
                                   "Embree's triangles or grid (the same hits)")
                       ->capture_default_str();
  ma::add_number_option(sub, "--theta", args->theta, ma::real(), "view polar angle in degrees, [0, 90)")->required();
  ma::add_number_option(sub, "--phi", args->phi, ma::real(), "view azimuth in degrees")->default_str("0");
  ma::add_number_option(sub, "--rays", args->rays, ma::whole(1, microsim::kMaxRays),
                         ma::at_most("rays to trace", microsim::kMaxRays))
      ->default_str(std::to_string(args->rays));
  ma::add_number_option(sub, "--seed", args->seed, ma::whole(),
                         "random seed (same seed, same histogram, whatever --threads)")
      ->default_str(std::to_string(args->seed));
  ma::add_number_option(sub, "--threads", args->threads, ma::integer(0, microsim::kMaxThreads),
                         ma::at_most("worker threads (0: all cores)", microsim::kMaxThreads))
      ->default_str(std::to_string(args->threads));
  ma::add_number_option(sub, "--rows", args->rows, ma::binning_rows(1),
                         fmt::format("rows of the sphere and lobe binnings (odd, 1..{}; cols = 2 rows)",
                                     microsim::kMaxBinningRows))
      ->default_str(std::to_string(args->rows));
  sub->add_option("--out", args->out, "histogram EXR to write (with --shard: the part, PART.json)")->required();
  sub->add_option("--json", args->json, "also write a JSON summary");
  sub->add_option("--mesh-out", args->mesh_out, "write the traced mesh (.ply or .obj; needs --mesh-level)");
  sub->add_option("--shard", args->shard,
                  "trace only shard K of N of the run (K/N, 1-based: a contiguous range of its blocks of 4096 rays); "
                  "--out PART.json is the part (its range, exact counts), and `microsim merge` joins the N parts into "
                  "the whole run, bit for bit");
  microsim::app::on_selected(sub, [args, alpha, tile_size, mesh_level, geometry] {
    if (geometry->count() > 0 && args->surface == "ellipsoid")
      throw UsageError("--geometry applies to heightfield surfaces only");
    args->alpha_given = alpha->count() > 0;
    args->tile_size_given = tile_size->count() > 0;
    args->mesh_level_given = mesh_level->count() > 0;
    return run_trace_vndf(*args);
  });
}};

}  // namespace
