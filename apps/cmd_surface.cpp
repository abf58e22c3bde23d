// microsim surface build | stats | import: periodic heightfield microsurfaces (microgeom/assembly.h).
//
//   surface build  --assembly NAME --alpha AX[,AY] --res N [--seed S] [--corr-cells C] [--tile-size L]
//                  [--iterations K] [--ndf-match radial|joint] --out SURF.exr [--mesh F.ply|obj] [--mesh-crop C]
//                  [--normals F.exr]
//                  [--json PATH]
//   surface stats  SURF.exr [--tile-size L] [--alpha AX[,AY]] [--reference ggx|beckmann] [--corr-cells C]
//                  [--check] [--json PATH] [--mesh F] [--mesh-crop C] [--normals F]
//   surface import EXTERNAL.exr --tile-size L --out SURF.exr
//
// Tables on stdout, progress and diagnostics on stderr. A built surface whose measured NDF misses the
// stated tolerance (microgeom/surface_stats.h) is an error: exit 2 and nothing written. Every output is
// staged to a temporary file in its directory and renamed only once all outputs are complete.
#include "command.h"
#include "number_options.h"
#include "microfacet/roughness.h"

#include "microgeom/assembly.h"
#include "core/atomic_file.h"
#include "core/cpu_time.h"
#include "microgeom/heightfield.h"
#include "microgeom/mesh_io.h"
#include "microgeom/surface_stats.h"
#include "progress_bar.h"
#include "surface_input.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <new>
#include <optional>

#include <unistd.h>

namespace fs = std::filesystem;
using microsim::app::UsageError;

namespace {

// ---- staged outputs: write everything to temporaries, rename all at the end ---------------------------
class StagedOutputs {
public:
  // A new temporary next to `path` with the same extension (core/atomic_file.h); writer(tmp) writes it.
  void stage(const fs::path& path, const std::function<void(const fs::path&)>& writer) {
    staged_.emplace_back(path);
    writer(staged_.back().path());
  }
  // Renames every staged file into place; the destructor removes the temporaries of an unfinished stage.
  void commit() {
    for (auto& tmp : staged_) tmp.commit();
    staged_.clear();
  }

private:
  std::vector<microsim::TemporaryFile> staged_;
};

void write_json_file(const fs::path& path, const nlohmann::json& j) {
  std::ofstream out(path, std::ios::trunc);
  if (!out) throw std::runtime_error(fmt::format("cannot write JSON '{}'", path.string()));
  out << j.dump(2) << '\n';
  out.close();
  if (!out) throw std::runtime_error(fmt::format("write error on JSON '{}'", path.string()));
}

// The optional outputs derived from a heightfield (--normals, --mesh with --mesh-crop), staged.
void stage_derived_outputs(StagedOutputs& outputs, const microgeom::Heightfield& field, const std::string& normals,
                           const std::string& mesh, int mesh_crop) {
  if (!normals.empty())
    outputs.stage(normals, [&](const fs::path& tmp) { microgeom::save_normal_map_exr(tmp, field); });
  if (!mesh.empty())
    outputs.stage(mesh, [&](const fs::path& tmp) { microgeom::write_heightfield_mesh(tmp, field, mesh_crop); });
}

void stage_json(StagedOutputs& outputs, const std::string& path, const nlohmann::json& j) {
  if (!path.empty()) outputs.stage(path, [&](const fs::path& tmp) { write_json_file(tmp, j); });
}

using microsim::app::interrupted_nothing_written;

// ---- option parsing -----------------------------------------------------------------------------------
// "AX" or "AX,AY" in the supported range (src/core/parse.h); the assembly's own range is checked after.
std::pair<double, double> surface_alpha(const std::string& text) {
  try {
    return microsim::parse_alpha("--alpha", text);
  } catch (const microsim::ParseError& e) {
    throw UsageError(e.what());
  }
}

// --mesh: a writable path with a mesh format's extension ("" is no mesh).
void check_mesh_output(const std::string& path) {
  if (path.empty()) return;
  microsim::app::check_output("--mesh", path);
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (ext != ".ply" && ext != ".obj" && ext != ".off" && ext != ".stl")
    throw UsageError(fmt::format("--mesh '{}': unknown mesh format '{}' (use .ply or .obj)", path, ext));
}

void check_mesh_crop(int mesh_crop, int resolution) {
  if (mesh_crop < 0 || mesh_crop > resolution)
    throw UsageError(fmt::format("--mesh-crop {} must be in [1, {}] (0 = whole tile)", mesh_crop, resolution));
}

double peak_rss_bytes() { return microsim::app::peak_rss_mib() * 1024.0 * 1024.0; }

// Wall and CPU time since its construction.
struct Stopwatch {
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  double cpu_start = microsim::process_cpu_seconds();
  double wall() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); }
  double cpu() const { return microsim::process_cpu_seconds() - cpu_start; }
};

