// scatter: the anisotropic GGX mirror's (F = 1) energy table from the Smith random walk (Heitz, Hanika, d'Eon,
// Dachsbacher 2016, "Multiple-Scattering Microfacet BSDFs with the Smith Model": every order), beside the
// analytic single-scattering table of scatter/albedo_anisotropic.h (same nodes: Gauss-Legendre in mu on [0, 1]
// and in phi on [0, pi / 2], phi from the alpha_x axis).
//
// A mirror loses nothing: every walk leaves (or stops at the order cap), so the every-order E is 1 less the
// unfinished weight. What the walk adds is the split of that 1 into
//   E1    order 1: the single scattering the analytic table computes by quadrature (the same integral, sampled);
//   E_ms  orders >= 2: the multiple scattering a compensation lobe must return (Kulla & Conty 2017: 1 - E1);
// per node with standard errors (one walk of `paths` paths per node, from its own seed: albedo_cell_seed of
// (alpha pair, node)), and their hemispherical averages X_avg = 2 sum_j w_j mu_j sum_k v_k X(mu_j, phi_k) with
// SE_avg = 2 sqrt(sum (w_j mu_j v_k SE_jk)^2) (independent nodes; the rules' own error is not in it).
// Nodes run one after another, each node's paths on the block runner: the same seed gives the same table
// whatever run.threads. Never prints.
#pragma once

#include "core/estimate.h"
#include "core/run_control.h"
#include "scatter/albedo_anisotropic.h"
#include "scatter/scatter_setup.h"
#include "scatter/smith_walk.h"

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace microsim {

struct AnisotropicWalkRequest : AnisotropicAxes {
  std::uint64_t paths = 100'000;      // per node, >= 1
  std::uint64_t seed = 1;
  int max_order = kDefaultMaxOrder;   // in [1, kMaxOrderCap]
  WalkKernel walk_kernel = WalkKernel::scalar;  // scatter/smith_walk.h (lanes: other random numbers, same walk)
  RunControl run;                     // threads, cancel; progress "anisotropic walk table" in paths
};

// The quantities of a node, in this order.
inline constexpr std::array<const char*, 4> kAnisotropicWalkQuantities{"E", "E1", "E_ms", "unfinished"};
using AnisotropicWalkNode = std::array<Estimate, 4>;

struct AnisotropicWalkTable : AnisotropicNodes {
  AnisotropicWalkRequest request;  // as given, without its RunControl
  std::vector<AnisotropicWalkNode> cells;    // [((ix * alphas_y + iy) * mus + j) * phis + k]
  std::vector<AnisotropicWalkNode> average;  // [ix * alphas_y + iy]
  double seconds = 0;
  std::size_t index(std::size_t ix, std::size_t iy, std::size_t j, std::size_t k) const {
    return ((ix * request.alphas_y.size() + iy) * mus.size() + j) * phis.size() + k;
  }
};

// The table: std::invalid_argument naming the bad value; nullopt when cancelled.
std::optional<AnisotropicWalkTable> anisotropic_walk_table(const AnisotropicWalkRequest& request);
// One line per node: alpha_x,alpha_y,mu,phi, then per quantity Q its Q,Q_se, then per quantity Q_avg,Q_avg_se;
// after a header and `#` comments.
std::string anisotropic_walk_csv(const AnisotropicWalkTable& table);
// kind "anisotropic walk table": the axes and weights, paths, seed, max_order, walk_kernel, seconds, and per
// quantity Q: Q {value, error} nested [alpha_x][alpha_y][mu][phi] and Q_avg {value, error} nested [alpha_x][alpha_y].
nlohmann::json anisotropic_walk_json(const AnisotropicWalkTable& table);

}  // namespace microsim
