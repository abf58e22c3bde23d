#include "scatter/albedo_layout.h"
#include "scatter/parallel_cells.h"

#include "core/parse.h"
#include "core/wall_clock.h"
#include "microfacet/ggx.h"
#include "scatter/albedo_table.h"

#include <fmt/core.h>

#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace microsim {

std::string to_string(LayoutEncoding e) {
  switch (e) {
    case LayoutEncoding::float32: return "float32";
    case LayoutEncoding::six_decimals: return "float32 printed with 6 decimals";
    case LayoutEncoding::half: return "half (IEEE binary16)";
    case LayoutEncoding::unorm16: return "normalised uint16";
  }
  return "?";
}

namespace {

AlbedoLayout cycles_layout() {
  AlbedoLayout l;
  l.name = "cycles";
  l.summary = "Blender Cycles ggx_E (32 x 32 over sqrt(alpha) and mu, nodes on the edges) and ggx_Eavg";
  // Generator: intern/cycles/app/cycles_precompute.cpp (cycles_precompute: rough = x / (nx - 1) and
  // mu = y / (ny - 1) clamped to [1e-4, 1], alpha = rough^2, data[y * nx + x], printed by std::to_string);
  // reader: intern/cycles/kernel/closure/bsdf_microfacet.h (microfacet_ggx_preserve_energy:
  // lookup_table_read_2D(rough, mu, ..., 32, 32), rough = sqrt(sqrt(alpha_x alpha_y))) and
  // intern/cycles/kernel/util/lookup_table.h (x (size - 1), linear between neighbours).
  l.source = "blender/blender intern/cycles/app/cycles_precompute.cpp, intern/cycles/kernel/closure/bsdf_microfacet.h, "
             "intern/cycles/kernel/util/lookup_table.h";
  l.quantity = "ggx_E";
  l.roughness = {32, LayoutPlacement::edges, 1e-4};
  l.mu = {32, LayoutPlacement::edges, 1e-4};
  l.mu_rows = true;
  l.encoding = LayoutEncoding::six_decimals;
  l.has_average = true;
  return l;
}

AlbedoLayout filament_layout() {
  AlbedoLayout l;
  l.name = "filament-dfg";
  l.summary = "Filament DFG LUT, multiscatter form (R = DFG.x, the albedo weighted by (1 - VoH)^5; G = DFG.y, E of "
              "F = 1): 128 x 128 texel centres over NoV and perceptual roughness, half floats, GL order";
  // Generator: libs/ibl/src/CubemapIBL.cpp (CubemapIBL::DFG, DFV_Multiscatter: NoV = (x + 0.5) / width,
  // linear_roughness = coord^2 with coord the perceptual roughness, 1024 Hammersley samples of the GGX NDF,
  // height-correlated Smith visibility, r.x += v Fc and r.y += v with Fc = (1 - VoH)^5) and
  // tools/cmgen/src/cmgen.cpp (iblLutDfg: half floats per texel, rows flipped to GL order); engine:
  // filament/src/details/DFG.cpp (DFG_LUT_SIZE 128, an RGB16F texture, B the cloth term) and the shaders'
  // textureLod(light_iblDFG, vec2(NoV, perceptualRoughness)), specularDFG = mix(dfg.xxx, dfg.yyy, f0).
  // The nodes are where the shader reads (texel centres). The generator's image row y has coord =
  // (height - y + 0.5) / height, and cmgen writes GL row j from image row height - 1 - j: GL row j holds
  // roughness (j + 1.5) / 128 (the last row clamped to 1), one texel above where it is read; a LUT made so is
  // graded as the renderer reads it, and the grade's hint names the shift.
  l.source = "google/filament libs/ibl/src/CubemapIBL.cpp, tools/cmgen/src/cmgen.cpp, filament/src/details/DFG.cpp";
  l.quantity = "DFG.y";
  l.grazing_quantity = "DFG.x";
  l.roughness = {128, LayoutPlacement::centres, 0};
  l.mu = {128, LayoutPlacement::centres, 0};
  l.encoding = LayoutEncoding::half;
  return l;
}

AlbedoLayout enterprise_layout() {
  AlbedoLayout l;
  l.name = "enterprise-pbr";
  l.summary = "Enterprise PBR GGX_E (32 x 32, [roughness][cos theta], roughness r = sqrt(alpha)) and GGX_E_avg";
  // Spec: spec-2021x.md.html, "Multiple-Scattering GGX BRDFs" (E_m(cos theta; r_uv), x: cos theta,
  // y: r_uv; r_uv = sqrt(r_u r_v); res/GGX_E.exr, res/GGX_E_avg.exr, res/pbrlut.hpp
  // GGX_E[32 roughness][32 cos_theta]).
  l.source = "DassaultSystemes-Technology/EnterprisePBRShadingModel spec-2021x.md.html, res/pbrlut.hpp";
  l.quantity = "GGX_E";
  l.roughness = {32, LayoutPlacement::centres, 0};
  l.mu = {32, LayoutPlacement::centres, 0};
  l.encoding = LayoutEncoding::float32;
  l.has_average = true;
  return l;
}

AlbedoLayout uniform_layout() {
  AlbedoLayout l;
  l.name = "uniform";
  l.summary = "a plain 32 x 32 grid at cell centres in alpha and mu, rows alpha, normalised uint16";
  l.source = "microsim (no renderer)";
  l.quantity = "E";
  l.roughness = {32, LayoutPlacement::centres, 0};
  l.mu = {32, LayoutPlacement::centres, 0};
  l.roughness_is_alpha = true;
  l.encoding = LayoutEncoding::unorm16;
  l.has_average = true;
  return l;
}

}  // namespace

