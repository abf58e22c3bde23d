// microsim albedo: energy-compensation reference tables (Kulla & Conty 2017): the directional albedo
// E(mu, alpha) and its hemispherical average E_avg(alpha) of a rough mirror, conductor or dielectric, from the analytic
// single scattering, the Smith random walk or the explicit `smith` heightfield (scatter/albedo_table.h),
// written as an EXR (rows alpha, columns mu), a CSV and JSON (scatter/albedo_table_io.h); with --layout, the
// table in a renderer's layout (scatter/albedo_layout.h), and with --grade TABLE --layout L, the grade of a
// table a renderer ships (scatter/albedo_grade.h). The table is measured by measure/albedo.h; with --shard K/N
// (the Smith walk), block range K of N of the table's cells, written as the part `microsim merge` joins.
//
// Exit codes: 0 done (a grade: every node within the tolerance), 1 a graded node beyond the tolerance, 2 bad
// usage or input (nothing written), 130 interrupted (the complete alphas written, marked partial; none
// complete, or a layout or grade: nothing written).
#include "albedo_layout_report.h"
#include "albedo_report.h"
#include "command.h"
#include "number_options.h"
#include "progress_bar.h"

#include "microfacet/material.h"
#include "microgeom/assembly.h"
#include "measure/albedo.h"
#include "scatter/albedo_anisotropic.h"
#include "scatter/albedo_anisotropic_walk.h"
#include "scatter/albedo_glass_layout.h"
#include "scatter/albedo_glass_walk.h"
#include "scatter/albedo_table.h"
#include "scatter/albedo_layout.h"
#include "scatter/albedo_table_io.h"
#include "core/atomic_file.h"
#include "core/parse.h"

#include <fmt/core.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <string>

