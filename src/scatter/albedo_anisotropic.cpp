#include "scatter/albedo_anisotropic.h"

#include "core/wall_clock.h"
#include "microfacet/ggx.h"
#include "microfacet/material.h"
#include "scatter/albedo_table.h"
#include "scatter/parallel_cells.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace microsim {

namespace {

void check_anisotropic_alphas(const char* what, const std::vector<double>& alphas) {
  if (alphas.empty()) throw std::invalid_argument(fmt::format("anisotropic albedo: no {}", what));
  for (const double a : alphas)
    if (!(a >= kMinAlbedoAlpha && a <= kMaxAlbedoAlpha))
      throw std::invalid_argument(
          fmt::format("anisotropic albedo: {} {} outside [{}, {}]", what, a, kMinAlbedoAlpha, kMaxAlbedoAlpha));
}

}  // namespace

void check_anisotropic_axes(const AnisotropicAxes& a) {
  check_anisotropic_alphas("alpha_x", a.alphas_x);
  check_anisotropic_alphas("alpha_y", a.alphas_y);
  if (a.mus < kMinAlbedoMus || a.mus > kMaxAlbedoMus)
    throw std::invalid_argument(fmt::format("anisotropic albedo: {} mus outside [{}, {}]", a.mus, kMinAlbedoMus, kMaxAlbedoMus));
  if (a.phis < 1 || a.phis > 64) throw std::invalid_argument(fmt::format("anisotropic albedo: {} phis outside [1, 64]", a.phis));
}

namespace {

void check_anisotropic_request(const AnisotropicAlbedoRequest& r) {
  check_anisotropic_axes(r);
  if (!(r.tolerance >= 1e-13 && r.tolerance <= 1e-2))
    throw std::invalid_argument(fmt::format("anisotropic albedo: tolerance {} outside [1e-13, 1e-2]", r.tolerance));
}

AnisotropicAlbedoTable empty_anisotropic_table(const AnisotropicAlbedoRequest& r) {
  AnisotropicAlbedoTable t;
  t.alphas_x = r.alphas_x;
  t.alphas_y = r.alphas_y;
  t.tolerance = r.tolerance;
  static_cast<AnisotropicNodes&>(t) = anisotropic_nodes(r);
  return t;
}

}  // namespace

AnisotropicNodes anisotropic_nodes(const AnisotropicAxes& axes) {
  const MuGrid mu = gauss_legendre_mus(axes.mus), phi = gauss_legendre_mus(axes.phis);
  AnisotropicNodes n{mu.mus, mu.weights, {}, phi.weights};
  for (const double p : phi.mus) n.phis.push_back(p * std::numbers::pi / 2);
  return n;
}

Vec3<double> anisotropic_view(double mu, double phi) {
  const double s = std::sqrt(std::max(0.0, 1 - mu * mu));
  return {s * std::cos(phi), s * std::sin(phi), mu};
}

Estimate anisotropic_mirror_albedo(double ax, double ay, double mu, double phi, double tolerance) {
  return single_scattering_albedo(GGX<double>(ax, ay), Material::mirror(), 0, anisotropic_view(mu, phi), tolerance).total();
}

std::optional<AnisotropicAlbedoTable> anisotropic_albedo_table(const AnisotropicAlbedoRequest& r) {
  check_anisotropic_request(r);
  const auto start = std::chrono::steady_clock::now();
  AnisotropicAlbedoTable t = empty_anisotropic_table(r);
  const std::size_t ny = t.alphas_y.size(), nm = t.mus.size(), np = t.phis.size();
  t.cells.resize(t.alphas_x.size() * ny * nm * np);
  std::atomic<std::uint64_t> done{0};
  if (!parallel_cells(t.cells.size(), r.run, "anisotropic albedo table", done, t.cells.size(), [&](std::size_t c) {
        const std::size_t k = c % np, j = (c / np) % nm, iy = (c / (np * nm)) % ny, ix = c / (np * nm * ny);
        t.cells[c] = anisotropic_mirror_albedo(t.alphas_x[ix], t.alphas_y[iy], t.mus[j], t.phis[k], r.tolerance);
      }))
    return std::nullopt;
  for (std::size_t ixy = 0; ixy < t.alphas_x.size() * ny; ++ixy) {
    Estimate avg;
    for (std::size_t j = 0; j < nm; ++j)
      for (std::size_t k = 0; k < np; ++k) {
        const double w = t.average_weight(j, k);
        avg.value += w * t.cells[(ixy * nm + j) * np + k].value;
        avg.standard_error += w * t.cells[(ixy * nm + j) * np + k].standard_error;
      }
    t.average.push_back(avg);
  }
  t.seconds = seconds_since(start);
  return t;
}