// ---- reports ------------------------------------------------------------------------------------------
// The measured NDF against the reference: slope-radius quantiles and bins.
void print_ndf(const microgeom::SurfaceStats& st) {
  fmt::print("\nslope-radius quantiles (normalised slopes |(sx/ax, sy/ay)|) against the reference:\n");
  fmt::print("| {:>7} | {:>12} | {:>12} | {:>9} |\n", "q", "measured", "reference", "rel.err");
  fmt::print("|{:-<9}|{:-<14}|{:-<14}|{:-<11}|\n", "", "", "", "");
  for (const auto& q : st.quantiles)
    fmt::print("| {:>7} | {:>12.6g} | {:>12.6g} | {:>+8.3f}% |{}\n", q.q, q.measured, q.expected, 100 * q.rel_error,
               q.q > 0.999 + 1e-12 ? " (not checked)" : "");
  fmt::print("\nradius bins ({} of equal reference probability), relative error in %:\n", st.radius_bins.size());
  for (std::size_t b = 0; b < st.radius_bins.size(); ++b)
    fmt::print("{:+6.2f}{}", 100 * st.radius_bins[b].rel_error, (b + 1) % 10 == 0 ? "\n" : " ");
  fmt::print("(radius, angle) bins ({} rings x {} sectors), relative error in %:\n", microgeom::kRingBins,
             microgeom::kAngleBins);
  for (int b = 0; b < microgeom::kAngularBins; ++b)
    fmt::print("{:+6.2f}{}", 100 * st.angular_bin_errors[b], (b + 1) % microgeom::kAngleBins == 0 ? "\n" : " ");
}

// The NDF error in the lobe bins of trace vndf, beside the noise of as many independent triangles: a traced
// VNDF at theta = 0 resolves it from about `resolving_rays` rays on.
void print_lobe_error(const microgeom::LobeNdfError& e) {
  fmt::print("\nNDF in the lobe bins of trace vndf ({} rows, {} bins, seen from the normal):\n", e.rows, e.bins);
  fmt::print("| total variation | noise of {} independent triangles | max bin error | resolved from about |\n"
             "|---|---|---|---|\n", e.triangles);
  fmt::print("| {:.5f} | {:.5f} | {:.2f}% | {:.3g} rays |\n", e.total_variation, e.iid_noise_tv,
             100 * e.max_rel_error, e.resolving_rays);
}

// The NDF check: the largest errors against their tolerances.
void print_ndf_check(const microgeom::SurfaceStats& st) {
  fmt::print("\n| NDF check                | max error | tolerance |\n|{:-<26}|{:-<11}|{:-<11}|\n", "", "", "");
  fmt::print("| quantiles q<=0.999       | {:>8.3f}% | {:>8.3f}% |\n", 100 * st.max_quantile_error,
             100 * st.tolerance.quantile);
  fmt::print("| radius bins              | {:>8.3f}% | {:>8.3f}% |\n", 100 * st.max_radius_bin_error,
             100 * st.tolerance.radius_bin);
  fmt::print("| (radius, angle) bins     | {:>8.3f}% | {:>8.3f}% |\n", 100 * st.max_angular_bin_error,
             100 * st.tolerance.angular_bin);
  fmt::print("NDF verdict: {}\n", st.ndf_verdict);
  print_lobe_error(st.lobe);
}

