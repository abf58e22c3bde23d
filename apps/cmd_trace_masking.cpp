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
#include "surface_input.h"
#include "number_options.h"

#include "microgeom/assembly.h"
#include "microgeom/heightfield.h"
#include "stats/histogram_io.h"
#include "measure/masking.h"
#include "progress_bar.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <new>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace microsim::app {

namespace {

namespace fs = std::filesystem;

constexpr int kVndfRows = kMaskingVndfRows;  // lobe and sphere bins of the VNDF comparison (lobe: 8 x 16 cells)

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
  std::string geometry = "triangles";
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

struct TableRow {
  std::string assembly;
  double alpha = 0, theta = 0;
  unsigned long long seed = 0;
  VndfComparison vndf;  // lobe bins
  MaskingResult masking;
};

// One column of the table: a measured quantity of a row with its Monte Carlo standard error (none for the
// VNDF distances, whose noise is the separate noise-floor column).
struct TableColumn {
  std::string header, key;
  int digits = 3;
  bool has_mc_error = true;
  Estimate (*get)(const TableRow&) = nullptr;
};

std::vector<TableColumn> table_columns(double grazing_share) {
  return {
      {"TV to Smith", "tv_smith_analytic", 4, false, [](const TableRow& r) { return Estimate{r.vndf.tv_analytic, 0}; }},
      {"TV to Smith, own NDF", "tv_smith_empirical", 4, false,
       [](const TableRow& r) { return Estimate{r.vndf.tv_empirical, 0}; }},
      {"TV noise", "tv_noise_floor", 4, false, [](const TableRow& r) { return Estimate{r.vndf.tv_noise, 0}; }},
      {"G1 / Smith G1", "g1_ratio_to_smith_analytic", 3, true,
       [](const TableRow& r) {
         const auto& m = r.masking;
         return Estimate{m.g1.value / m.g1_smith_analytic, m.g1.se / m.g1_smith_analytic};
       }},
      {"facing: G1(v\\|m) / G1", "facing_ratio", 3, true, [](const TableRow& r) { return r.masking.by_normal.back().ratio; }},
      {"grazing decile: G1(v\\|m) / G1", "grazing_decile_ratio", 3, true,
       [](const TableRow& r) { return r.masking.by_normal.front().ratio; }},
      {fmt::format("near-grazing {:g}%: G1(v\\|m) / G1", 100 * grazing_share), "near_grazing_ratio", 3, true,
       [](const TableRow& r) { return r.masking.near_grazing.ratio; }},
      {"near-grazing: angle(m, v) from", "near_grazing_angle_min_deg", 1, false,
       [](const TableRow& r) {
         return Estimate{std::acos(std::clamp(r.masking.near_grazing.hi, -1.0, 1.0)) * 180.0 / kPi<double>, 0};
       }},
      {"mirror pair: G2 / HC Smith", "mirror_pair_g2_ratio", 3, true,
       [](const TableRow& r) { return r.masking.pair_cone->ratio_analytic; }},
      {"mirror lobe: G2 / HC Smith", "mirror_lobe_g2_ratio", 3, true,
       [](const TableRow& r) { return r.masking.mirror->ratio_analytic; }},
      {"leak ratio", "leak_ratio", 4, true, [](const TableRow& r) { return r.masking.leak_ratio; }},
  };
}

// A column over the realisations of one cell: the mean, the standard deviation across realisations and the
// standard error of the mean (sd / sqrt(k); it contains the Monte Carlo noise too), and the Monte Carlo
// error of the mean, sqrt(sum se_i^2) / k.
struct CellSummary {
  std::vector<double> values;
  double mean = 0, sd = 0, se_across = 0, mc_se = 0, min = 0, max = 0;
};

CellSummary summarise(const std::vector<Estimate>& xs) {
  CellSummary c;
  const double k = double(xs.size());
  double mc = 0;
  c.min = xs.front().value;
  c.max = xs.front().value;
  for (const auto& x : xs) {
    c.values.push_back(x.value);
    c.mean += x.value / k;
    mc += x.se * x.se;
    c.min = std::min(c.min, x.value);
    c.max = std::max(c.max, x.value);
  }
  double ss = 0;
  for (const auto& x : xs) ss += sqr(x.value - c.mean);
  c.sd = xs.size() > 1 ? std::sqrt(ss / (k - 1.0)) : 0.0;
  c.se_across = c.sd / std::sqrt(k);
  c.mc_se = std::sqrt(mc) / k;
  return c;
}

std::vector<unsigned long long> parse_seeds(const MaskingArgs& a) {
  if (a.seeds.empty()) return {a.seed};
  std::vector<unsigned long long> seeds;
  for (const std::uint64_t s : parse_uint_list("--seeds", a.seeds)) {
    if (std::find(seeds.begin(), seeds.end(), s) != seeds.end())
      throw UsageError(fmt::format("--seeds {}: seed {} appears twice", quote_excerpt(a.seeds), s));
    seeds.push_back(s);
  }
  return seeds;
}

// A surface of the table, or nothing when Ctrl-C stopped its build.
std::optional<microgeom::Heightfield> build_unless_interrupted(const microgeom::AssemblyParams& p,
                                                               microgeom::BuildReport& report) {
  try {
    return microgeom::build_assembly(p, &report, {}, [] { return interrupted(); });
  } catch (const microgeom::BuildCancelled&) {
    return std::nullopt;
  }
}

int run_table(const MaskingArgs& a) {
  check_distinct_outputs({}, {{"--json", a.json}, {"--markdown", a.markdown}});
  const auto alphas = parse_double_list("--alphas", a.alphas);
  const auto thetas = parse_double_list("--thetas", a.thetas);
  const auto names = split_names("--assemblies", a.assemblies);
  const auto seeds = parse_seeds(a);
  for (double t : thetas) check_theta("--thetas", t);
  for (double al : alphas)
    if (!(al >= microgeom::kMinAssemblyAlpha && al <= microgeom::kMaxAssemblyAlpha))
      throw UsageError(fmt::format("--alphas: {} outside [{}, {}]", al, microgeom::kMinAssemblyAlpha, microgeom::kMaxAssemblyAlpha));
  for (const auto& n : names)
    if (!microgeom::find_assembly(n)) throw UsageError(fmt::format("--assemblies: unknown assembly '{}'", n));
  if (a.table_vndf_rays <= 0) throw UsageError(fmt::format("--vndf-rays {}: must be positive", a.table_vndf_rays));
  if (!std::isfinite(a.table_phi)) throw UsageError(fmt::format("--phi {}: must be finite", a.table_phi));
  check_grazing_share(a.grazing_share);
  {
    microgeom::AssemblyParams p;
    p.resolution = a.res;
    p.corr_cells = a.corr_cells;
    try {
      microgeom::validate(p);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
  }
  check_output("--json", a.json);
  check_output("--markdown", a.markdown);
  install_interrupt_handler();

  const auto t_start = std::chrono::steady_clock::now();
  const std::vector<TableColumn> columns = table_columns(a.grazing_share);
  std::vector<TableRow> rows;
  nlohmann::json j;
  j["parameters"] = {{"assemblies", names}, {"alphas", alphas}, {"thetas", thetas}, {"phi", a.table_phi},
                     {"resolution", a.res}, {"corr_cells", a.corr_cells}, {"seeds", seeds},
                     {"samples", a.samples}, {"vndf_rays", a.table_vndf_rays}, {"vndf_lobe_rows", kVndfRows},
                     {"grazing_share", a.grazing_share}};
  bool partial = false;
  for (const auto& name : names) {
    for (double alpha : alphas) {
      for (const unsigned long long seed : seeds) {
        if (interrupted()) {
          partial = true;
          break;
        }
        microgeom::AssemblyParams p;
        p.assembly = name;
        p.alpha_x = p.alpha_y = alpha;
        p.resolution = a.res;
        p.seed = seed;
        p.corr_cells = a.corr_cells;
        const auto tb = std::chrono::steady_clock::now();
        microgeom::BuildReport report;
        const std::optional<microgeom::Heightfield> built = build_unless_interrupted(p, report);
        if (!built) {
          partial = true;
          break;
        }
        const microgeom::Heightfield& field = *built;
        const double build_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - tb).count();
        const AnalyticSmith analytic = analytic_reference(field);
        const EmpiricalSmith empirical(field);
        const HeightfieldScene scene(field);
        nlohmann::json js;
        js["assembly"] = name;
        js["alpha"] = alpha;
        js["seed"] = seed;
        js["corr_cells"] = report.corr_cells;
        js["build_seconds"] = build_s;
        js["scene_seconds"] = scene.build_seconds();
        js["analytic_reference"] = analytic.describe();
        for (double theta : thetas) {
          if (interrupted()) {
            partial = true;
            break;
          }
          const auto tr = std::chrono::steady_clock::now();
          const Vec3<double> v = direction_from_degrees(theta, a.table_phi);
          const std::vector<DirectionBinning> binnings = {DirectionBinning::lobe(
              GGX<double>(analytic.alpha_x(), analytic.alpha_y()), v, SampleDomain::microfacet_normal, kVndfRows)};
          TraceOptions to;
          to.rays = std::uint64_t(a.table_vndf_rays);
          to.seed = seed;
          to.run = cli_run_control(a.threads, nullptr);
          const TraceResult tres = trace_vndf_heightfield(scene, v, binnings, to);
          TableRow row;
          row.assembly = name;
          row.alpha = alpha;
          row.theta = theta;
          row.seed = seed;
          row.vndf = compare_vndf(tres.counts[0], tres.unbinned[0], binnings[0], v, analytic, empirical);
          MaskingOptions mo;
          mo.samples = std::uint64_t(a.samples);
          mo.seed = seed;
          mo.run = cli_run_control(a.threads, nullptr);
          mo.grazing_share = a.grazing_share;
          // The specular pair: l = v mirrored through the mean normal, facets within the cone around z.
          mo.light = Vec3<double>(-v.x(), -v.y(), v.z());
          row.masking = estimate_masking(scene, analytic, empirical, v, mo);
          const bool view_partial = tres.partial || row.masking.partial;
          partial = partial || view_partial;
          const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - tr).count();
          const auto& nb = row.masking.by_normal;
          fmt::print(stderr,
                     "{:<9} alpha {:<4} seed {:<3} theta {:<3}: TV {:.4f} (own NDF {:.4f}, floor {:.4f}) facing {:.3f} "
                     "grazing decile {:.3f} near-grazing {:.3f} G2 pair/HC {:.3f} lobe/HC {:.3f} leak {:.4f} ({:.1f} s)\n",
                     name, alpha, seed, theta, row.vndf.tv_analytic, row.vndf.tv_empirical, row.vndf.tv_noise,
                     nb.back().ratio.value, nb.front().ratio.value, row.masking.near_grazing.ratio.value,
                     row.masking.pair_cone->ratio_analytic.value, row.masking.mirror->ratio_analytic.value,
                     row.masking.leak_ratio.value, secs);
          nlohmann::json jr;
          jr["theta"] = theta;
          jr["vndf"] = to_json(row.vndf);
          jr["vndf_rays"] = tres.rays;
          jr["vndf_rays_per_second"] = tres.rays_per_second();
          jr["masking"] = to_json(row.masking);
          jr["partial"] = view_partial;
          js["views"].push_back(jr);
          if (!view_partial) rows.push_back(std::move(row));  // the table holds the complete views only
        }
        j["surfaces"].push_back(js);
      }
    }
  }
  const double total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  j["seconds"] = total_s;
  j["peak_rss_mib"] = peak_rss_mib();
  j["partial"] = partial;
  const std::size_t views_requested = names.size() * alphas.size() * seeds.size() * thetas.size();
  j["views_requested"] = views_requested;
  j["views_complete"] = rows.size();

