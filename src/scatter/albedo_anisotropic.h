// scatter: the energy-compensation table of an anisotropic GGX mirror (F = 1): the directional albedo
// E(mu, phi; alpha_x, alpha_y) of single scattering and its hemispherical average
//   E_avg(alpha_x, alpha_y) = (1 / pi) int_0^{2 pi} int_0^1 E mu dmu dphi,
// the tables Kulla & Conty 2017 build for isotropic roughness, which no renderer ships anisotropic (Enterprise
// PBR reads its isotropic table at sqrt(alpha_x alpha_y); Cycles at sqrt(sqrt(alpha_x alpha_y))).
//
// The view wi = (sqrt(1 - mu^2) cos phi, sqrt(1 - mu^2) sin phi, mu), phi from the alpha_x axis. E is even in
// phi and in pi - phi (the GGX ellipse's two mirror symmetries), so phi in [0, pi / 2] holds every view, and
// the phi average over [0, 2 pi] is that over [0, pi / 2]. Nodes: Gauss-Legendre in mu on [0, 1] (as
// albedo_table.h) and in phi on [0, pi / 2] (E is smooth and periodic in phi); each E the analytic
// single-scattering albedo (single_scattering_albedo: its quadrature over the anisotropic visible normals)
// with its error estimate; E_avg = 2 sum_j w_j mu_j sum_k v_k E(mu_j, phi_k), v_k the phi weights (sum 1),
// errors added (the rules' own error is not in it). The Smith walk's every-order albedo of a mirror is 1
// (every path leaves), so the single-scattering table is the one compensation needs; the walk's split of that 1
// into order 1 and the rest, per node: scatter/albedo_anisotropic_walk.h. Never prints.
#pragma once

#include "core/estimate.h"
#include "core/math.h"
#include "core/run_control.h"

#include <nlohmann/json_fwd.hpp>

#include <optional>
#include <string>
#include <vector>

namespace microsim {

// The axes of an anisotropic table's request (analytic or walk, scatter/albedo_anisotropic_walk.h).
struct AnisotropicAxes {
  std::vector<double> alphas_x{0.25, 0.5, 1.0}, alphas_y{0.25, 0.5, 1.0};  // each in [kMinAlbedoAlpha, kMaxAlbedoAlpha]
  int mus = 16;                // Gauss-Legendre nodes in mu, in [kMinAlbedoMus, kMaxAlbedoMus]
  int phis = 8;                // Gauss-Legendre nodes in phi on [0, pi / 2], in [1, 64]
};

struct AnisotropicAlbedoRequest : AnisotropicAxes {
  double tolerance = 1e-8;     // each node's quadrature, in [1e-13, 1e-2]
  RunControl run;              // threads, cancel; progress "anisotropic albedo table" in nodes
};

// The nodes of an anisotropic table (analytic or walk): Gauss-Legendre in mu on [0, 1] and in phi on [0, pi / 2]
// (phi_weights sum to 1).
struct AnisotropicNodes {
  std::vector<double> mus, mu_weights, phis, phi_weights;
  // The weight of node (j, k) in a hemispherical average (the header's rule): 2 w_j mu_j v_k.
  double average_weight(std::size_t j, std::size_t k) const { return 2 * mu_weights[j] * mus[j] * phi_weights[k]; }
};
AnisotropicNodes anisotropic_nodes(const AnisotropicAxes& axes);
// The view of node (mu, phi): (sqrt(1 - mu^2) cos phi, sqrt(1 - mu^2) sin phi, mu), phi from the alpha_x axis.
Vec3<double> anisotropic_view(double mu, double phi);

struct AnisotropicAlbedoTable : AnisotropicNodes {
  std::vector<double> alphas_x, alphas_y;
  double tolerance = 0;
  std::vector<Estimate> cells;    // [((ix * alphas_y + iy) * mus + j) * phis + k]
  std::vector<Estimate> average;  // [ix * alphas_y + iy]
  double seconds = 0;
  std::size_t index(std::size_t ix, std::size_t iy, std::size_t j, std::size_t k) const {
    return ((ix * alphas_y.size() + iy) * mus.size() + j) * phis.size() + k;
  }
};

// std::invalid_argument naming an alpha outside [kMinAlbedoAlpha, kMaxAlbedoAlpha] (or none), mus outside
// [kMinAlbedoMus, kMaxAlbedoMus], phis outside [1, 64].
void check_anisotropic_axes(const AnisotropicAxes& axes);
// One node: E of the view (mu, phi) (mu in (0, 1]) on GGX(alpha_x, alpha_y), with its error estimate.
Estimate anisotropic_mirror_albedo(double alpha_x, double alpha_y, double mu, double phi, double tolerance);
// The table: std::invalid_argument naming the bad value; nullopt when cancelled.
std::optional<AnisotropicAlbedoTable> anisotropic_albedo_table(const AnisotropicAlbedoRequest& request);
// One line per node: alpha_x,alpha_y,mu,phi,E,E_error,E_avg,E_avg_error, after a header and `#` comments.
std::string anisotropic_albedo_csv(const AnisotropicAlbedoTable& table);
// The same as JSON: kind "anisotropic albedo table", the axes and weights, tolerance, seconds, E {value, error}
// nested [alpha_x][alpha_y][mu][phi] and E_avg {value, error} nested [alpha_x][alpha_y].
nlohmann::json anisotropic_albedo_json(const AnisotropicAlbedoTable& table);

}  // namespace microsim