// Slopes, heights and their coupling.
void print_moments(const microgeom::SurfaceStats& st) {
  fmt::print("\nslopes: mean ({:.3g}, {:.3g}); rms ({:.6g}, {:.6g}); normalised second moment per axis ({:.4g}, {:.4g})"
             "; max normalised radius {:.6g}\n",
             st.mean_slope_x, st.mean_slope_y, st.rms_slope_x, st.rms_slope_y, st.normalised_second_moment_x,
             st.normalised_second_moment_y, st.max_normalised_radius);
  fmt::print("heights: mean {:.4g}, sd {:.6g}, range [{:.6g}, {:.6g}] (= {:.4g} tiles), skewness {:.4g}, excess "
             "kurtosis {:.4g}\n",
             st.height_mean, st.height_sd, st.height_min, st.height_max, (st.height_max - st.height_min) / st.tile_size,
             st.height_skewness, st.height_excess_kurtosis);
  fmt::print("height-slope coupling: Spearman(height, slope radius) {:+.4f}; Spearman(|height - median|, slope "
             "radius) {:+.4f}; mean height of the steepest 1% / 0.1% of facets: {:+.3f} / {:+.3f} sd\n",
             st.spearman_height_slope, st.spearman_extremity_slope, st.steepest_1pct_height_z,
             st.steepest_01pct_height_z);
}

void print_stats(const microgeom::SurfaceStats& st, const microgeom::Heightfield& field) {
  using microgeom::to_string;
  fmt::print("surface: {} x {} vertices, tile {:.6g}, cell {:.6g}, {} triangles\n", field.resolution(),
             field.resolution(), st.tile_size, st.cell_size, st.triangles);
  fmt::print("NDF reference: {} with alpha = ({:.6g}, {:.6g}){}; fitted from median |slope|: ({:.6g}, {:.6g})\n",
             to_string(st.reference), st.alpha_x, st.alpha_y, st.alpha_fitted ? " (fitted)" : "",
             st.fitted_alpha_x, st.fitted_alpha_y);
  print_ndf(st);
  print_ndf_check(st);
  print_moments(st);
}

nlohmann::json stats_json(const microgeom::SurfaceStats& st) {
  nlohmann::json j;
  j["triangles"] = st.triangles;
  j["reference"] = to_string(st.reference);
  j["alpha"] = {st.alpha_x, st.alpha_y};
  j["alpha_fitted"] = st.alpha_fitted;
  j["fitted_alpha"] = {st.fitted_alpha_x, st.fitted_alpha_y};
  for (const auto& q : st.quantiles)
    j["quantiles"].push_back({{"q", q.q}, {"measured", q.measured}, {"expected", q.expected}, {"rel_error", q.rel_error}});
  for (const auto& b : st.radius_bins)
    j["radius_bins"].push_back({{"lo", b.lo},
                                {"hi", std::isfinite(b.hi) ? nlohmann::json(b.hi) : nlohmann::json("inf")},
                                {"expected_fraction", b.expected_fraction},
                                {"measured_fraction", b.measured_fraction},
                                {"rel_error", b.rel_error}});
  j["angular_bins"] = {{"rings", microgeom::kRingBins},
                       {"sectors", microgeom::kAngleBins},
                       {"rel_errors", std::vector<double>(st.angular_bin_errors.begin(), st.angular_bin_errors.end())}};
  j["max_quantile_error"] = st.max_quantile_error;
  j["max_radius_bin_error"] = st.max_radius_bin_error;
  j["max_angular_bin_error"] = st.max_angular_bin_error;
  j["tolerance"] = {{"quantile", st.tolerance.quantile},
                    {"radius_bin", st.tolerance.radius_bin},
                    {"angular_bin", st.tolerance.angular_bin}};
  j["ndf_within_tolerance"] = st.ndf_within_tolerance;
  j["ndf_verdict"] = st.ndf_verdict;
  j["lobe_bins"] = {{"rows", st.lobe.rows},
                    {"bins", st.lobe.bins},
                    {"total_variation", st.lobe.total_variation},
                    {"iid_noise_tv", st.lobe.iid_noise_tv},
                    {"max_rel_error", st.lobe.max_rel_error},
                    {"resolving_rays", st.lobe.resolving_rays}};
  j["slopes"] = {{"mean", {st.mean_slope_x, st.mean_slope_y}},
                 {"rms", {st.rms_slope_x, st.rms_slope_y}},
                 {"normalised_second_moment", {st.normalised_second_moment_x, st.normalised_second_moment_y}},
                 {"max_normalised_radius", st.max_normalised_radius}};
  j["heights"] = {{"mean", st.height_mean}, {"sd", st.height_sd},         {"min", st.height_min},
                  {"max", st.height_max},   {"skewness", st.height_skewness}, {"excess_kurtosis", st.height_excess_kurtosis}};
  j["tile_size"] = st.tile_size;
  j["cell_size"] = st.cell_size;
  j["coupling"] = {{"spearman_height_slope", st.spearman_height_slope},
                   {"spearman_extremity_slope", st.spearman_extremity_slope},
                   {"steepest_1pct_height_z", st.steepest_1pct_height_z},
                   {"steepest_01pct_height_z", st.steepest_01pct_height_z}};
  return j;
}

