#include "scatter/albedo_glass_layout.h"
#include "scatter/albedo_table_io.h"
#include "scatter/parallel_cells.h"

#include "core/wall_clock.h"
#include "microfacet/ggx.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace microsim {

namespace {

GlassLayout cycles_glass(bool inverse) {
  GlassLayout l;
  l.name = inverse ? "cycles-glass-inv" : "cycles-glass";
  l.quantity = inverse ? "ggx_glass_inv_E" : "ggx_glass_E";
  l.summary = fmt::format("Blender Cycles {} (16 x 16 x 16 over sqrt(alpha), mu and t = sqrt((ior - 1) / (ior + 1)){}) "
                          "and {}Eavg: a GGX dielectric's E = E_R + E_T",
                          l.quantity, inverse ? ", light from inside: relative index 1 / ior" : "",
                          inverse ? "ggx_glass_inv_" : "ggx_glass_");
  // Generator: cycles_precompute (precompute_ggx_glass_E, the "ggx_glass_E" / "ggx_glass_inv_E" terms:
  // nx = ny = nz = 16, ior_from_F0(sqr(sqr(t))), the inverse at 1 / ior); reader: microfacet_ggx_preserve_energy
  // (z = sqrt(|ior - 1| / (ior + 1)), lookup_table_read_3D) and lookup_table.h.
  l.source = "blender/blender intern/cycles/app/cycles_precompute.cpp, intern/cycles/kernel/closure/bsdf_microfacet.h, "
             "intern/cycles/kernel/util/lookup_table.h";
  l.inverse = inverse;
  return l;
}

constexpr int kGlassAverageNodes = 32;  // Gauss-Legendre nodes of E_avg's mu integral

// Cycles computes in float, where its first index node (ior 1 + 2e-8) is 1 exactly: the interface is then
// invisible, no reflection and no bending (wo = -wi for every facet), so every visible normal's weight is
// G2 / G1 = (1 + Lambda) / (1 + 2 Lambda) (Heitz 2014 eq. 99, Lambda(wo) = Lambda(wi)), from either side.
SingleScatteringAlbedo glass_reference(double alpha, double mu, double ior, bool inverse, double tolerance) {
  if (float(ior) == 1.0f) {
    const GGX<double> ggx(std::max(alpha, kMinAlpha));
    const double lambda = ggx.Lambda(albedo_view(mu, false));
    SingleScatteringAlbedo a;
    a.transmitted = {(1 + lambda) / (1 + 2 * lambda), 0.0};
    return a;
  }
  return single_scattering_albedo(GGX<double>(std::max(alpha, kMinAlpha)), Material::dielectric(ior), 0,
                                  albedo_view(mu, inverse), tolerance, RefractionMasking::height_correlated);
}

GlassLayoutTable empty_glass_table(const GlassLayout& l, double tolerance) {
  GlassLayoutTable t;
  t.layout = l;
  t.tolerance = tolerance;
  fill_glass_axes(t, l);
  return t;
}

bool fill_glass_averages(GlassLayoutTable& t, const RunControl& run, std::atomic<std::uint64_t>& done,
                         std::uint64_t total) {
  const MuGrid grid = gauss_legendre_mus(kGlassAverageNodes);
  const std::size_t n = grid.mus.size(), nx = t.alphas.size();
  std::vector<Estimate> e(t.iors.size() * nx * n);
  if (!parallel_cells(e.size(), run, "glass layout table", done, total, [&](std::size_t k) {
        const std::size_t z = k / (nx * n), x = (k / n) % nx;
        e[k] = glass_reference(t.alphas[x], grid.mus[k % n], t.iors[z], t.layout.inverse, t.tolerance).total();
      }))
    return false;
  for (std::size_t zx = 0; zx < t.iors.size() * nx; ++zx) {
    Estimate avg;
    for (std::size_t j = 0; j < n; ++j) {
      const double w = 2 * grid.weights[j] * grid.mus[j];
      avg.value += w * e[zx * n + j].value;
      avg.standard_error += w * e[zx * n + j].standard_error;
    }
    t.average.push_back(avg);
  }
  return true;
}

}  // namespace

const std::vector<GlassLayout>& glass_layouts() {
  static const std::vector<GlassLayout> layouts{cycles_glass(false), cycles_glass(true)};
  return layouts;
}

const GlassLayout* find_glass_layout(std::string_view name) {
  for (const GlassLayout& l : glass_layouts())
    if (l.name == name) return &l;
  return nullptr;
}

std::string glass_layout_names() {
  std::string s;
  for (const GlassLayout& l : glass_layouts()) s += (s.empty() ? "" : ", ") + l.name;
  return s;
}

double glass_layout_coordinate(int index, int nodes) { return std::clamp(double(index) / (nodes - 1), 1e-4, 1.0); }
double glass_layout_index_coordinate(int index, int nodes) {
  return std::clamp(double(index) / (nodes - 1), 1e-4, 0.99);
}
double glass_layout_ior(double t) { return (1 + t * t) / (1 - t * t); }

