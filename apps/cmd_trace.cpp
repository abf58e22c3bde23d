// microsim trace vndf: the exact VNDF oracle. Traces a parallel beam onto the GGX ellipsoid (exact
// quadric, or the mesh of a tessellation level), histograms the first-hit normals in the validator's
// sphere and lobe bins, writes the histogram as an EXR (src/microsim/histogram_io.h) and reports the
// distance to the analytic D_v (total variation and chi-square goodness of fit).
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
#include "trace/trace_vndf.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace microsim::app {
// Defined in cmd_trace_masking.cpp: `trace vndf --surface SURF.exr` (an explicit heightfield).
int run_trace_vndf_heightfield(const std::string& surface, std::optional<double> tile_size, double theta, double phi,
                               long long rays, unsigned long long seed, int threads, int rows, const std::string& out,
                               const std::string& json);
}  // namespace microsim::app

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
  std::string out, json, mesh_out;
  double tile_size = 0;
  bool alpha_given = false, tile_size_given = false, mesh_level_given = false;
};

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
    return microsim::app::run_trace_vndf_heightfield(
        a.surface, a.tile_size_given ? std::optional<double>(a.tile_size) : std::nullopt, a.theta, a.phi, a.rays,
        a.seed, a.threads, a.rows, a.out, a.json);
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
  if (std::filesystem::path(a.out).extension() != ".exr") throw UsageError(fmt::format("--out '{}': must be an .exr file", a.out));
  for (const std::string& path : {a.out, a.json, a.mesh_out}) {
    if (path.empty()) continue;
    try {
      ms::check_writable(path);
    } catch (const ms::HistogramIoError& e) {
      throw UsageError(e.what());
    }
  }

  // ---- trace ---------------------------------------------------------------------------------------------
  const ms::GGX<double> ggx(ax, ay);
  const ms::Vec3<double> wi = ms::direction_from_degrees(a.theta, a.phi);
  ms::install_interrupt_handler();
  const ms::EllipsoidTarget target(ax, ay, a.mesh_level);
  if (!a.mesh_out.empty()) microgeom::write_ellipsoid_mesh(*target.mesh(), a.mesh_out);
  fmt::print(stderr, "trace vndf: ellipsoid alpha ({}, {}), {}, theta {} phi {}, {} rays, seed {}\n", ax, ay,
             target.describe(), a.theta, a.phi, a.rays, a.seed);
  ms::TracedHistogram h;
  h.binnings = {ms::DirectionBinning::sphere(a.rows),
                ms::DirectionBinning::lobe(ggx, wi, ms::SampleDomain::microfacet_normal, a.rows)};
  ms::TraceOptions options;
  options.rays = std::uint64_t(a.rays);
  options.seed = a.seed;
  const auto progress = std::make_shared<ms::CliProgress>(true);
  options.run = ms::cli_run_control(a.threads, progress);
  const ms::TraceResult r = ms::trace_vndf(target, wi, h.binnings, options);
  progress->finish();
  h.counts = r.counts;
  h.rays = r.rays;
  h.hits = r.hits;
  h.partial = r.partial;
  if (r.partial) fmt::print(stderr, "trace vndf: interrupted after {} of {} rays; writing a partial histogram\n", r.rays, a.rays);

  // ---- analyse and write ---------------------------------------------------------------------------------
  const ms::TraceAnalysis analysis = ms::analyse_against_vndf(h, ggx, wi, r.unbinned);
  const ms::ParallelBeam beam(target.ellipsoid(), wi);
  const auto g17 = [](double x) { return fmt::format("{:.17g}", x); };
  h.attributes["surface"] = a.surface;
  h.attributes["target"] = target.describe();
  h.attributes["mesh_level"] = std::to_string(target.mesh_level());
  h.attributes["alpha"] = g17(ax) + "," + g17(ay);
  h.attributes["theta"] = g17(a.theta);
  h.attributes["phi"] = g17(a.phi);
  h.attributes["wi"] = g17(wi.x()) + "," + g17(wi.y()) + "," + g17(wi.z());
  h.attributes["seed"] = std::to_string(a.seed);
  h.attributes["rays_requested"] = std::to_string(a.rays);
  h.attributes["threads"] = std::to_string(a.threads);
  h.attributes["rays_per_second"] = g17(r.rays_per_second());
  ms::write_histogram_exr(a.out, h);

  nlohmann::json j;
  j["surface"] = a.surface;
  j["target"] = target.describe();
  j["mesh_level"] = target.mesh_level();
  j["triangles"] = target.triangle_count();
  j["alpha"] = {ax, ay};
  j["theta"] = a.theta;
  j["phi"] = a.phi;
  j["wi"] = {wi.x(), wi.y(), wi.z()};
  j["rays_requested"] = a.rays;
  j["rays"] = r.rays;
  j["hits"] = r.hits;
  j["hit_fraction"] = r.rays ? double(r.hits) / double(r.rays) : 0.0;
  j["expected_hit_fraction"] = beam.expected_hit_fraction();
  j["seconds"] = r.seconds;
  j["rays_per_second"] = r.rays_per_second();
  j["cpu_seconds"] = r.cpu_seconds;
  j["cpu_ns_per_ray"] = r.cpu_ns_per_ray();
  j["seed"] = a.seed;
  j["threads"] = a.threads;
  j["rows"] = a.rows;
  j["partial"] = r.partial;
  j["output"] = a.out;
  const auto& lobe_fit = analysis.fits.back().binning == "lobe" ? analysis.fits.back() : analysis.fits.front();
  j["total_variation"] = lobe_fit.total_variation;  // lobe bins resolve the lobe at every alpha
  j["noise_floor_tv"] = lobe_fit.noise_floor_tv;
  j["p_value"] = analysis.p_value;
  j["analysis"] = ms::to_json(analysis);
  if (!a.json.empty()) ms::write_text_atomically(a.json, j.dump(2) + "\n");

  // ---- report (stdout) -----------------------------------------------------------------------------------
  fmt::print("trace vndf  ellipsoid alpha ({}, {})  theta {}  phi {}  {}\n", ax, ay, a.theta, a.phi, target.describe());
  fmt::print("rays {}  hits {}  hit fraction {:.6f} (exact ellipsoid: {:.6f})  {:.2f} s  {:.3f} Mrays/s  "
             "{:.1f} CPU ns/ray{}\n",
             r.rays, r.hits, r.rays ? double(r.hits) / double(r.rays) : 0.0, beam.expected_hit_fraction(), r.seconds,
             r.rays_per_second() * 1e-6, r.cpu_ns_per_ray(), r.partial ? "  PARTIAL (interrupted)" : "");
  fmt::print("{:<8} {:>6} {:>12} {:>12} {:>12} {:>6} {:>10}\n", "bins", "cells", "TV", "TV floor", "chi2", "dof", "p");
  for (const ms::TraceFit& f : analysis.fits) {
    fmt::print("{:<8} {:>6} {:>12.6f} {:>12.6f} {:>12.1f} {:>6} {:>10.4g}\n", f.binning, f.chi2.cells, f.total_variation,
               f.noise_floor_tv, f.chi2.statistic, f.chi2.dof, f.chi2.p_value);
  }
  fmt::print("distance to analytic D_v: Sidak-combined p = {:.4g} ({} at level {})\n", analysis.p_value,
             analysis.rejected ? "distinguishable" : "indistinguishable", analysis.significance);
  fmt::print("wrote {}{}\n", a.out, a.json.empty() ? "" : " and " + a.json);
  return r.partial ? microsim::app::kExitInterrupted : microsim::app::kExitOk;
}

microsim::app::CommandRegistration reg{"trace", [](CLI::App& app) {
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
  sub->add_option("--out", args->out, "histogram EXR to write")->required();
  sub->add_option("--json", args->json, "also write a JSON summary");
  sub->add_option("--mesh-out", args->mesh_out, "write the traced mesh (.ply or .obj; needs --mesh-level)");
  microsim::app::on_selected(sub, [args, alpha, tile_size, mesh_level] {
    args->alpha_given = alpha->count() > 0;
    args->tile_size_given = tile_size->count() > 0;
    args->mesh_level_given = mesh_level->count() > 0;
    return run_trace_vndf(*args);
  });
}};

}  // namespace
