#include "scatter/albedo_glass_walk.h"

#include "core/wall_clock.h"
#include "microfacet/material.h"
#include "microfacet/ggx.h"
#include "scatter/albedo_table.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <string_view>

namespace microsim {

namespace {

constexpr const char* kGlassWalkMasking =
    "order 1 is single scattering with the Smith microsurface's own masking (as `albedo --model analytic "
    "--material dielectric:ETA`), not Cycles' height-correlated reflection form for both lobes: compare order 1 "
    "with the former, not with the glass layout table";

GlassWalkTable empty_glass_walk(const GlassWalkRequest& r) {
  GlassWalkTable t;
  t.request = r;
  t.request.run = {};
  const GlassLayout& l = r.layout;
  fill_glass_axes(t, l);
  return t;
}

// The options of node (x, y, z): its view (from inside for the -inv layout), material, seed, paths; progress
// reported from `before` of `total` paths.
ScatterOptions node_options(const GlassWalkRequest& r, std::size_t x, std::size_t y, std::size_t z,
                            std::uint64_t before, std::uint64_t total) {
  const GlassLayout& l = r.layout;
  ScatterOptions o = albedo_cell_walk(albedo_view(glass_layout_coordinate(int(y), l.mu_nodes), l.inverse), r.paths,
                                      albedo_cell_seed(r.seed, z, y * std::size_t(l.roughness_nodes) + x),
                                      r.max_order, r.run, "glass walk table", before, total);
  o.material = Material::dielectric(glass_layout_ior(glass_layout_index_coordinate(int(z), l.index_nodes)));
  return o;
}

// The node's quantities (kGlassWalkQuantities) from its histogram, whose "reflected" bins are the upper
// hemisphere: from inside, what is reflected leaves downward.
GlassWalkNode node_quantities(const ScatterHistogram& h, bool inside) {
  const ScatterSide back = inside ? ScatterSide::transmitted : ScatterSide::reflected;
  const ScatterSide through = inside ? ScatterSide::reflected : ScatterSide::transmitted;
  return {h.albedo(0, -1),          h.albedo(0, -1, back), h.albedo(0, -1, through), h.albedo(0, 0),
          h.albedo(0, 0, back),     h.albedo(0, 0, through), h.unfinished(0)};
}

}  // namespace

namespace {

void check_glass_walk_request(const GlassWalkRequest& r) {
  if (r.paths == 0) throw std::invalid_argument("glass walk table: 0 paths per node");
  if (r.max_order < 1 || r.max_order > kMaxOrderCap)
    throw std::invalid_argument(fmt::format("glass walk table: max_order {} outside [1, {}]", r.max_order, kMaxOrderCap));
}

// Node (x, y, z), its progress from `before` of `total` paths.
std::optional<GlassWalkNode> walk_node(const GlassWalkRequest& r, std::size_t x, std::size_t y, std::size_t z,
                                       std::uint64_t before, std::uint64_t total) {
  const GlassLayout& l = r.layout;
  if (x >= std::size_t(l.roughness_nodes) || y >= std::size_t(l.mu_nodes) || z >= std::size_t(l.index_nodes))
    throw std::invalid_argument(fmt::format("glass walk node ({}, {}, {}) outside the {} layout", x, y, z, l.name));
  const double r0 = glass_layout_coordinate(int(x), l.roughness_nodes), alpha = std::max(r0 * r0, kMinAlpha);
  const SmithMicrosurface surface{NdfKind::ggx, alpha, alpha, HeightDistribution::uniform};
  const ScatterHistogram h = smith_walk_scatter(surface, node_options(r, x, y, z, before, total), r.walk_kernel);
  if (h.partial) return std::nullopt;
  return node_quantities(h, l.inverse);
}

}  // namespace

std::optional<GlassWalkNode> glass_walk_node(const GlassWalkRequest& r, std::size_t x, std::size_t y, std::size_t z) {
  check_glass_walk_request(r);
  return walk_node(r, x, y, z, 0, r.paths);
}

std::optional<GlassWalkTable> glass_walk_table(const GlassWalkRequest& r) {
  check_glass_walk_request(r);
  const auto start = std::chrono::steady_clock::now();
  GlassWalkTable t = empty_glass_walk(r);
  const std::size_t nx = t.alphas.size(), ny = t.mus.size(), nodes = nx * ny * t.iors.size();
  for (std::size_t c = 0; c < nodes; ++c) {
    if (r.run.cancelled()) return std::nullopt;
    const std::optional<GlassWalkNode> cell =
        walk_node(r, c % nx, (c / nx) % ny, c / (nx * ny), c * r.paths, nodes * r.paths);
    if (!cell) return std::nullopt;
    t.cells.push_back(*cell);
  }
  t.seconds = seconds_since(start);
  return t;
}

std::string glass_walk_csv(const GlassWalkTable& t) {
  const GlassWalkRequest& r = t.request;
  std::string s = fmt::format(
      "# microsim glass walk table on the {} layout's nodes: {}\n# the Smith random walk (Heitz et al. 2016), {} "
      "paths per node, seed {}, max order {}, kernel {}; _se: standard errors; E_R back to the light's side, E_T "
      "through; E1: order 1\n# masking: {}\nx,y,z,roughness,alpha,mu,t,ior",
      r.layout.name, r.layout.summary, r.paths, r.seed, r.max_order, to_string(r.walk_kernel), kGlassWalkMasking);
  for (const char* q : kGlassWalkQuantities) s += fmt::format(",{0},{0}_se", q);
  s += "\n";
  for (std::size_t z = 0; z < t.iors.size(); ++z)
    for (std::size_t y = 0; y < t.mus.size(); ++y)
      for (std::size_t x = 0; x < t.alphas.size(); ++x) {
        s += fmt::format("{},{},{},{:.9g},{:.9g},{:.9g},{:.9g},{:.12g}", x, y, z, t.roughness[x], t.alphas[x],
                         t.mus[y], t.index_coordinates[z], t.iors[z]);
        for (const Estimate& e : t.cells[t.index(x, y, z)]) s += fmt::format(",{:.9g},{:.3g}", e.value, e.standard_error);
        s += "\n";
      }
  return s;
}

nlohmann::json glass_walk_json(const GlassWalkTable& t) {
  const GlassWalkRequest& r = t.request;
  nlohmann::json j = {{"kind", "glass walk table"}, {"model", "smith-walk"}, {"layout", r.layout.name},
                      {"summary", r.layout.summary}, {"source", r.layout.source}, {"masking", kGlassWalkMasking},
                      {"roughness", t.roughness}, {"alphas", t.alphas}, {"mus", t.mus},
                      {"index_coordinates", t.index_coordinates}, {"iors", t.iors}, {"paths", r.paths},
                      {"seed", r.seed}, {"max_order", r.max_order}, {"walk_kernel", to_string(r.walk_kernel)},
                      {"seconds", t.seconds}};
  for (std::size_t q = 0; q < kGlassWalkQuantities.size(); ++q) {
    nlohmann::json value = nlohmann::json::array(), error = nlohmann::json::array();
    for (std::size_t z = 0; z < t.iors.size(); ++z) {
      std::vector<std::vector<double>> v(t.mus.size()), e(t.mus.size());
      for (std::size_t y = 0; y < t.mus.size(); ++y)
        for (std::size_t x = 0; x < t.alphas.size(); ++x) {
          v[y].push_back(t.cells[t.index(x, y, z)][q].value);
          e[y].push_back(t.cells[t.index(x, y, z)][q].standard_error);
        }
      value.push_back(v);
      error.push_back(e);
    }
    j[kGlassWalkQuantities[q]] = {{"value", value}, {"error", error}};
  }
  return j;
}

}  // namespace microsim