const std::vector<AlbedoLayout>& albedo_layouts() {
  static const std::vector<AlbedoLayout> layouts{cycles_layout(), filament_layout(), enterprise_layout(),
                                                 uniform_layout()};
  return layouts;
}

std::string albedo_layout_names() {
  std::string s;
  for (const AlbedoLayout& l : albedo_layouts()) s += (s.empty() ? "" : ", ") + l.name;
  return s;
}

const AlbedoLayout& find_albedo_layout(std::string_view what, std::string_view name) {
  for (const AlbedoLayout& l : albedo_layouts())
    if (l.name == name) return l;
  throw ParseError(fmt::format("{} {}: unknown layout ({})", what, quote_excerpt(name), albedo_layout_names()));
}

double layout_coordinate(const LayoutAxis& axis, double index) {
  const double c = axis.placement == LayoutPlacement::edges ? index / (axis.nodes - 1) : (index + 0.5) / axis.nodes;
  return std::clamp(c, axis.lowest, 1.0);
}

double layout_alpha(const AlbedoLayout& layout, double roughness_coordinate) {
  return layout.roughness_is_alpha ? roughness_coordinate : roughness_coordinate * roughness_coordinate;
}

std::size_t layout_storage_index(const AlbedoLayout& l, std::size_t ri, std::size_t mj) {
  return l.mu_rows ? mj * std::size_t(l.roughness.nodes) + ri : ri * std::size_t(l.mu.nodes) + mj;
}
int layout_columns(const AlbedoLayout& l) { return l.mu_rows ? l.roughness.nodes : l.mu.nodes; }
int layout_rows(const AlbedoLayout& l) { return l.mu_rows ? l.mu.nodes : l.roughness.nodes; }

std::uint16_t half_bits(double value) {
  const std::uint16_t sign = std::signbit(value) ? 0x8000 : 0;
  const double a = std::abs(value);
  if (!(a < 65520.0)) return std::uint16_t(sign | 0x7c00);  // overflows to infinity (and NaN: infinity)
  if (a < std::ldexp(1.0, -14)) {                            // subnormal: multiples of 2^-24
    return std::uint16_t(sign | std::uint16_t(std::nearbyint(std::ldexp(a, 24))));
  }
  int exponent = 0;
  const double fraction = std::frexp(a, &exponent);  // a = fraction 2^exponent, fraction in [0.5, 1)
  // 11 significant bits: the mantissa counts multiples of 2^(exponent - 11); rounding may carry into the
  // exponent, which the bit layout absorbs (mantissa 2048 becomes the next exponent's 1024).
  const auto m = std::uint32_t(std::nearbyint(std::ldexp(fraction, 11)));
  const std::uint32_t bits = (std::uint32_t(exponent - 2 + 15) << 10) + m;
  return std::uint16_t(sign | bits);
}