namespace microsim::app {
namespace {

constexpr double kDefaultGradeTolerance = 1e-4;

struct AlbedoArgs {
  std::string model, material = "mirror", ndf = "ggx", alphas = "0.1,0.25,0.5,0.75,1";
  std::string walk_kernel = "scalar";  // --walk-kernel: smith-walk's kernel (scatter/smith_walk.h)
  bool inside = false;
  int mus = 16;
  std::uint64_t rays = 1'000'000;
  int res = 512;
  int max_order = kDefaultMaxOrder;
  double tolerance = 1e-8;
  std::uint64_t seed = 1;
  int threads = 0;
  std::string out, csv, json;
  std::string shard;                            // --shard K/N: the part of block range K of N of the cells
  std::string layout, grade, encoded, centres;  // --layout, --grade and their outputs
  std::string alphas_y;                         // anisotropic: the alpha_y axis (--alphas is alpha_x)
  int phis = 8;
  std::uint64_t table_samples = 0;
  std::set<std::string> given;  // the options given on the command line
};

// Options that only some models use: given to another model, they are an error, not silently ignored.
void check_model_options(const AlbedoArgs& a, AlbedoModel model) {
  const auto refuse = [&](const char* option, const char* applies) {
    if (a.given.count(option))
      throw UsageError(fmt::format("{} applies to {} only (not --model {})", option, applies, to_string(model)));
  };
  if (model == AlbedoModel::analytic)
    for (const char* o : {"--rays", "--seed", "--max-order"}) refuse(o, "the sampled models (smith-walk, surface)");
  if (model != AlbedoModel::surface) refuse("--res", "--model surface");
  if (model != AlbedoModel::analytic) refuse("--tolerance", "--model analytic");
  if (model != AlbedoModel::smith_walk) refuse("--shard", "--model smith-walk");
  if (model != AlbedoModel::smith_walk) refuse("--walk-kernel", "--model smith-walk");
}

// --walk-kernel of a smith-walk table, refused before any work where the lanes kernel does not walk (it walks
// GGX: every material of a table is its).
WalkKernel albedo_walk_kernel(const AlbedoArgs& a, NdfKind ndf) {
  const WalkKernel kernel = parse_walk_kernel("--walk-kernel", a.walk_kernel);  // ParseError: the caller's
  if (kernel == WalkKernel::lanes && ndf != NdfKind::ggx)
    throw UsageError(fmt::format("--ndf {}: not supported by --walk-kernel lanes (it walks GGX); --walk-kernel scalar "
                                 "walks every case", to_string(ndf)));
  return kernel;
}

Material albedo_material(const AlbedoArgs& a) {
  Material m;
  try {
    m = parse_material("--material", a.material);
  } catch (const std::invalid_argument& e) {  // ParseError, or a constructor's check
    throw UsageError(e.what());
  }
  // A conductor's table is not the mirror's scaled by a Fresnel average (F varies over the facets seen and
  // with the order): each complex index is its own table.
  if (m.kind() == MaterialKind::conductor && m.channels() != 1)
    throw UsageError(fmt::format("--material {}: one conductor index per table (conductor:ETA,K)", quote_excerpt(a.material)));
  if (m.kind() != MaterialKind::mirror && m.kind() != MaterialKind::dielectric && m.kind() != MaterialKind::conductor)
    throw UsageError(fmt::format("--material {}: an albedo table is for mirror, conductor:ETA,K or dielectric:ETA",
                                 quote_excerpt(a.material)));
  if (a.inside && !m.transmits())
    throw UsageError(fmt::format("--inside: light from inside needs a dielectric (--material {} is opaque)", m.describe()));
  return m;
}

std::vector<double> albedo_alphas(const AlbedoArgs& a) {
  const std::vector<double> alphas = parse_double_list("--alphas", a.alphas, Interval{kMinAlbedoAlpha, kMaxAlbedoAlpha});
  for (std::size_t i = 1; i < alphas.size(); ++i)
    if (!(alphas[i] > alphas[i - 1]))
      throw UsageError(fmt::format("--alphas {}: must increase ({} after {})", quote_excerpt(a.alphas), alphas[i],
                                   alphas[i - 1]));
  return alphas;
}

// --shard: --out is the part for `microsim merge`, a JSON file, and the only output.
void check_shard_outputs(const AlbedoArgs& a) {
  for (const auto& [option, path] : {std::pair{"--csv", a.csv}, std::pair{"--json", a.json}})
    if (!path.empty()) throw UsageError(fmt::format("{} does not apply to --shard (its output is the part, --out PART.json)", option));
  if (std::filesystem::path(a.out).extension() != ".json")
    throw UsageError(fmt::format("--out {}: with --shard {} it is the part for `microsim merge`, a JSON file (--out "
                                 "PART.json)", quote_excerpt(a.out), a.shard));
  check_output("--out", a.out);
}

void check_albedo_outputs(const AlbedoArgs& a) {
  if (!a.shard.empty()) return check_shard_outputs(a);
  check_distinct_outputs({}, {{"--out", a.out}, {"--csv", a.csv}, {"--json", a.json}});
  if (std::filesystem::path(a.out).extension() != ".exr")
    throw UsageError(fmt::format("--out {}: must be an .exr file", quote_excerpt(a.out)));
  if (!a.csv.empty() && std::filesystem::path(a.csv).extension() != ".csv")
    throw UsageError(fmt::format("--csv {}: must be a .csv file", quote_excerpt(a.csv)));
  check_output("--out", a.out);
  check_output("--csv", a.csv);
  check_output("--json", a.json);
}

// The request from the options, checked before any work (UsageError naming the bad value).
AlbedoTableRequest albedo_request(const AlbedoArgs& a) {
  AlbedoTableRequest r;
  try {
    r.model = parse_albedo_model("--model", a.model);
    r.ndf = parse_ndf_kind("--ndf", a.ndf);
    r.alphas = albedo_alphas(a);
    check_model_options(a, r.model);
    r.walk_kernel = albedo_walk_kernel(a, r.ndf);
  } catch (const ParseError& e) {
    throw UsageError(e.what());
  }
  r.material = albedo_material(a);
  r.inside = a.inside;
  r.mus = a.mus;
  r.tolerance = a.tolerance;
  r.paths = a.rays;
  r.seed = a.seed;
  r.max_order = a.max_order;
  r.resolution = a.res;
  try {
    check_albedo_request(r);
  } catch (const std::invalid_argument& e) {  // what is left: a surface resolution outside the supported range
    throw UsageError(r.model == AlbedoModel::surface ? fmt::format("--res {}: {}", a.res, e.what()) : e.what());
  }
  check_albedo_outputs(a);
  return r;
}

// A layout table or a grade takes only its own options: any other given is an error, not silently ignored.
void check_only(const AlbedoArgs& a, const std::set<std::string>& allowed, const char* mode) {
  for (const std::string& o : a.given)
    if (!allowed.count(o)) throw UsageError(fmt::format("{} does not apply to {}", o, mode));
}

NdfKind layout_ndf(const AlbedoArgs& a) {
  try {
    return parse_ndf_kind("--ndf", a.ndf);
  } catch (const ParseError& e) {
    throw UsageError(e.what());
  }
}

const AlbedoLayout& chosen_layout(const AlbedoArgs& a) {
  try {
    return find_albedo_layout("--layout", a.layout);
  } catch (const ParseError& e) {
    throw UsageError(e.what());
  }
}

// Per index node: the multiple scattering E - E1 averaged over the in-range (roughness, mu) nodes, and the
// share of it transmitted, sum (E_T - E1_T) / sum (E - E1).
void print_glass_walk(const GlassWalkTable& t) {
  fmt::print("{} nodes, Smith walk (Heitz et al. 2016; order 1 with the walk's own masking, not Cycles'): {} paths "
             "per node; {:.1f} s\n{:>12} {:>12} {:>12}\n", t.request.layout.name, t.request.paths, t.seconds, "ior",
             "mean E-E1", "T share");
  for (std::size_t z = 0; z < t.iors.size(); ++z) {
    double ms = 0, ms_t = 0;
    int n = 0;
    for (std::size_t y = 0; y < t.mus.size(); ++y)
      for (std::size_t x = 0; x < t.alphas.size(); ++x) {
        if (!t.in_range[x]) continue;
        const GlassWalkNode& c = t.cells[t.index(x, y, z)];
        ms += c[0].value - c[3].value;
        ms_t += c[2].value - c[5].value;
        ++n;
      }
    fmt::print("{:>12.6g} {:>12.6f} {:>12.4f}\n", t.request.layout.inverse ? 1 / t.iors[z] : t.iors[z], ms / n,
               ms > 0 ? ms_t / ms : 0.0);
  }
}

// A table's run (the anisotropic mirror's, the walk tables): its progress and Ctrl-C (exit 130, nothing
// written), then its CSV and JSON and its printed summary.
template <class Request, class Compute, class Csv, class Json, class Print>
int run_table(const AlbedoArgs& a, Request r, const Compute& compute, const Csv& csv, const Json& json,
              const Print& print) {
  const auto progress = std::make_shared<CliProgress>(true);
  r.run = cli_run_control(a.threads, progress);
  install_interrupt_handler();
  const auto t = compute(r);
  progress->finish();
  if (!t) return interrupted_nothing_written("albedo");
  if (!a.csv.empty()) write_file_atomically(a.csv, csv(*t));
  if (!a.json.empty()) write_file_atomically(a.json, json(*t).dump(2) + "\n");
  print(*t);
  return kExitOk;
}

// A walk table's run (the glass layout's split, the anisotropic mirror's): the walk options of the request, then
// run_table.
template <class Request, class Compute, class Csv, class Json, class Print>
int run_walk_table(const AlbedoArgs& a, Request r, const Compute& compute, const Csv& csv, const Json& json,
                   const Print& print) {
  try {
    r.walk_kernel = parse_walk_kernel("--walk-kernel", a.walk_kernel);
  } catch (const ParseError& e) {
    throw UsageError(e.what());
  }
  r.paths = a.rays;
  r.seed = a.seed;
  r.max_order = a.max_order;
  return run_table(a, r, compute, csv, json, print);
}

// --layout cycles-glass[-inv] --model smith-walk: the walk's split over the layout's nodes
// (scatter/albedo_glass_walk.h): CSV and JSON.
int run_glass_walk(const AlbedoArgs& a, const GlassLayout& layout) {
  check_only(a, {"--layout", "--model", "--rays", "--seed", "--max-order", "--walk-kernel", "--threads", "--csv",
                 "--json"},
             "a glass --layout with --model smith-walk (the walk's split on the layout's nodes)");
  if (a.csv.empty() && a.json.empty())
    throw UsageError(fmt::format("--layout {} --model smith-walk needs --csv or --json", layout.name));
  check_distinct_outputs({}, {{"--csv", a.csv}, {"--json", a.json}});
  check_output("--csv", a.csv);
  check_output("--json", a.json);
  GlassWalkRequest r;
  r.layout = layout;
  return run_walk_table(a, r, glass_walk_table, glass_walk_csv, glass_walk_json, print_glass_walk);
}

// A dielectric over Cycles' index axis (scatter/albedo_glass_layout.h): CSV, the encoded text and JSON, no EXR.
int run_glass_layout(const AlbedoArgs& a, const GlassLayout& layout) {
  if (a.model == "smith-walk") return run_glass_walk(a, layout);
  check_only(a, {"--layout", "--model", "--tolerance", "--threads", "--csv", "--encoded", "--json"},
             "a glass --layout (the analytic reference of a GGX dielectric at the layout's indices)");
  if (a.given.count("--model") && a.model != "analytic")
    throw UsageError(fmt::format("--model {}: a glass layout table holds the analytic reference (--model analytic) "
                                 "or the walk's split (--model smith-walk)", quote_excerpt(a.model)));
  if (a.csv.empty() && a.encoded.empty() && a.json.empty())
    throw UsageError(fmt::format("--layout {} needs --csv, --encoded or --json", layout.name));
  check_distinct_outputs({}, {{"--csv", a.csv}, {"--encoded", a.encoded}, {"--json", a.json}});
  check_output("--csv", a.csv);
  check_output("--encoded", a.encoded);
  check_output("--json", a.json);
  return run_albedo_glass_layout(layout, a.tolerance, a.threads, {a.csv, a.encoded, a.json});
}

int run_layout(const AlbedoArgs& a) {
  if (const GlassLayout* glass = find_glass_layout(a.layout)) return run_glass_layout(a, *glass);
  check_only(a, {"--layout", "--model", "--material", "--ndf", "--tolerance", "--threads", "--out", "--csv", "--json",
                 "--encoded", "--centres"},
             "--layout (a renderer's table: the analytic reference of a GGX or Beckmann mirror)");
  if (a.given.count("--model") && a.model != "analytic")
    throw UsageError(fmt::format("--model {}: a layout table holds the analytic reference (--model analytic)",
                                 quote_excerpt(a.model)));
  if (a.material != "mirror")
    throw UsageError(fmt::format("--material {}: the renderers' layouts hold a mirror's E (F = 1): --material mirror",
                                 quote_excerpt(a.material)));
  const AlbedoLayout& layout = chosen_layout(a);
  const NdfKind ndf = layout_ndf(a);
  if (a.out.empty()) throw UsageError("--layout needs --out T.exr");
  check_albedo_outputs(a);
  check_distinct_outputs({}, {{"--out", a.out}, {"--csv", a.csv}, {"--json", a.json}, {"--encoded", a.encoded},
                              {"--centres", a.centres}});
  check_output("--encoded", a.encoded);
  check_output("--centres", a.centres);
  return run_albedo_layout(layout, ndf, a.tolerance, a.threads, {a.out, a.csv, a.json, a.encoded, a.centres});
}

int run_grade(const AlbedoArgs& a) {
  check_only(a, {"--grade", "--layout", "--ndf", "--tolerance", "--table-samples", "--threads", "--json"},
             "--grade (the grade of a table in a layout)");
  if (a.layout.empty())
    throw UsageError("--grade needs --layout (the table's layout: " + albedo_layout_names() + ", " +
                     glass_layout_names() + ")");
  const GlassLayout* glass = find_glass_layout(a.layout);
  const AlbedoLayout* layout = glass == nullptr ? &chosen_layout(a) : nullptr;
  const NdfKind ndf = layout_ndf(a);
  if (glass != nullptr && ndf != NdfKind::ggx)
    throw UsageError(fmt::format("--ndf {} does not apply to a glass layout (a GGX dielectric's)", to_string(ndf)));
  check_distinct_outputs({{"--grade", a.grade}}, {{"--json", a.json}});
  check_output("--json", a.json);
  const double tolerance = a.given.count("--tolerance") ? a.tolerance : kDefaultGradeTolerance;
  if (glass != nullptr) return run_albedo_glass_grade(*glass, a.grade, tolerance, a.table_samples, a.threads, a.json);
  return run_albedo_grade(*layout, ndf, a.grade, tolerance, a.table_samples, a.threads, a.json);
}

void print_anisotropic(const AnisotropicAlbedoTable& t) {
  fmt::print("anisotropic GGX mirror (F = 1), analytic single scattering: {} x {} roughnesses, {} mus x {} phis; "
             "{:.1f} s\nE_avg (rows alpha_x, columns alpha_y):\n{:>10}", t.alphas_x.size(), t.alphas_y.size(),
             t.mus.size(), t.phis.size(), t.seconds, "");
  for (const double ay : t.alphas_y) fmt::print(" {:>10g}", ay);
  fmt::print("\n");
  for (std::size_t ix = 0; ix < t.alphas_x.size(); ++ix) {
    fmt::print("{:>10g}", t.alphas_x[ix]);
    for (std::size_t iy = 0; iy < t.alphas_y.size(); ++iy)
      fmt::print(" {:>10.6f}", t.average[ix * t.alphas_y.size() + iy].value);
    fmt::print("\n");
  }
}

// The outputs and axes of an anisotropic table (either model), checked before any work.
void anisotropic_axes(const AlbedoArgs& a, AnisotropicAxes& axes) {
  if (a.csv.empty() && a.json.empty()) throw UsageError("--alphas-y needs --csv T.csv or --json T.json");
  check_distinct_outputs({}, {{"--csv", a.csv}, {"--json", a.json}});
  check_output("--csv", a.csv);
  check_output("--json", a.json);
  try {
    axes.alphas_x = albedo_alphas(a);
    axes.alphas_y = parse_double_list("--alphas-y", a.alphas_y, Interval{kMinAlbedoAlpha, kMaxAlbedoAlpha});
  } catch (const ParseError& e) {
    throw UsageError(e.what());
  }
  axes.mus = a.mus;
  axes.phis = a.phis;
}

void print_anisotropic_walk(const AnisotropicWalkTable& t) {
  const AnisotropicWalkRequest& r = t.request;
  fmt::print("anisotropic GGX mirror (F = 1), Smith walk (Heitz et al. 2016): {} x {} roughnesses, {} mus x {} phis, "
             "{} paths per node; {:.1f} s\nE1_avg and E_ms_avg (orders >= 2) with standard errors:\n",
             r.alphas_x.size(), r.alphas_y.size(), t.mus.size(), t.phis.size(), r.paths, t.seconds);
  for (std::size_t ix = 0; ix < r.alphas_x.size(); ++ix)
    for (std::size_t iy = 0; iy < r.alphas_y.size(); ++iy) {
      const AnisotropicWalkNode& n = t.average[ix * r.alphas_y.size() + iy];
      fmt::print("  alpha ({:g}, {:g}): E1_avg {:.6f} +- {:.1e}, E_ms_avg {:.6f} +- {:.1e}\n", r.alphas_x[ix],
                 r.alphas_y[iy], n[1].value, n[1].standard_error, n[2].value, n[2].standard_error);
    }
}

// --alphas-y --model smith-walk: the walk's table (scatter/albedo_anisotropic_walk.h), CSV and JSON.
int run_anisotropic_walk(const AlbedoArgs& a) {
  check_only(a, {"--model", "--alphas", "--alphas-y", "--phis", "--mus", "--rays", "--seed", "--max-order",
                 "--walk-kernel", "--threads", "--csv", "--json"},
             "--alphas-y --model smith-walk (the anisotropic GGX mirror's walk table)");
  AnisotropicWalkRequest r;
  anisotropic_axes(a, r);
  return run_walk_table(a, r, anisotropic_walk_table, anisotropic_walk_csv, anisotropic_walk_json,
                        print_anisotropic_walk);
}

// --alphas-y: the anisotropic mirror's table (scatter/albedo_anisotropic.h), CSV and JSON.
int run_anisotropic(const AlbedoArgs& a) {
  if (a.model == "smith-walk") return run_anisotropic_walk(a);
  check_only(a, {"--model", "--alphas", "--alphas-y", "--phis", "--mus", "--tolerance", "--threads", "--csv", "--json"},
             "--alphas-y (the anisotropic GGX mirror's table)");
  if (a.model != "analytic")
    throw UsageError(fmt::format("--model {}: --alphas-y needs --model analytic or smith-walk", quote_excerpt(a.model)));
  AnisotropicAlbedoRequest r;
  anisotropic_axes(a, r);
  r.tolerance = a.tolerance;
  return run_table(a, r, anisotropic_albedo_table, anisotropic_albedo_csv, anisotropic_albedo_json, print_anisotropic);
}

// --shard K/N: block range K of N of the table's cells.
BlockRange shard_cells(const AlbedoArgs& a, const AlbedoTableRequest& request) {
  try {
    const ShardSpec s = parse_shard("--shard", a.shard, albedo_cell_count(request));
    return shard_range(albedo_cell_count(request), s.index, s.count);
  } catch (const ParseError& e) {
    throw UsageError(e.what());
  }
}

// The part of a shard's cells (measure_albedo_part), written to --out.
int run_shard(const AlbedoArgs& a, const AlbedoTableRequest& request, const BlockRange& cells) {
  const std::optional<nlohmann::json> part = measure_albedo_part(request, cells);
  if (!part) return interrupted_nothing_written("albedo");
  write_file_atomically(a.out, part->dump(2) + "\n");
  fmt::print("albedo: shard {}: cells {} of {} ({} paths each), {:.1f} s; part written to {} (`microsim merge`)\n",
             a.shard, cells.to_string(), albedo_cell_count(request), request.paths, (*part)["seconds"].get<double>(), a.out);
  return kExitOk;
}

int run_albedo(const AlbedoArgs& a) {
  if (!a.grade.empty()) return run_grade(a);
  if (a.given.count("--alphas-y")) return run_anisotropic(a);
  if (a.given.count("--phis")) throw UsageError("--phis applies to --alphas-y only");
  if (!a.layout.empty()) return run_layout(a);
  for (const char* o : {"--encoded", "--centres", "--table-samples"})
    if (a.given.count(o)) throw UsageError(fmt::format("{} applies to --layout or --grade only", o));
  if (a.model.empty()) throw UsageError("--model is required (analytic, smith-walk or surface), or --layout or --grade");
  if (a.out.empty()) throw UsageError("--out is required");
  AlbedoTableRequest request = albedo_request(a);
  const std::optional<BlockRange> shard = a.shard.empty() ? std::nullopt : std::optional(shard_cells(a, request));
  const auto progress = std::make_shared<CliProgress>(true);
  request.run = cli_run_control(a.threads, progress);
  install_interrupt_handler();
  fmt::print(stderr, "albedo: {}, {} alphas x {} mus{}\n", describe_albedo_request(request), request.alphas.size(),
             request.mus,
             request.model == AlbedoModel::analytic ? "" : fmt::format(", {} paths per cell", request.paths));
  if (shard) {
    const int code = run_shard(a, request, *shard);
    progress->finish();
    return code;
  }
  const AlbedoTable table = measure_albedo_table(request, print_albedo_row);
  progress->finish();
  return report_albedo_table(table, {a.out, a.csv, a.json});
}

void add_albedo_options(CLI::App* sub, AlbedoArgs& a) {
  sub->add_option("--model", a.model, "analytic (single scattering, by quadrature), smith-walk or surface (required "
                  "unless --layout or --grade)");
  sub->add_option("--material", a.material, "mirror, conductor:ETA,K (one index; its F_avg too) or dielectric:ETA")
      ->capture_default_str();
  sub->add_flag("--inside", a.inside, "light from inside the dielectric (the table of 1/eta)");
  sub->add_option("--ndf", a.ndf, "ggx or beckmann (surface: the smith or beckmann assembly; --layout, --grade: the "
                  "mirror's distribution)")->capture_default_str();
  sub->add_option("--alphas", a.alphas,
                  fmt::format("roughnesses (rows), increasing, each in [{}, {}]", kMinAlbedoAlpha, kMaxAlbedoAlpha))
      ->capture_default_str();
  add_number_option(sub, "--mus", a.mus, integer(kMinAlbedoMus, kMaxAlbedoMus),
                    fmt::format("Gauss-Legendre nodes in mu = cos(theta) (columns), {}..{}", kMinAlbedoMus, kMaxAlbedoMus))
      ->default_str(std::to_string(a.mus));
  add_number_option(sub, "--rays", a.rays, whole(1, kMaxRays), at_most("sampled models: paths per cell", kMaxRays))
      ->default_str(std::to_string(a.rays));
  add_number_option(sub, "--res", a.res,
                    power_of_two(microgeom::kMinAssemblyResolution, microgeom::kMaxAssemblyResolution),
                    "surface: resolution N of each alpha's surface (a power of two; GGX needs >= 256)")
      ->default_str(std::to_string(a.res));
  add_number_option(sub, "--max-order", a.max_order, integer(1, kMaxOrderCap),
                    "sampled models: order cap (the weight left is the `unfinished` quantity)")
      ->default_str(std::to_string(a.max_order));
  add_number_option(sub, "--tolerance", a.tolerance, real(Interval{1e-13, 1e-2}),
                    "analytic and --layout: absolute error target of each cell's quadrature, in [1e-13, 1e-2]; "
                    "--grade: the largest |table - reference| a node may have (default 1e-4)")
      ->default_str("1e-08");
  add_number_option(sub, "--seed", a.seed, whole(), "random seed (same seed, same table, whatever --threads)")
      ->default_str(std::to_string(a.seed));
  add_number_option(sub, "--threads", a.threads, integer(0, kMaxThreads), at_most("worker threads (0: all cores)", kMaxThreads))
      ->default_str(std::to_string(a.threads));
  sub->add_option("--out", a.out, "the table as an EXR (rows alpha, columns mu; --layout: the layout's grid; --shard: the "
                  "part, a JSON file)");
  sub->add_option("--shard", a.shard,
                  "smith-walk: run only shard K of N (K/N, 1-based) of the table's cells and write its part, --out "
                  "PART.json (exact estimates); `microsim merge` joins the parts into the single run's table, bit for bit");
  sub->add_option("--walk-kernel", a.walk_kernel, "smith-walk: the code that walks each cell's paths: scalar (the "
                  "reference) or lanes (SIMD lanes, several times faster, GGX only; other random numbers: its parts "
                  "merge only with its own)")->capture_default_str();
  sub->add_option("--csv", a.csv, "also write the table as CSV");
  sub->add_option("--json", a.json, "also write the table (--grade: the grade) as JSON");
  sub->add_option("--layout", a.layout,
                  "a renderer's layout of the GGX (or --ndf beckmann) mirror's E(mu, alpha), analytic reference and error "
                  "per node: " +
                      albedo_layout_names() + "; of a GGX dielectric's E = E_R + E_T over Cycles' index axis (--csv, "
                      "--encoded, --json): " + glass_layout_names() +
                      " (with --model smith-walk: the walk's E_R, E_T of every order and of order 1 per node, --csv, "
                      "--json)");
  sub->add_option("--alphas-y", a.alphas_y,
                  "an anisotropic GGX mirror's table per (alpha_x in --alphas, alpha_y in this list) and node (mu, phi): "
                  "--model analytic: E (single scattering) and E_avg; --model smith-walk: E (every order), E1 (order "
                  "1), E_ms (orders >= 2) and unfinished, with standard errors, and their averages (--csv, --json)");
  add_number_option(sub, "--phis", a.phis, integer(1, 64),
                    "--alphas-y: Gauss-Legendre nodes in phi over [0, pi/2], 1..64")->default_str(std::to_string(a.phis));
  sub->add_option("--encoded", a.encoded, "--layout: also write the values in the renderer's own encoding");
  sub->add_option("--centres", a.centres, "--layout: also write the interpolation error at the cell centres (CSV)");
  sub->add_option("--grade", a.grade,
                  "grade a table in --layout L (.exr; the .csv microsim writes; or a .txt of the values in storage order as "
                  "the renderer prints them, Cycles' 'f' suffixes allowed) against the reference: exit 0 all nodes "
                  "within --tolerance, 1 not");
  add_number_option(sub, "--table-samples", a.table_samples, whole(1, kMaxRays),
                    "--grade: the samples per node the table was built from (its noise is reported)");
}

CommandRegistration albedo_registration{"albedo", [](CLI::App& app) {
  auto args = std::make_shared<AlbedoArgs>();
  auto* sub = app.add_subcommand(
      "albedo",
      "Energy-compensation tables (Kulla & Conty 2017): the directional albedo E(mu, alpha) and its hemispherical "
      "average E_avg(alpha) = 2 int_0^1 E mu dmu of a rough mirror, conductor (and its F_avg) or dielectric (from "
      "outside, or --inside), with "
      "errors: --model analytic (single scattering by quadrature), smith-walk (the Smith random walk, Heitz et al. "
      "2016: all orders and order 1) or surface (the explicit smith heightfield, traced). mu on Gauss-Legendre "
      "nodes. Writes an EXR, optionally CSV and JSON. --layout cycles|filament-dfg|enterprise-pbr|uniform: the GGX "
      "mirror's table in a renderer's layout; --layout cycles-glass|cycles-glass-inv: a GGX dielectric's over Cycles' "
      "index axis (--model smith-walk: the walk's reflected / transmitted split per node); --alphas-y: the "
      "anisotropic mirror's E(mu, phi) and E_avg (analytic; smith-walk: split into order 1 and orders >= 2); --grade "
      "TABLE --layout L: grade a shipped table. Exit 0 done (grade: passed), 1 a graded node beyond --tolerance, 2 "
      "bad input (nothing written), 130 interrupted.");
  add_albedo_options(sub, *args);
  on_selected(sub, [args, sub] {
    for (const CLI::Option* o : sub->get_options())
      if (o->count() > 0) args->given.insert(o->get_name());
    return run_albedo(*args);
  });
}};

}  // namespace
}  // namespace microsim::app