std::string assembly_help() {
  std::string s;
  for (const auto& a : microgeom::assembly_registry())
    s += fmt::format("\n  {:<9} {} (NDF: {})", a.name, a.summary, to_string(a.reference));
  return s;
}
// "smith, ..., beckmann": the assemblies' names, for an option's help line.
std::string assembly_names() {
  std::string s;
  for (const auto& a : microgeom::assembly_registry()) s += (s.empty() ? "" : ", ") + a.name;
  return s;
}
// ---- surface build ------------------------------------------------------------------------------------
struct BuildOptions {
  std::string assembly, alpha, out, mesh, normals, json, ndf_match = "radial";
  int resolution = 0, mesh_crop = 0, iterations = 0;
  std::uint64_t seed = 1;
  double corr_cells = 0, tile_size = 1.0;
  bool quiet = false;
  bool unsupported = false;  // build even outside microgeom::check_supported_range
};

// What the build and its statistics cost.
struct BuildCost {
  double build_seconds = 0, build_cpu = 0, build_rss = 0;  // the build (peak RSS so far: the build itself)
  double stats_seconds = 0, stats_cpu = 0, rss = 0;         // the statistics, and the peak RSS of both
};

microgeom::AssemblyParams assembly_params(const BuildOptions& o) {
  microgeom::AssemblyParams p;
  p.assembly = o.assembly;
  std::tie(p.alpha_x, p.alpha_y) = surface_alpha(o.alpha);
  p.resolution = o.resolution;
  p.seed = o.seed;
  p.corr_cells = o.corr_cells;
  p.tile_size = o.tile_size;
  p.iterations = o.iterations;
  const auto match = microgeom::ndf_match_from_string(o.ndf_match);
  if (!match) throw UsageError(fmt::format("--ndf-match '{}' must be radial or joint", o.ndf_match));
  p.ndf_match = *match;
  try {
    microgeom::validate(p);
    if (!o.unsupported) microgeom::check_supported_range(p);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  return p;
}

// The build's parameters, every option checked before any work (UsageError).
microgeom::AssemblyParams check_build(const BuildOptions& o) {
  microsim::app::check_distinct_outputs(
      {}, {{"--out", o.out}, {"--normals", o.normals}, {"--mesh", o.mesh}, {"--json", o.json}});
  const microgeom::AssemblyParams p = assembly_params(o);
  microsim::app::check_output("--out", o.out);
  check_mesh_output(o.mesh);
  check_mesh_crop(o.mesh_crop, o.resolution);
  microsim::app::check_output("--normals", o.normals);
  microsim::app::check_output("--json", o.json);
  return p;
}

// The correlation length in cells (the assembly's default when not given); a note when the tile is narrow.
double corr_length(const microgeom::AssemblyParams& p, bool quiet) {
  const double l = p.corr_cells == 0 ? microgeom::default_corr_cells(p.resolution) : p.corr_cells;
  if (p.resolution / l < 64 && !quiet)
    fmt::print(stderr, "surface build: note: the tile is only {:.3g} correlation lengths wide (64-128 advised for "
                       "masking statistics)\n", p.resolution / l);
  return l;
}

// The surface, with a progress bar on stderr unless quiet; nothing when Ctrl-C stopped the build.
std::optional<microgeom::Heightfield> build_with_progress(const microgeom::AssemblyParams& p, bool quiet,
                                                          microgeom::BuildReport& report) {
  microsim::ProgressBar bar(fmt::format("surface build {} {}^2", p.assembly, p.resolution), 1000, !quiet);
  std::uint64_t shown = 0;
  const auto progress = [&](std::string_view, double fraction) {
    const auto target = std::uint64_t(std::clamp(fraction, 0.0, 1.0) * 1000);
    if (target > shown) {
      bar.add(target - shown);
      shown = target;
    }
  };
  try {
    return microgeom::build_assembly(p, &report, progress, [] { return microsim::interrupted(); });
  } catch (const microgeom::BuildCancelled&) {
    return std::nullopt;
  }
}

// The NDF check of a built surface: its assembly's reference and roughness, the tolerance for its size.
microgeom::StatsOptions build_stats_options(const microgeom::AssemblyParams& p, double l) {
  const microgeom::AssemblyInfo* info = microgeom::find_assembly(p.assembly);
  microgeom::StatsOptions so;
  so.reference = info->reference;
  so.alpha_x = p.alpha_x;
  so.alpha_y = p.alpha_y;
  so.tolerance = microgeom::tolerance_for(info->reference, p.resolution, l);
  return so;
}

void print_build(const microgeom::AssemblyParams& p, double l, const microgeom::BuildReport& report) {
  fmt::print("surface build: assembly {}, alpha ({:.6g}, {:.6g}), resolution {}, seed {}, correlation length {:.6g} "
             "cells ({:.4g} per tile), {} slope-matching iterations, NDF matched {}\n",
             p.assembly, p.alpha_x, p.alpha_y, p.resolution, p.seed, l, p.resolution / l, report.iterations,
             microgeom::to_string(p.ndf_match));
  for (const auto& note : report.notes) fmt::print("  {}\n", note);
  if (!report.residuals.empty()) {
    fmt::print("slope-matching residual per iteration:");
    for (double r : report.residuals) fmt::print(" {:.2e}", r);
    fmt::print("\n");
  }
}

void print_cost(const BuildCost& c, const microgeom::Heightfield& field) {
  fmt::print("\nbuild {:.3f} s wall, {:.3f} s CPU (peak RSS {:.1f} MiB, {:.1f} bytes per texel); statistics {:.3f} s "
             "wall, {:.3f} s CPU (peak RSS {:.1f} MiB)\n",
             c.build_seconds, c.build_cpu, c.build_rss / (1024.0 * 1024.0), c.build_rss / double(field.texel_count()),
             c.stats_seconds, c.stats_cpu, c.rss / (1024.0 * 1024.0));
}

nlohmann::json build_json(const BuildOptions& o, const microgeom::AssemblyParams& p, double l,
                          const microgeom::BuildReport& report, const BuildCost& c, const microgeom::SurfaceStats& st) {
  nlohmann::json j;
  j["command"] = "surface build";
  j["assembly"] = p.assembly;
  j["alpha"] = {p.alpha_x, p.alpha_y};
  j["resolution"] = p.resolution;
  j["seed"] = p.seed;
  j["corr_cells"] = l;
  j["tile_size"] = p.tile_size;
  j["iterations"] = report.iterations;
  j["ndf_match"] = std::string(microgeom::to_string(p.ndf_match));
  j["refinement"] = {{"sweeps", report.refine_sweeps},
                     {"moves", report.refine_moves},
                     {"objective_before", report.refine_objective_before},
                     {"objective_after", report.refine_objective_after}};
  j["residuals"] = report.residuals;
  j["notes"] = report.notes;
  j["build_seconds"] = c.build_seconds;
  j["stats_seconds"] = c.stats_seconds;
  j["build_cpu_seconds"] = c.build_cpu;
  j["stats_cpu_seconds"] = c.stats_cpu;
  j["peak_rss_bytes_build"] = c.build_rss;
  j["peak_rss_bytes"] = c.rss;
  j["stats"] = stats_json(st);
  j["outputs"] = {{"heightmap", o.out}, {"normals", o.normals}, {"mesh", o.mesh}};
  return j;
}

// Every output of the build, all or nothing.
void write_build_outputs(const BuildOptions& o, const microgeom::Heightfield& field, const nlohmann::json& j) {
  StagedOutputs outputs;
  outputs.stage(o.out, [&](const fs::path& tmp) { microgeom::save_heightmap_exr(tmp, field); });
  stage_derived_outputs(outputs, field, o.normals, o.mesh, o.mesh_crop);
  stage_json(outputs, o.json, j);
  outputs.commit();
}

int run_build(const BuildOptions& o) {
  const microgeom::AssemblyParams p = check_build(o);
  const double l = corr_length(p, o.quiet);
  microsim::install_interrupt_handler();
  BuildCost cost;
  const Stopwatch build_clock;
  microgeom::BuildReport report;
  const std::optional<microgeom::Heightfield> field = build_with_progress(p, o.quiet, report);
  if (!field) return interrupted_nothing_written("surface build");
  cost.build_seconds = build_clock.wall();
  cost.build_rss = peak_rss_bytes();
  cost.build_cpu = build_clock.cpu();

  const Stopwatch stats_clock;
  const microgeom::StatsOptions so = build_stats_options(p, l);
  const microgeom::SurfaceStats st = microgeom::measure_surface(*field, so);
  if (microsim::interrupted()) return interrupted_nothing_written("surface build");
  cost.stats_seconds = stats_clock.wall();
  cost.stats_cpu = stats_clock.cpu();

  print_build(p, l, report);
  print_stats(st, *field);
  cost.rss = peak_rss_bytes();
  print_cost(cost, *field);
  if (!st.ndf_within_tolerance)
    throw UsageError(fmt::format("the {} surface misses its {} NDF: {} (nothing written)", p.assembly,
                                 to_string(so.reference), st.ndf_verdict));
  write_build_outputs(o, *field, build_json(o, p, l, report, cost, st));
  if (!o.quiet) fmt::print(stderr, "surface build: wrote {}\n", o.out);
  return microsim::app::kExitOk;
}

// ---- surface stats ------------------------------------------------------------------------------------
struct StatsCliOptions {
  std::string path, alpha, reference, json, mesh, normals;
  bool alpha_given = false;  // --alpha '' is an empty number, not "no --alpha"
  double tile_size = 0, corr_cells = 0;
  int mesh_crop = 0;
  bool check = false;
};

// A number the file's metadata states; absent is nullopt, present but malformed is bad input (exit 2).
std::optional<double> metadata_number(const microgeom::Heightfield& f, const std::string& key) {
  auto it = f.metadata.find(key);
  if (it == f.metadata.end()) return {};
  const std::optional<double> v = microsim::try_parse_double(it->second);
  if (!v)
    throw UsageError(fmt::format("the heightmap's attribute microsim.{} = {} is not a finite number", key,
                                 microsim::quote_excerpt(it->second)));
  return v;
}

// Reference: the option, else the file's, else GGX.
microsim::NdfKind reference_ndf(const StatsCliOptions& o, const microgeom::Heightfield& field) {
  std::string ref = o.reference;
  if (ref.empty()) {
    auto it = field.metadata.find("reference_ndf");
    ref = it != field.metadata.end() ? it->second : "ggx";
  }
  if (const auto ndf = microsim::ndf_kind_from_string(ref)) return *ndf;
  throw UsageError(fmt::format("--reference '{}' must be ggx or beckmann", ref));
}

// Alpha: the option, else the file's, else fitted (left unset).
void set_alpha(microgeom::StatsOptions& so, const StatsCliOptions& o, const microgeom::Heightfield& field) {
  if (o.alpha_given) {
    std::tie(so.alpha_x, so.alpha_y) = surface_alpha(o.alpha);
  } else if (auto ax = metadata_number(field, "alpha_x"), ay = metadata_number(field, "alpha_y");
             ax && ay && *ax > 0 && *ay > 0) {
    so.alpha_x = *ax;
    so.alpha_y = *ay;
  }
}

// The correlation length for the tolerance: the option, else the file's, else 0 (none known).
double stats_corr_length(const StatsCliOptions& o, const microgeom::Heightfield& field) {
  if (o.corr_cells < 0) throw UsageError(fmt::format("--corr-cells {} must be > 0", o.corr_cells));
  return o.corr_cells != 0 ? o.corr_cells : metadata_number(field, "corr_cells").value_or(0.0);
}

void check_stats_outputs(const StatsCliOptions& o) {
  microsim::app::check_distinct_outputs({{"heightmap", o.path}},
                                        {{"--json", o.json}, {"--mesh", o.mesh}, {"--normals", o.normals}});
  microsim::app::check_output("--json", o.json);
  check_mesh_output(o.mesh);
  microsim::app::check_output("--normals", o.normals);
}

// --tile-size for a heightmap: 0 is "not given" (the file's own).
std::optional<double> tile_size_option(double tile_size) {
  return tile_size != 0 ? std::optional<double>(tile_size) : std::nullopt;
}

void print_stats_header(const StatsCliOptions& o, const microgeom::Heightfield& field, double l) {
  fmt::print("surface stats: {}", o.path);
  if (auto it = field.metadata.find("assembly"); it != field.metadata.end()) fmt::print(" (assembly {})", it->second);
  fmt::print("{}\n", l > 0 ? fmt::format(", tolerance for {:.4g} correlation lengths per tile", field.resolution() / l)
                           : ", fixed tolerance (no correlation length known)");
}

nlohmann::json stats_report_json(const StatsCliOptions& o, const microgeom::Heightfield& field,
                                 const microgeom::SurfaceStats& st) {
  nlohmann::json j;
  j["command"] = "surface stats";
  j["path"] = o.path;
  j["resolution"] = field.resolution();
  j["metadata"] = field.metadata;
  j["stats"] = stats_json(st);
  return j;
}

int run_stats(const StatsCliOptions& o) {
  check_stats_outputs(o);
  microsim::install_interrupt_handler();
  const microgeom::Heightfield field = microsim::app::load_surface(o.path, tile_size_option(o.tile_size), "heightmap");
  check_mesh_crop(o.mesh_crop, field.resolution());
  microgeom::StatsOptions so;
  so.reference = reference_ndf(o, field);
  set_alpha(so, o, field);
  // Tolerance: scaled by the correlation length when one is known, else the fixed bounds.
  const double l = stats_corr_length(o, field);
  so.tolerance = l > 0 ? microgeom::tolerance_for(so.reference, field.resolution(), l) : microgeom::NdfTolerance{};

  const microgeom::SurfaceStats st = microgeom::measure_surface(field, so);
  if (microsim::interrupted()) return interrupted_nothing_written("surface stats");
  print_stats_header(o, field, l);
  print_stats(st, field);

  StagedOutputs outputs;
  stage_derived_outputs(outputs, field, o.normals, o.mesh, o.mesh_crop);
  stage_json(outputs, o.json, stats_report_json(o, field, st));
  outputs.commit();
  if (o.check && !st.ndf_within_tolerance) return microsim::app::kExitRejected;
  return microsim::app::kExitOk;
}

// ---- surface import -----------------------------------------------------------------------------------
struct ImportOptions {
  std::string path, out;
  double tile_size = 0;
};

int run_import(const ImportOptions& o) {
  microsim::app::check_distinct_outputs({{"heightmap", o.path}}, {{"--out", o.out}});
  if (!(o.tile_size > 0)) throw UsageError(fmt::format("--tile-size {} must be > 0", o.tile_size));
  microsim::app::check_output("--out", o.out);
  microsim::install_interrupt_handler();
  microgeom::Heightfield field = microsim::app::load_surface(o.path, o.tile_size, "heightmap");
  if (microsim::interrupted()) return interrupted_nothing_written("surface import");
  field.metadata["assembly"] = "imported";
  field.metadata["source"] = fs::absolute(o.path).string();
  StagedOutputs outputs;
  outputs.stage(o.out, [&](const fs::path& tmp) { microgeom::save_heightmap_exr(tmp, field); });
  outputs.commit();
  fmt::print("surface import: {} ({} x {}, tile size {:.6g}, heights [{:.6g}, {:.6g}]) -> {}\n", o.path,
             field.resolution(), field.resolution(), field.tile_size(), field.min_height(), field.max_height(), o.out);
  return microsim::app::kExitOk;
}

// ---- the subcommands ----------------------------------------------------------------------------------
namespace ma = microsim::app;
using ma::add_number_option;

void add_build_command(CLI::App* group) {
  auto b = std::make_shared<BuildOptions>();
  auto* build = group->add_subcommand(
      "build",
      "Build a periodic heightfield with a prescribed NDF, check its measured NDF against the analytic one "
      "(an error if it misses the stated tolerance) and write it as an EXR heightmap.");
  build->footer("Assemblies (all reproducible from --seed, isotropic or anisotropic):" + assembly_help() +
                "\nAnisotropy stretches the spectra: the surface is the affine image of an isotropic one."
                "\nSupported range (where a build meets its NDF check; docs/reference/surfaces.md): N >= 256 for the GGX "
                "assemblies (beckmann: N >= 16), max/min alpha <= 4, --corr-cells in [min(8, max(N >= 256 ? 4 : 2, "
                "N/128)), N/16] (beckmann: up to N/8); outside it the build is refused (exit 2) unless --unsupported.");
  build->add_option("--assembly", b->assembly,
                    "assembly name: " + assembly_names() + " (described under \"Assemblies\" below)")
      ->required();
  build->add_option("--alpha", b->alpha, "GGX/Beckmann roughness AX or AX,AY, each in [0.005, 2]")->required();
  add_number_option(build, "--res", b->resolution,
                    ma::power_of_two(microgeom::kMinAssemblyResolution, microgeom::kMaxAssemblyResolution),
                    "vertices per side N (a power of two, 16..8192; 8192 needs ~2 GiB)")
      ->required();
  add_number_option(build, "--seed", b->seed, ma::whole(), "random seed (default 1)");
  const double inf = std::numeric_limits<double>::infinity();
  add_number_option(build, "--corr-cells", b->corr_cells, ma::real(microsim::Interval{0, inf}),
                    "correlation length l in cells, in [2, N/8] (default min(16, N/16)); the mixture's patches are 8 l");
  add_number_option(build, "--tile-size", b->tile_size, ma::real(microsim::Interval{0, inf, true}),
                    "physical side L of the tile (default 1)");
  add_number_option(build, "--iterations", b->iterations, ma::integer(0, 100),
                    "slope-matching iterations, 0..100 (default 8)");
  build->add_option("--ndf-match", b->ndf_match,
                    "radial (default: slope radii rank-matched, angles kept) or joint (the (radius, angle) law "
                    "matched, then the lobe bins of trace vndf refined; docs/reference/surfaces.md section 8)");
  build->add_option("--out", b->out, "heightmap EXR (channel 'height', attributes microsim.*)")->required();
  build->add_option("--mesh", b->mesh, "also write the mesh (.ply or .obj) through OpenMesh");
  add_number_option(build, "--mesh-crop", b->mesh_crop, ma::integer(0, std::numeric_limits<int>::max()),
                    "write only the first C x C cells to --mesh (default: whole tile)");
  build->add_option("--normals", b->normals, "also write the normal map EXR (R, G, B = unit cell normals)");
  build->add_option("--json", b->json, "also write the build report and statistics as JSON");
  build->add_flag("--quiet", b->quiet, "no progress on stderr");
  build->add_flag("--unsupported", b->unsupported,
                  "build even outside the supported range (the NDF check still decides; scripts/surface_range.sh)");
  ma::on_selected(build, [b] { return run_build(*b); });
}

void add_stats_command(CLI::App* group) {
  auto s = std::make_shared<StatsCliOptions>();
  auto* stats = group->add_subcommand(
      "stats",
      "Measure a heightmap EXR (built or imported): its NDF against GGX or Beckmann (slope-radius quantiles, "
      "equal-probability bins), slope and height statistics, and the height-slope correlation.");
  stats->add_option("heightmap", s->path, "heightmap EXR")->required();
  add_number_option(stats, "--tile-size", s->tile_size, ma::real(),
                    "physical tile size (required if the file has no microsim.tile_size)");
  auto* stats_alpha = stats->add_option("--alpha", s->alpha,
                    "normalising roughness AX[,AY], each in [1e-4, 10], anisotropy at most 1:1000 (default: the "
                    "file's, else fitted)");
  stats->add_option("--reference", s->reference, "ggx or beckmann (default: the file's, else ggx)");
  add_number_option(stats, "--corr-cells", s->corr_cells, ma::real(),
                    "correlation length for the tolerance (default: the file's)");
  stats->add_flag("--check", s->check, "exit 1 when the NDF misses the tolerance");
  stats->add_option("--json", s->json, "also write the statistics as JSON");
  stats->add_option("--mesh", s->mesh, "also write the mesh (.ply or .obj)");
  add_number_option(stats, "--mesh-crop", s->mesh_crop, ma::integer(0, std::numeric_limits<int>::max()),
                    "write only the first C x C cells to --mesh");
  stats->add_option("--normals", s->normals, "also write the normal map EXR");
  ma::on_selected(stats, [s, stats_alpha] {
    s->alpha_given = stats_alpha->count() > 0;
    return run_stats(*s);
  });
}

void add_import_command(CLI::App* group) {
  auto im = std::make_shared<ImportOptions>();
  auto* import = group->add_subcommand(
      "import",
      "Import an external heightmap EXR (channel 'height' or 'Y' or a single channel; square; heights in the "
      "unit of --tile-size) as a microsim heightmap, so a measured surface can be studied like a built one.");
  import->add_option("heightmap", im->path, "external heightmap EXR")->required();
  add_number_option(import, "--tile-size", im->tile_size, ma::real(),
                    "physical side of the tile, same unit as the heights")
      ->required();
  import->add_option("--out", im->out, "microsim heightmap EXR")->required();
  ma::on_selected(import, [im] { return run_import(*im); });
}

microsim::app::CommandRegistration surface_registration{"surface", [](CLI::App& app) {
  CLI::App* group = microsim::app::get_or_add_subcommand(
      app, "surface", "Periodic heightfield microsurfaces: build an assembly, measure a heightmap, import one.");
  add_build_command(group);
  add_stats_command(group);
  add_import_command(group);
}};

}  // namespace