  // One table row per (assembly, alpha, theta), over the realisations that were traced.
  const bool several = seeds.size() > 1;
  std::string seed_text;
  for (std::size_t k = 0; k < seeds.size(); ++k) seed_text += (k ? "," : "") + std::to_string(seeds[k]);
  std::string md;
  if (partial)
    md += fmt::format("**PARTIAL: interrupted (Ctrl-C) after {} of {} views; the table holds the complete views "
                      "only.**\n\n",
                      rows.size(), views_requested);
  md += fmt::format("Surfaces {}^2, correlation length {} cells (0 = default), seed{} {}, view azimuth {} deg; per view "
                    "{} VNDF rays (lobe bins {} x {}) and {} surface points; near-grazing class: the bottom {:g}% of "
                    "the front-facing projected area. {:.0f} s in all.\n",
                    a.res, a.corr_cells, several ? "s" : "", seed_text, a.table_phi, a.table_vndf_rays, kVndfRows,
                    2 * kVndfRows, a.samples, 100 * a.grazing_share, total_s);
  if (several) {
    md += fmt::format("Each cell: the mean over the {} realisations ± its standard error across them (sd / sqrt({})), "
                      "then in brackets the Monte Carlo error of that mean.\n",
                      seeds.size(), seeds.size());
  }
  md += "\n| assembly | alpha | theta |";
  for (const auto& c : columns) md += " " + c.header + " |";
  md += "\n|---|---|---|";
  for (std::size_t k = 0; k < columns.size(); ++k) md += "---|";
  md += "\n";
  for (const auto& name : names) {
    for (double alpha : alphas) {
      for (double theta : thetas) {
        std::vector<const TableRow*> cell;
        for (const auto& r : rows)
          if (r.assembly == name && r.alpha == alpha && r.theta == theta) cell.push_back(&r);
        if (cell.empty()) continue;
        nlohmann::json jc = {{"assembly", name}, {"alpha", alpha}, {"theta", theta}, {"realisations", cell.size()}};
        md += fmt::format("| {} | {} | {} |", name, alpha, theta);
        for (const auto& col : columns) {
          std::vector<Estimate> xs;
          for (const TableRow* r : cell) xs.push_back(col.get(*r));
          const CellSummary s = summarise(xs);
          jc[col.key] = {{"values", s.values}, {"mean", s.mean}, {"sd_across", s.sd}, {"se_across", s.se_across},
                         {"mc_se", s.mc_se}, {"min", s.min}, {"max", s.max}};
          if (!several) {
            md += col.has_mc_error ? " " + pm(xs.front(), col.digits) + " |"
                                   : fmt::format(" {:.{}f} |", xs.front().value, col.digits);
          } else if (col.has_mc_error) {
            md += fmt::format(" {:.{}f} ± {:.{}f} [{:.{}f}] |", s.mean, col.digits, s.se_across, col.digits, s.mc_se,
                              col.digits);
          } else {
            md += fmt::format(" {:.{}f} ± {:.{}f} |", s.mean, col.digits, s.se_across, col.digits);
          }
        }
        md += "\n";
        j["cells"].push_back(jc);
      }
    }
  }
  if (!a.json.empty()) write_text_atomically(a.json, j.dump(2) + "\n");
  if (!a.markdown.empty()) write_text_atomically(a.markdown, md);
  fmt::print("{}", md);
  fmt::print("peak RSS {:.1f} MiB\n", peak_rss_mib());
  bool failed = false;
  for (const auto& r : rows) failed = failed || leak_failed(r.masking);
  if (partial) return interrupted_partial_written("trace masking --table", {a.json, a.markdown});
  return failed ? kExitRejected : kExitOk;
}

}  // namespace

