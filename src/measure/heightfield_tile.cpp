// measure: the explicit tile of a heightfield measurement (heightfield_tile.h).
#include "measure/heightfield_tile.h"

#include "core/parse.h"
#include "microgeom/assembly.h"

#include <fmt/core.h>

#include <algorithm>
#include <stdexcept>
#include <string>

namespace microsim {
namespace {

double metadata_number(const microgeom::Heightfield& field, const std::string& key, double otherwise) {
  const auto it = field.metadata.find(key);
  return it == field.metadata.end() ? otherwise : try_parse_double(it->second).value_or(otherwise);
}

nlohmann::json fit_json(const VndfComparison& c) {
  return {{"binning", c.binning},
          {"bins", c.bins},
          {"total_variation", c.tv_analytic},
          {"noise_floor_tv", c.tv_noise},
          {"tv_own_ndf", c.tv_empirical},
          {"chi2", {{"statistic", c.chi2_analytic}, {"dof", c.dof_analytic}, {"p_value", c.p_value_analytic}}},
          {"chi2_own_ndf", {{"statistic", c.chi2_empirical}, {"dof", c.dof_empirical}, {"p_value", c.p_value_empirical}}}};
}

}  // namespace

double alpha_anisotropy(const std::pair<double, double>& alpha) {
  return std::max(alpha.first, alpha.second) / std::min(alpha.first, alpha.second);
}

SurfaceDecision plan_assembly_tile(const std::string& assembly, SizeRequest size, const std::pair<double, double>& alpha,
                                   std::uint64_t seed) {
  SurfaceDecision out;
  const microgeom::AssemblyInfo& info = *microgeom::find_assembly(assembly);  // the spec checked the name
  const bool ggx = info.reference == NdfKind::ggx;
  SurfacePlan& p = out.plan;
  p.kind = "assembly";
  p.name = assembly;
  p.ndf = to_string(info.reference);
  p.seed = seed;
  size.min_resolution = ggx ? microgeom::kMinGgxCheckedResolution : kMinSurfaceResolution;
  const SurfaceSize chosen = choose_surface_size(builtin_trade_table(), size);
  p.reason = (ggx ? "" : "the table was measured on smith (GGX): taken for this assembly too; ") + chosen.reason;
  if (!chosen.found) {
    out.why = chosen.reason;
    return out;
  }
  p.resolution = chosen.resolution;
  p.corr_cells = chosen.corr_cells;
  p.ndf_match = chosen.ndf_match;
  p.bias = chosen.bias;
  p.hash = surface_key_hash(surface_key(p, alpha));
  try {
    microgeom::check_supported_range(assembly_params(surface_key(p, alpha)));
  } catch (const std::invalid_argument& e) {  // OutsideSupportedRange, or what validate() refuses
    out.why = fmt::format("assembly {} at alpha ({}, {}): {}", p.name, alpha.first, alpha.second, e.what());
    return out;
  }
  out.runnable = true;
  return out;
}

SurfaceDecision plan_heightmap_tile(const std::string& path, double target_tv, double anisotropy, SurfaceCache& cache) {
  SurfaceDecision out;
  const microgeom::Heightfield& field = cache.heightmap(path);
  SurfacePlan& p = out.plan;
  p.kind = "heightmap";
  p.name = path;
  p.resolution = field.resolution();
  p.corr_cells = metadata_number(field, "corr_cells", 0);
  const auto match = field.metadata.find("ndf_match");
  p.ndf_match = match != field.metadata.end() ? match->second : "radial";
  const auto ndf = field.metadata.find("reference_ndf");
  p.ndf = ndf != field.metadata.end() ? ndf->second : "ggx";
  p.hash = cache.heightmap_digest(path);
  const auto predicted = p.corr_cells > 0 ? predicted_bias(builtin_trade_table(), p.resolution, p.corr_cells,
                                                           p.ndf_match, anisotropy)
                                          : std::nullopt;
  if (predicted) {
    p.bias = predicted->bias;
    p.reason = predicted->reason;
    if (p.bias > kBiasShare * target_tv)
      p.reason += fmt::format("; ABOVE {} x target TV {} = {:.2e}: the histogram resolves the target but the tile's "
                              "bias may exceed its share", kBiasShare, target_tv, kBiasShare * target_tv);
  } else {
    p.reason = p.corr_cells > 0 ? fmt::format("the heightmap's own size ({}^2, l {} cells): narrower than every row of "
                                              "the trade table: its bias is not predicted", p.resolution, p.corr_cells)
                                : fmt::format("the heightmap's own size ({}^2); it has no corr_cells attribute: its "
                                              "bias is not predicted", p.resolution);
  }
  if (match == field.metadata.end()) p.reason += " (no ndf_match attribute: taken as radial, the larger bias)";
  out.runnable = true;
  return out;
}

SurfaceKey surface_key(const SurfacePlan& plan, const std::pair<double, double>& alpha) {
  return {plan.name, plan.ndf, alpha.first, alpha.second, plan.resolution, plan.corr_cells, plan.ndf_match, plan.seed};
}

const microgeom::Heightfield& tile_surface(const SurfacePlan& p, const std::pair<double, double>& alpha, SurfaceCache& cache,
                                          const RunControl& run) {
  if (p.kind != "heightmap") return cache.surface_for(surface_key(p, alpha), run);
  const std::string& digest = cache.heightmap_digest(p.name);
  if (!p.hash.empty() && digest != p.hash)  // a plan of an earlier version has no digest
    throw std::invalid_argument(fmt::format("the heightmap {} is not the one planned: its heights' digest is {}, the "
                                            "plan's {} (changed since the plan, or another file on this node)",
                                            p.name, digest, p.hash));
  return cache.heightmap(p.name);
}

std::string surface_label(const SurfacePlan& plan) {
  return plan.kind == "heightmap" ? plan.name : fmt::format("assembly {} {}", plan.name, plan.hash);
}

nlohmann::json heightfield_vndf_values(const HeightfieldVndf& m, const std::vector<std::uint64_t>& unbinned,
                                       const SurfacePlan& plan) {
  nlohmann::json fits = nlohmann::json::array();
  double own = 0;
  for (const VndfComparison& c : m.comparisons) {
    fits.push_back(fit_json(c));
    own = std::max(own, c.tv_empirical);
  }
  const HeightfieldVndfDiagnostics& g = m.diagnostics;
  return {{"analysis", {{"binnings", fits}, {"reference", "Smith's D_v with the analytic NDF"}}},
          {"rays", m.histogram.rays},
          {"hits", m.histogram.hits},
          {"expected_hit_fraction", 1.0},
          {"total_variation", heightfield_total_variation(m)},
          {"noise_floor_tv", heightfield_noise_floor(m)},
          {"unbinned", unbinned},
          {"heightfield", {{"surface", surface_label(plan)},
                           {"resolution", plan.resolution},
                           {"predicted_bias", plan.bias},
                           {"tv_own_ndf", own},
                           {"reference_source", m.reference_source},
                           {"backfacing", g.backfacing},
                           {"edge_grazes", g.edge_grazes},
                           {"leaked", g.leaked},
                           {"unresolved", g.unresolved}}}};
}

}  // namespace microsim
