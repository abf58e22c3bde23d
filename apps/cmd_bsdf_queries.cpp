// microsim bsdf-queries --bsdf SPEC --out Q.npy: the pairs (wi, wo) a renderer fills in with its eval() for
// `microsim check-eval` (validate/bsdf_queries.h): an NPY (N, 6) array, wi then wo per row, z-up.
//
// Exit codes: 0 written, 2 bad usage.
#include "bsdf_options.h"
#include "command.h"
#include "number_options.h"

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
  int per_view = 512;
  unsigned long long seed = 1;
  bool float32 = false;
};

int run_queries(const QueryArgs& a) {
  check_output("--out", a.out);
  if (std::filesystem::path(a.out).extension() != ".npy") throw UsageError(fmt::format("--out '{}': must be a .npy file", a.out));
  const Material bsdf = microfacet_bsdf_option(a.bsdf);
  std::optional<GGX<double>> ggx;
  if (!a.alpha.empty()) {
    const auto [ax, ay] = parse_alpha("--alpha", a.alpha);
    ggx = GGX<double>(ax, ay);
  }
  const std::vector<BsdfQuery> queries = bsdf_queries(bsdf, a.per_view, a.seed, ggx);
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
  fmt::print("fill in f(wi, wo) |cos wo| per channel (and pdf(wo | wi)) and run `microsim check-eval` on the result\n");
  return kExitOk;
}

CommandRegistration bsdf_queries_registration{"bsdf-queries", [](CLI::App& app) {
  auto a = std::make_shared<QueryArgs>();
  auto* sub = app.add_subcommand(
      "bsdf-queries",
      "Write the pairs (wi, wo) a renderer fills in with its eval() for `microsim check-eval`: views at 0, 30, 60, 80 "
      "and 89.9 deg (and from inside a dielectric), wo stratified over the sphere, and the edge cases renderers get "
      "wrong (the mirror direction, wo = wi, wo = -wi, grazing wo, the refraction through the mean surface, and with "
      "--alpha directions in the lobe). Query the BSDF at the ends of its alpha range too. Exit 0 written, 2 bad usage.");
  sub->add_option("--bsdf", a->bsdf, "mirror, conductor:ETA,K or dielectric:ETA (a dielectric's queries cover both sides)")
      ->required();
  sub->add_option("--alpha", a->alpha, "also query wo in the lobe of this GGX roughness (AX or AX,AY)");
  sub->add_option("--out", a->out, "the query file, .npy (N, 6): wi_x wi_y wi_z wo_x wo_y wo_z per row")->required();
  add_number_option(sub, "--per-view", a->per_view, integer(2, 1 << 20), "stratified wo per view")->default_str("512");
  add_number_option(sub, "--seed", a->seed, whole(), "seed of the jitter")->default_str("1");
  sub->add_flag("--float32", a->float32, "write float32 (default float64)");
  on_selected(sub, [a] { return run_queries(*a); });
}};

}  // namespace
}  // namespace microsim::app