double half_value(std::uint16_t bits) {
  const double sign = (bits & 0x8000) ? -1.0 : 1.0;
  const int exponent = (bits >> 10) & 0x1f, mantissa = bits & 0x3ff;
  if (exponent == 0) return sign * std::ldexp(double(mantissa), -24);
  if (exponent == 31) return mantissa ? std::nan("") : sign * std::numeric_limits<double>::infinity();
  return sign * std::ldexp(double(mantissa + 1024), exponent - 25);
}

double encode_layout_value(LayoutEncoding e, double v) {
  switch (e) {
    case LayoutEncoding::float32: return double(float(v));
    case LayoutEncoding::six_decimals: return double(float(std::nearbyint(v * 1e6) / 1e6));
    case LayoutEncoding::half: return half_value(half_bits(v));
    case LayoutEncoding::unorm16: return std::nearbyint(std::clamp(v, 0.0, 1.0) * 65535) / 65535;
  }
  return v;
}

double layout_quantisation(LayoutEncoding e, double v) {
  const double a = std::abs(v);
  switch (e) {
    case LayoutEncoding::float32: return a > 0 ? std::ldexp(1.0, std::ilogb(a) - 24) : 0.0;
    case LayoutEncoding::six_decimals: return 5e-7 + (a > 0 ? std::ldexp(1.0, std::ilogb(a) - 24) : 0.0);
    case LayoutEncoding::half:
      return a < std::ldexp(1.0, -14) ? std::ldexp(1.0, -25) : std::ldexp(1.0, std::ilogb(a) - 11);
    case LayoutEncoding::unorm16: return 0.5 / 65535;
  }
  return 0;
}

Estimate mirror_albedo_reference(double alpha, double mu, double tolerance, NdfKind ndf) {
  if (ndf == NdfKind::beckmann) return beckmann_mirror_split(alpha, mu, tolerance).unit;
  return single_scattering_albedo(GGX<double>(alpha), Material::mirror(), 0, albedo_view(mu, false), tolerance)
      .total();
}

SchlickSplitAlbedo mirror_split_reference(double alpha, double mu, double tolerance, NdfKind ndf) {
  if (ndf == NdfKind::beckmann) return beckmann_mirror_split(alpha, mu, tolerance);
  return schlick_split_albedo(GGX<double>(alpha), albedo_view(mu, false), tolerance);
}

namespace {

constexpr int kAverageNodes = 32;

// The reference at (alpha, mu) into e, and the grazing channel into g when the layout has it (one quadrature
// for both).
void layout_reference(const AlbedoLayout& layout, NdfKind ndf, double alpha, double mu, double tolerance, Estimate& e,
                      Estimate& g) {
  if (!layout.has_grazing()) {
    e = mirror_albedo_reference(alpha, mu, tolerance, ndf);
    return;
  }
  const SchlickSplitAlbedo s = mirror_split_reference(alpha, mu, tolerance, ndf);
  e = s.unit;
  g = s.grazing;
}  // Gauss-Legendre nodes of E_avg's mu integral

LayoutTable empty_layout_table(const AlbedoLayout& layout, double tolerance) {
  LayoutTable t;
  t.layout = layout;
  t.tolerance = tolerance;
  for (int i = 0; i < layout.roughness.nodes; ++i) {
    t.roughness.push_back(layout_coordinate(layout.roughness, i));
    t.alphas.push_back(layout_alpha(layout, t.roughness.back()));
    t.in_range.push_back(t.alphas.back() >= kMinAlpha);
  }
  for (int j = 0; j < layout.mu.nodes; ++j) t.mus.push_back(layout_coordinate(layout.mu, j));
  return t;
}

// E_avg of each roughness node: 2 sum_j w_j mu_j E(mu_j), errors added.
bool fill_averages(LayoutTable& t, const RunControl& run, std::atomic<std::uint64_t>& done, std::uint64_t total) {
  const MuGrid grid = gauss_legendre_mus(kAverageNodes);
  const std::size_t n = grid.mus.size();
  std::vector<Estimate> e(t.alphas.size() * n);
  if (!parallel_cells(e.size(), run, "layout table", done, total, [&](std::size_t k) {
        e[k] = mirror_albedo_reference(t.alphas[k / n], grid.mus[k % n], t.tolerance, t.ndf);
      }))
    return false;
  for (std::size_t i = 0; i < t.alphas.size(); ++i) {
    Estimate avg;
    for (std::size_t j = 0; j < n; ++j) {
      const double w = 2 * grid.weights[j] * grid.mus[j];
      avg.value += w * e[i * n + j].value;
      avg.standard_error += w * e[i * n + j].standard_error;
    }
    t.average.push_back(avg);
  }
  return true;
}

}  // namespace