namespace {

CommandRegistration reg{"trace masking", [](CLI::App& app) {
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
      "--table builds the assemblies and prints the masking table of docs/masking.md. Exit 0 done, 1 leak test "
      "failed, 2 bad input, 130 interrupted.");
  sub->add_option("--surface", args->surface, "heightmap EXR (microsim surface build/import)");
  add_number_option(sub, "--tile-size", args->tile_size, real(),
                    "physical tile size, for heightmaps without the microsim.tile_size attribute");
  add_number_option(sub, "--theta", args->theta, real(), "view polar angle in degrees, [0, 90)");
  add_number_option(sub, "--phi", args->phi, real(), "view azimuth in degrees (single surface; default 0)");
  add_number_option(sub, "--theta-l", args->theta_l, real(), "light polar angle in degrees, [0, 90): adds G2(v, l)");
  add_number_option(sub, "--phi-l", args->phi_l, real(), "light azimuth in degrees")
      ->default_str(fmt::format("{}", args->phi_l));
  add_number_option(sub, "--cone", args->cone, real(),
                    "half-angle (deg) of the mirror cone around the half vector for G2(v, l)")
      ->default_str(fmt::format("{}", args->cone));
  add_number_option(sub, "--samples", args->samples, whole(1, kMaxSamples),
                    at_most("surface points per view", kMaxSamples))
      ->default_str(std::to_string(args->samples));
  add_number_option(sub, "--vndf-rays", args->vndf_rays, whole(0, kMaxRays),
                    at_most("also trace the VNDF with this many rays (single surface; table: rays per view, "
                            "default 2e6)",
                            kMaxRays));
  add_number_option(sub, "--seed", args->seed, whole(), "random seed (same seed, same result, whatever --threads)")
      ->default_str(std::to_string(args->seed));
  add_number_option(sub, "--threads", args->threads, integer(0, kMaxThreads),
                    at_most("worker threads (0: all cores)", kMaxThreads))
      ->default_str(std::to_string(args->threads));
  add_number_option(sub, "--bins", args->bins, integer(1, 1000), "bins of <v, m> and of height, 1..1000")
      ->default_str(std::to_string(args->bins));
  add_number_option(sub, "--grazing-share", args->grazing_share, real(),
                    "share of the front-facing projected area in the fine near-grazing class of G1(v | m) "
                    "(the facets with the smallest <v, m>), in (0, 0.5)")
      ->default_str(fmt::format("{}", args->grazing_share));
  sub->add_option("--geometry", args->geometry, "Embree geometry: triangles or grid")->capture_default_str();
  sub->add_option("--json", args->json, "write the results as JSON");
  sub->add_flag("--table", args->table, "build the assemblies and print the masking table (docs/masking.md)");
  sub->add_option("--assemblies", args->assemblies, "table: assemblies")->capture_default_str();
  sub->add_option("--alphas", args->alphas, "table: roughnesses")->capture_default_str();
  sub->add_option("--thetas", args->thetas, "table: view angles (deg)")->capture_default_str();
  add_number_option(sub, "--table-phi", args->table_phi, real(), "table: view azimuth (deg), off the grid axes")
      ->default_str(fmt::format("{}", args->table_phi));
  add_number_option(sub, "--res", args->res,
                    power_of_two(microgeom::kMinAssemblyResolution, microgeom::kMaxAssemblyResolution),
                    "table: surface resolution N (a power of two, 16..8192)")
      ->default_str(std::to_string(args->res));
  add_number_option(sub, "--corr-cells", args->corr_cells, real(),
                    "table: correlation length in cells (0: assembly default)")
      ->default_str(fmt::format("{}", args->corr_cells));
  sub->add_option("--seeds", args->seeds,
                  "table: several surface realisations per cell, e.g. 1,2,3 (each cell: mean over the realisations "
                  "± its standard error across them, and the Monte Carlo error of the mean); default: --seed only");
  sub->add_option("--markdown", args->markdown, "table: also write the markdown table to this file");
  sub->add_option("--shard", args->shard,
                  "single surface: sample only shard K of N of the run (K/N, 1-based: a contiguous range of its blocks "
                  "of 4096 points) and write the partial result to --json, for `microsim merge`");
  on_selected(sub, [args] {
    if (args->table && !args->shard.empty())
      throw UsageError(fmt::format("--shard {} with --table: the table is not sharded; shard a single surface's run "
                                   "(trace masking --surface S --shard K/N, or trace vndf --surface S --shard K/N)",
                                   args->shard));
    if (args->table) {
      MaskingArgs a = *args;
      if (a.vndf_rays > 0) a.table_vndf_rays = a.vndf_rays;
      return run_table(a);
    }
    return run_masking(*args);
  });
}};

}  // namespace

}  // namespace microsim::app
