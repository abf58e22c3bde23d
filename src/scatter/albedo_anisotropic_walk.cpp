#include "scatter/albedo_anisotropic_walk.h"

#include "core/exact_sum.h"
#include "core/wall_clock.h"
#include "scatter/albedo_table.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string_view>

namespace microsim {

namespace {

void check_walk_request(const AnisotropicWalkRequest& r) {
  check_anisotropic_axes(r);
  if (r.paths == 0) throw std::invalid_argument("anisotropic walk table: 0 paths per node");
  if (r.max_order < 1 || r.max_order > kMaxOrderCap)
    throw std::invalid_argument(fmt::format("anisotropic walk table: max_order {} outside [1, {}]", r.max_order, kMaxOrderCap));
}

// Orders >= 2 of channel 0: the per-path weight of a path is in exactly one order bin, so the bins' weights
// and squared weights add to the sums of the multiple-scattering weight per path.
Estimate multiple_scattering(const ScatterHistogram& h) {
  ExactSum w, w2;
  for (int k = 1; k < kScatterOrderBins; ++k) {
    const Histogram& bins = h.histogram(0, k);
    for (std::size_t b = 0; b < bins.size(); ++b) {
      w += bins.exact_weight(b);
      w2 += bins.exact_weight_squared(b);
    }
  }
  return mean_per_path(w.value(), w2.value(), h.paths());
}

// The options of node c (of `nodes`) at (mu, phi): its view, seed, paths; progress in paths of the whole table.
ScatterOptions node_options(const AnisotropicWalkRequest& r, std::size_t pair, std::size_t node, std::size_t c,
                            std::size_t nodes, double mu, double phi) {
  return albedo_cell_walk(anisotropic_view(mu, phi), r.paths,
                          albedo_cell_seed(r.seed, pair, node), r.max_order, r.run, "anisotropic walk table",
                          c * r.paths, nodes * r.paths);
}

// The hemispherical averages of every alpha pair (the header's rule and its standard error).
void add_averages(AnisotropicWalkTable& t) {
  const std::size_t nm = t.mus.size(), np = t.phis.size();
  for (std::size_t pair = 0; pair < t.request.alphas_x.size() * t.request.alphas_y.size(); ++pair) {
    AnisotropicWalkNode avg{};
    for (std::size_t q = 0; q < avg.size(); ++q) {
      double variance = 0;
      for (std::size_t j = 0; j < nm; ++j)
        for (std::size_t k = 0; k < np; ++k) {
          const double w = t.average_weight(j, k);
          const Estimate& e = t.cells[(pair * nm + j) * np + k][q];
          avg[q].value += w * e.value;
          variance += (w * e.standard_error) * (w * e.standard_error);
        }
      avg[q].standard_error = std::sqrt(variance);
    }
    t.average.push_back(avg);
  }
}

}  // namespace

std::optional<AnisotropicWalkTable> anisotropic_walk_table(const AnisotropicWalkRequest& r) {
  check_walk_request(r);
  const auto start = std::chrono::steady_clock::now();
  AnisotropicWalkTable t;
  t.request = r;
  t.request.run = {};
  static_cast<AnisotropicNodes&>(t) = anisotropic_nodes(r);
  const std::size_t ny = r.alphas_y.size(), nm = t.mus.size(), np = t.phis.size();
  const std::size_t nodes = r.alphas_x.size() * ny * nm * np;
  for (std::size_t c = 0; c < nodes; ++c) {
    if (r.run.cancelled()) return std::nullopt;
    const std::size_t pair = c / (nm * np), node = c % (nm * np);
    const SmithMicrosurface surface{NdfKind::ggx, r.alphas_x[pair / ny], r.alphas_y[pair % ny],
                                    HeightDistribution::uniform};
    const ScatterOptions o = node_options(r, pair, node, c, nodes, t.mus[node / np], t.phis[node % np]);
    const ScatterHistogram h = smith_walk_scatter(surface, o, r.walk_kernel);
    if (h.partial) return std::nullopt;
    t.cells.push_back({h.albedo(0, -1), h.albedo(0, 0), multiple_scattering(h), h.unfinished(0)});
  }
  add_averages(t);
  t.seconds = seconds_since(start);
  return t;
}

std::string anisotropic_walk_csv(const AnisotropicWalkTable& t) {
  std::string s = fmt::format(
      "# microsim anisotropic walk table: GGX mirror (F = 1), the Smith random walk (Heitz et al. 2016), {} paths per "
      "node, seed {}, max order {}, kernel {}\n# E: every order; E1: order 1; E_ms: orders >= 2; unfinished: the weight "
      "left at the order cap; _se: standard errors. phi from the alpha_x axis; Gauss-Legendre nodes in mu on [0, 1] "
      "and phi on [0, pi/2]; _avg: 2 int E mu dmu dphi / pi\nalpha_x,alpha_y,mu,phi",
      t.request.paths, t.request.seed, t.request.max_order, to_string(t.request.walk_kernel));
  for (const char* q : kAnisotropicWalkQuantities) s += fmt::format(",{0},{0}_se", q);
  for (const char* q : kAnisotropicWalkQuantities) s += fmt::format(",{0}_avg,{0}_avg_se", q);
  s += "\n";
  const std::size_t ny = t.request.alphas_y.size();
  for (std::size_t c = 0; c < t.cells.size(); ++c) {
    const std::size_t np = t.phis.size(), nm = t.mus.size(), pair = c / (nm * np), j = (c / np) % nm, k = c % np;
    s += fmt::format("{:.9g},{:.9g},{:.17g},{:.17g}", t.request.alphas_x[pair / ny], t.request.alphas_y[pair % ny],
                     t.mus[j], t.phis[k]);
    for (const Estimate& e : t.cells[c]) s += fmt::format(",{:.9g},{:.3g}", e.value, e.standard_error);
    for (const Estimate& e : t.average[pair]) s += fmt::format(",{:.9g},{:.3g}", e.value, e.standard_error);
    s += "\n";
  }
  return s;
}

nlohmann::json anisotropic_walk_json(const AnisotropicWalkTable& t) {
  const AnisotropicWalkRequest& r = t.request;
  nlohmann::json j = {{"kind", "anisotropic walk table"}, {"model", "smith-walk"}, {"alphas_x", r.alphas_x},
                      {"alphas_y", r.alphas_y}, {"mus", t.mus}, {"mu_weights", t.mu_weights}, {"phis", t.phis},
                      {"phi_weights", t.phi_weights}, {"paths", r.paths}, {"seed", r.seed},
                      {"max_order", r.max_order}, {"walk_kernel", to_string(r.walk_kernel)}, {"seconds", t.seconds}};
  for (std::size_t q = 0; q < kAnisotropicWalkQuantities.size(); ++q) {
    nlohmann::json value = nlohmann::json::array(), error = nlohmann::json::array();
    nlohmann::json avg_value = nlohmann::json::array(), avg_error = nlohmann::json::array();
    for (std::size_t ix = 0; ix < r.alphas_x.size(); ++ix) {
      nlohmann::json vx = nlohmann::json::array(), ex = nlohmann::json::array(), av, ae;
      for (std::size_t iy = 0; iy < r.alphas_y.size(); ++iy) {
        std::vector<std::vector<double>> v(t.mus.size()), e(t.mus.size());
        for (std::size_t m = 0; m < t.mus.size(); ++m)
          for (std::size_t k = 0; k < t.phis.size(); ++k) {
            v[m].push_back(t.cells[t.index(ix, iy, m, k)][q].value);
            e[m].push_back(t.cells[t.index(ix, iy, m, k)][q].standard_error);
          }
        vx.push_back(v);
        ex.push_back(e);
        av.push_back(t.average[ix * r.alphas_y.size() + iy][q].value);
        ae.push_back(t.average[ix * r.alphas_y.size() + iy][q].standard_error);
      }
      value.push_back(vx);
      error.push_back(ex);
      avg_value.push_back(av);
      avg_error.push_back(ae);
    }
    const std::string name = kAnisotropicWalkQuantities[q];
    j[name] = {{"value", value}, {"error", error}};
    j[name + "_avg"] = {{"value", avg_value}, {"error", avg_error}};
  }
  return j;
}

}  // namespace microsim