std::string anisotropic_albedo_csv(const AnisotropicAlbedoTable& t) {
  std::string s = fmt::format("# microsim anisotropic albedo table: GGX mirror (F = 1), analytic single scattering\n"
                              "# phi from the alpha_x axis; Gauss-Legendre nodes in mu on [0, 1] and phi on [0, pi/2]; "
                              "quadrature tolerance {:g}\n",
                              t.tolerance);
  s += "alpha_x,alpha_y,mu,phi,E,E_error,E_avg,E_avg_error\n";
  for (std::size_t ix = 0; ix < t.alphas_x.size(); ++ix)
    for (std::size_t iy = 0; iy < t.alphas_y.size(); ++iy)
      for (std::size_t j = 0; j < t.mus.size(); ++j)
        for (std::size_t k = 0; k < t.phis.size(); ++k) {
          const Estimate& e = t.cells[t.index(ix, iy, j, k)];
          const Estimate& a = t.average[ix * t.alphas_y.size() + iy];
          s += fmt::format("{:.9g},{:.9g},{:.17g},{:.17g},{:.12g},{:.3g},{:.12g},{:.3g}\n", t.alphas_x[ix],
                           t.alphas_y[iy], t.mus[j], t.phis[k], e.value, e.standard_error, a.value, a.standard_error);
        }
  return s;
}

nlohmann::json anisotropic_albedo_json(const AnisotropicAlbedoTable& t) {
  nlohmann::json value = nlohmann::json::array(), error = nlohmann::json::array();
  nlohmann::json avg_value = nlohmann::json::array(), avg_error = nlohmann::json::array();
  for (std::size_t ix = 0; ix < t.alphas_x.size(); ++ix) {
    nlohmann::json vx = nlohmann::json::array(), ex = nlohmann::json::array(), av = nlohmann::json::array(),
                   ae = nlohmann::json::array();
    for (std::size_t iy = 0; iy < t.alphas_y.size(); ++iy) {
      nlohmann::json vy = nlohmann::json::array(), ey = nlohmann::json::array();
      for (std::size_t j = 0; j < t.mus.size(); ++j) {
        std::vector<double> v, e;
        for (std::size_t k = 0; k < t.phis.size(); ++k) {
          v.push_back(t.cells[t.index(ix, iy, j, k)].value);
          e.push_back(t.cells[t.index(ix, iy, j, k)].standard_error);
        }
        vy.push_back(v);
        ey.push_back(e);
      }
      vx.push_back(vy);
      ex.push_back(ey);
      av.push_back(t.average[ix * t.alphas_y.size() + iy].value);
      ae.push_back(t.average[ix * t.alphas_y.size() + iy].standard_error);
    }
    value.push_back(vx);
    error.push_back(ex);
    avg_value.push_back(av);
    avg_error.push_back(ae);
  }
  return {{"kind", "anisotropic albedo table"}, {"alphas_x", t.alphas_x}, {"alphas_y", t.alphas_y}, {"mus", t.mus},
          {"mu_weights", t.mu_weights}, {"phis", t.phis}, {"phi_weights", t.phi_weights}, {"tolerance", t.tolerance},
          {"seconds", t.seconds}, {"E", {{"value", value}, {"error", error}}},
          {"E_avg", {{"value", avg_value}, {"error", avg_error}}}};
}

}  // namespace microsim