std::optional<GlassLayoutTable> glass_layout_table(const GlassLayout& layout, double tolerance, const RunControl& run,
                                                   bool averages) {
  if (!(tolerance >= 1e-13 && tolerance <= 1e-2))
    throw std::invalid_argument(fmt::format("glass layout table: tolerance {} outside [1e-13, 1e-2]", tolerance));
  const auto start = std::chrono::steady_clock::now();
  GlassLayoutTable t = empty_glass_table(layout, tolerance);
  const std::size_t nx = t.alphas.size(), ny = t.mus.size(), nz = t.iors.size();
  const std::uint64_t total = nx * ny * nz + (averages ? nx * nz * kGlassAverageNodes : 0);
  std::atomic<std::uint64_t> done{0};
  t.cells.resize(nx * ny * nz);
  if (!parallel_cells(t.cells.size(), run, "glass layout table", done, total, [&](std::size_t k) {
        const std::size_t x = k % nx, y = (k / nx) % ny, z = k / (nx * ny);
        t.cells[k] = glass_reference(t.alphas[x], t.mus[y], t.iors[z], layout.inverse, tolerance);
      }))
    return std::nullopt;
  if (averages && !fill_glass_averages(t, run, done, total)) return std::nullopt;
  t.seconds = seconds_since(start);
  return t;
}

double encode_glass_value(double value) {
  return double(float(std::nearbyint(std::clamp(value, 0.0, 1.0) * 1e6) / 1e6));
}

std::string glass_layout_encoded(const GlassLayoutTable& t) {
  std::string s;
  const std::size_t nx = t.alphas.size(), ny = t.mus.size(), nz = t.iors.size();
  for (std::size_t z = 0; z < nz; ++z) {
    if (z > 0) s += "\n";
    for (std::size_t y = 0; y < ny; ++y)
      for (std::size_t x = 0; x < nx; ++x)
        s += fmt::format("{:.6f}{}", encode_glass_value(t.cells[t.index(x, y, z)].total().value),
                         x + 1 < nx ? ", " : "\n");
  }
  return s;
}

std::string glass_layout_average_encoded(const GlassLayoutTable& t) {
  std::string s;
  const std::size_t nx = t.alphas.size();
  for (std::size_t zx = 0; zx < t.average.size(); ++zx)
    s += fmt::format("{:.6f}{}", encode_glass_value(t.average[zx].value), (zx + 1) % nx ? ", " : "\n");
  return s;
}

std::string glass_layout_csv(const GlassLayoutTable& t) {
  std::string s = fmt::format("# microsim glass layout table {}: {}\n# source: {}\n# reference tolerance {:g}; "
                              "errors: quadrature error estimates\n",
                              t.layout.name, t.layout.summary, t.layout.source, t.tolerance);
  s += "x,y,z,roughness,alpha,mu,t,ior,E,E_error,E_R,E_R_error,E_T,E_T_error,E_encoded";
  s += t.average.empty() ? "\n" : ",E_avg,E_avg_error\n";
  const std::size_t nx = t.alphas.size(), ny = t.mus.size(), nz = t.iors.size();
  for (std::size_t z = 0; z < nz; ++z)
    for (std::size_t y = 0; y < ny; ++y)
      for (std::size_t x = 0; x < nx; ++x) {
        const SingleScatteringAlbedo& c = t.cells[t.index(x, y, z)];
        const Estimate e = c.total();
        s += fmt::format("{},{},{},{:.9g},{:.9g},{:.9g},{:.9g},{:.12g},{:.12g},{:.3g},{:.12g},{:.3g},{:.12g},{:.3g},{:.6f}",
                         x, y, z, t.roughness[x], t.alphas[x], t.mus[y], t.index_coordinates[z], t.iors[z], e.value,
                         e.standard_error, c.reflected.value, c.reflected.standard_error, c.transmitted.value,
                         c.transmitted.standard_error, encode_glass_value(e.value));
        if (!t.average.empty())
          s += fmt::format(",{:.12g},{:.3g}", t.average[z * nx + x].value, t.average[z * nx + x].standard_error);
        s += "\n";
      }
  return s;
}

namespace {

// [z][y][x] of one quantity of every node.
template <class F> nlohmann::json glass_nested(const GlassLayoutTable& t, const F& of) {
  nlohmann::json out = nlohmann::json::array();
  for (std::size_t z = 0; z < t.iors.size(); ++z) {
    nlohmann::json slice = nlohmann::json::array();
    for (std::size_t y = 0; y < t.mus.size(); ++y) {
      std::vector<double> row;
      for (std::size_t x = 0; x < t.alphas.size(); ++x) row.push_back(of(t.cells[t.index(x, y, z)]));
      slice.push_back(row);
    }
    out.push_back(slice);
  }
  return out;
}

}  // namespace

nlohmann::json glass_layout_json(const GlassLayoutTable& t) {
  using C = SingleScatteringAlbedo;
  nlohmann::json j{{"kind", "glass layout table"}, {"layout", t.layout.name}, {"summary", t.layout.summary},
                   {"source", t.layout.source}, {"quantity", t.layout.quantity}, {"inverse", t.layout.inverse},
                   {"roughness", t.roughness}, {"alphas", t.alphas}, {"mus", t.mus},
                   {"index_coordinates", t.index_coordinates}, {"iors", t.iors}, {"tolerance", t.tolerance},
                   {"seconds", t.seconds}};
  j["E"] = {{"value", glass_nested(t, [](const C& c) { return c.total().value; })},
            {"error", glass_nested(t, [](const C& c) { return c.total().standard_error; })}};
  j["E_R"] = {{"value", glass_nested(t, [](const C& c) { return c.reflected.value; })},
              {"error", glass_nested(t, [](const C& c) { return c.reflected.standard_error; })}};
  j["E_T"] = {{"value", glass_nested(t, [](const C& c) { return c.transmitted.value; })},
              {"error", glass_nested(t, [](const C& c) { return c.transmitted.standard_error; })}};
  j["E_encoded"] = glass_nested(t, [](const C& c) { return encode_glass_value(c.total().value); });
  if (!t.average.empty()) j["E_avg"] = estimate_rows_json(t.average, t.alphas.size());  // [index][roughness]
  return j;
}

}  // namespace microsim
