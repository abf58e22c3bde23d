// microsim bsdf-queries --bsdf SPEC --out Q.npy: the pairs (wi, wo) a renderer fills in with its eval() for
// `microsim check-eval` (validate/bsdf_queries.h): an NPY (N, 6) array, wi then wo per row, z-up.
// microsim bsdf-queries --cells --theta T [--phi P] --out C.npy: one view's cell points (measure/bsdf_self_check.h
// cell_points), which a renderer fills in with eval() and pdf() for `check-bsdf-files --cells`.
//
// Exit codes: 0 written, 2 bad usage.
#include "bsdf_options.h"
#include "command.h"
#include "number_options.h"

#include "measure/bsdf_self_check.h"
#include "microfacet/roughness.h"
#include "validate/bsdf_queries.h"
#include "validate/sample_io.h"

#include <fmt/core.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace microsim::app {
namespace {

struct QueryArgs {
  std::string bsdf, alpha, out;
  int per_view = 512, points_per_cell = 256;
  unsigned long long seed = 1;
  double theta = 0, phi = 0;
  bool float32 = false, cells = false;
};

// --cells: the pairs (the view, a cell point), cell after cell.
std::vector<BsdfQuery> cell_queries(const QueryArgs& a) {
  if (!a.bsdf.empty() || !a.alpha.empty()) throw UsageError("--cells: the cell points do not depend on --bsdf or --alpha");
  const Vec3<double> wi = direction_from_degrees(a.theta, a.phi);
  std::vector<BsdfQuery> q;
  for (const Vec3<double>& wo : battery::cell_points(a.points_per_cell, a.seed)) q.push_back({wi, wo});
  return q;
}

int run_queries(const QueryArgs& a) {
  check_output("--out", a.out);
  if (std::filesystem::path(a.out).extension() != ".npy") throw UsageError(fmt::format("--out '{}': must be a .npy file", a.out));
  std::vector<BsdfQuery> queries;
  if (a.cells) {
    queries = cell_queries(a);
  } else {
    if (a.bsdf.empty()) throw UsageError("--bsdf is required (or --cells)");
    const Material bsdf = microfacet_bsdf_option(a.bsdf);
    std::optional<GGX<double>> ggx;
    if (!a.alpha.empty()) {
      const auto [ax, ay] = parse_alpha("--alpha", a.alpha);
      ggx = GGX<double>(ax, ay);
    }
    queries = bsdf_queries(bsdf, a.per_view, a.seed, ggx);
  }
  std::vector<double> table;
  table.reserve(queries.size() * 6);
  for (const BsdfQuery& q : queries) table.insert(table.end(), {q.wi.x(), q.wi.y(), q.wi.z(), q.wo.x(), q.wo.y(), q.wo.z()});
  try {
    write_npy_table(a.out, table, 6, a.float32);
  } catch (const SampleFileError& e) {
    throw UsageError(e.what());
  }
  fmt::print("bsdf-queries: {} pairs (wi, wo) written to {} ({} x 6, {})\n", queries.size(), a.out, queries.size(),
             a.float32 ? "float32" : "float64");
  fmt::print("fill in f(wi, wo) |cos wo| per channel (and pdf(wo | wi)) and run `microsim {}` on the result\n",
             a.cells ? "check-bsdf-files --cells" : "check-eval");
  return kExitOk;
}

CommandRegistration bsdf_queries_registration{"bsdf-queries", [](CLI::App& app) {
  auto a = std::make_shared<QueryArgs>();
  auto* sub = app.add_subcommand(
      "bsdf-queries",
      "Write the pairs (wi, wo) a renderer fills in with its eval() for `microsim check-eval`: views at 0, 30, 60, 80 "
      "and 89.9 deg (and from inside a dielectric), wo stratified over the sphere, and the edge cases renderers get "
      "wrong (the mirror direction, wo = wi, wo = -wi, grazing wo, the refraction through the mean surface, and with "
      "--alpha directions in the lobe). Query the BSDF at the ends of its alpha range too. With --cells, instead one "
      "view's cell points for `check-bsdf-files --cells`: the sphere's 256 equal-area cells (16 in z by 16 in phi), "
      "in each a grid of strata with one point jittered in each, cell after cell; filled in with eval() and pdf(), "
      "they give the integrals of pdf() and eval() over each cell. Exit 0 written, 2 bad usage.");
  sub->add_option("--bsdf", a->bsdf, "mirror, conductor:ETA,K or dielectric:ETA (a dielectric's queries cover both sides); "
                  "required unless --cells");
  sub->add_option("--alpha", a->alpha, "also query wo in the lobe of this GGX roughness (AX or AX,AY)");
  sub->add_option("--out", a->out, "the query file, .npy (N, 6): wi_x wi_y wi_z wo_x wo_y wo_z per row")->required();
  add_number_option(sub, "--per-view", a->per_view, integer(2, 1 << 20), "stratified wo per view")->default_str("512");
  add_number_option(sub, "--seed", a->seed, whole(), "seed of the jitter")->default_str("1");
  sub->add_flag("--float32", a->float32, "write float32 (default float64)");
  sub->add_flag("--cells", a->cells, "write one view's cell points (--theta, --phi) for check-bsdf-files --cells");
  add_number_option(sub, "--theta", a->theta, real({0, 180}), "--cells: the view's polar angle in degrees (> 90: from inside)")
      ->default_str("0");
  add_number_option(sub, "--phi", a->phi, real(), "--cells: the view's azimuth in degrees")->default_str("0");
  add_number_option(sub, "--points-per-cell", a->points_per_cell, integer(4, 1 << 12),
                    "--cells: points per cell (n x n strata, n the even number nearest its square root)")
      ->default_str("256");
  on_selected(sub, [a] { return run_queries(*a); });
}};

}  // namespace
}  // namespace microsim::app