std::optional<LayoutTable> layout_table(const AlbedoLayout& layout, double tolerance, const RunControl& run,
                                        bool averages, NdfKind ndf) {
  if (!(tolerance >= 1e-13 && tolerance <= 1e-2))
    throw std::invalid_argument(fmt::format("layout table: tolerance {} outside [1e-13, 1e-2]", tolerance));
  const auto start = std::chrono::steady_clock::now();
  LayoutTable t = empty_layout_table(layout, tolerance);
  t.ndf = ndf;
  const std::size_t nr = t.alphas.size(), nm = t.mus.size(), cr = nr - 1, cm = nm - 1;
  const std::uint64_t total = nr * nm + cr * cm + (layout.has_average && averages ? nr * kAverageNodes : 0);
  std::atomic<std::uint64_t> done{0};
  t.cells.resize(nr * nm);
  t.grazing.resize(layout.has_grazing() ? nr * nm : 0);
  if (!parallel_cells(t.cells.size(), run, "layout table", done, total, [&](std::size_t k) {
        Estimate unused;
        layout_reference(layout, ndf, t.alphas[k / nm], t.mus[k % nm], tolerance, t.cells[k],
                         layout.has_grazing() ? t.grazing[k] : unused);
      }))
    return std::nullopt;
  t.centres.resize(cr * cm);
  t.grazing_centres.resize(layout.has_grazing() ? cr * cm : 0);
  if (!parallel_cells(t.centres.size(), run, "layout table", done, total, [&](std::size_t k) {
        const double r = layout_coordinate(layout.roughness, double(k / cm) + 0.5);
        const double mu = layout_coordinate(layout.mu, double(k % cm) + 0.5);
        Estimate unused;
        layout_reference(layout, ndf, layout_alpha(layout, r), mu, tolerance, t.centres[k],
                         layout.has_grazing() ? t.grazing_centres[k] : unused);
      }))
    return std::nullopt;
  if (layout.has_average && averages && !fill_averages(t, run, done, total)) return std::nullopt;
  std::vector<double> nodes;
  for (const Estimate& e : t.cells) nodes.push_back(e.value);
  t.interpolation = interpolation_error(t, nodes);
  if (layout.has_grazing()) {
    std::vector<double> grazing;
    for (const Estimate& e : t.grazing) grazing.push_back(e.value);
    t.grazing_interpolation = interpolation_error(t, grazing, t.grazing_centres);
  }
  t.seconds = seconds_since(start);
  return t;
}

InterpolationError interpolation_error(const LayoutTable& t, const std::vector<double>& nodes) {
  return interpolation_error(t, nodes, t.centres);
}

InterpolationError interpolation_error(const LayoutTable& t, const std::vector<double>& nodes,
                                       const std::vector<Estimate>& centres) {
  const std::size_t nm = t.mus.size(), cr = t.alphas.size() - 1, cm = nm - 1;
  if (nodes.size() != t.cells.size() || centres.size() != cr * cm)
    throw std::invalid_argument("interpolation_error: node or centre count does not match the layout");
  InterpolationError r;
  double sum = 0;
  std::size_t counted = 0;
  for (std::size_t i = 0; i < cr; ++i)
    for (std::size_t j = 0; j < cm; ++j) {
      if (!t.in_range[i] || !t.in_range[i + 1]) {
        r.errors.push_back(std::nan(""));
        continue;
      }
      ++counted;
      const double bilinear =
          (nodes[i * nm + j] + nodes[i * nm + j + 1] + nodes[(i + 1) * nm + j] + nodes[(i + 1) * nm + j + 1]) / 4;
      const double e = bilinear - centres[i * cm + j].value;
      r.errors.push_back(e);
      sum += e * e;
      if (std::abs(e) > r.max_abs) {
        r.max_abs = std::abs(e);
        r.worst_ri = i;
        r.worst_mj = j;
      }
    }
  r.rms = counted == 0 ? 0.0 : std::sqrt(sum / double(counted));
  r.worst_alpha = layout_alpha(t.layout, layout_coordinate(t.layout.roughness, double(r.worst_ri) + 0.5));
  r.worst_mu = layout_coordinate(t.layout.mu, double(r.worst_mj) + 0.5);
  return r;
}

}  // namespace microsim
