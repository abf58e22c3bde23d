#include "scatter/analytic_scatter.h"

#include "microfacet/bsdf.h"
#include "microfacet/samplers.h"
#include "stats/binning.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace microsim {

namespace {

constexpr const char* ndf_name(const GGX<double>&) { return "ggx"; }
constexpr const char* ndf_name(const Beckmann<double>&) { return "beckmann"; }


[[noreturn]] void no_closed_form(const Material& material) {
  throw std::invalid_argument(fmt::format("analytic single scattering: material {} has no closed-form single "
                                          "scattering (mirror, conductor or dielectric only)", material.describe()));
}

template <class Ndf>
double flux_of(const Ndf& ndf, const Material& material, int channel, const Vec3<double>& wi, const Vec3<double>& wo) {
  const double cos_o = std::abs(wo.z());
  switch (material.kind()) {
    case MaterialKind::mirror: return mirror_brdf(ndf, wi, wo) * cos_o;
    case MaterialKind::conductor: return conductor_brdf(ndf, material.ior(channel), wi, wo) * cos_o;
    case MaterialKind::dielectric: return dielectric_bsdf_smith(ndf, material.eta(), wi, wo) * cos_o;
    case MaterialKind::lambertian: break;
  }
  no_closed_form(material);
}

template <class Ndf>
std::string measurement_of(const Ndf& ndf, const Vec3<double>& wi, const Material& material, int rows_per_hemisphere) {
  return fmt::format("analytic {} alpha {},{} wi {},{},{} material {} rows {}", ndf_name(ndf), ndf.alpha_x(),
                     ndf.alpha_y(), wi.x(), wi.y(), wi.z(), material.describe(), rows_per_hemisphere);
}

}  // namespace

double single_scattering_flux(const GGX<double>& ggx, const Material& material, int channel, const Vec3<double>& wi,
                              const Vec3<double>& wo) {
  return flux_of(ggx, material, channel, wi, wo);
}
double single_scattering_flux(const Beckmann<double>& beckmann, const Material& material, int channel,
                              const Vec3<double>& wi, const Vec3<double>& wo) {
  return flux_of(beckmann, material, channel, wi, wo);
}

std::string analytic_measurement(const GGX<double>& ggx, const Vec3<double>& wi, const Material& material,
                                 int rows_per_hemisphere) {
  return measurement_of(ggx, wi, material, rows_per_hemisphere);
}
std::string analytic_measurement(const Beckmann<double>& beckmann, const Vec3<double>& wi, const Material& material,
                                 int rows_per_hemisphere) {
  return measurement_of(beckmann, wi, material, rows_per_hemisphere);
}

namespace {

void check_analytic_inputs(const Vec3<double>& wi, const Material& material) {
  if (material.kind() == MaterialKind::lambertian) no_closed_form(material);
  if (!wi.allFinite() || std::abs(wi.norm() - 1.0) > 1e-9 || wi.z() == 0.0)
    throw std::invalid_argument(fmt::format("analytic single scattering: wi ({}, {}, {}) must be a unit direction off "
                                            "the horizon", wi.x(), wi.y(), wi.z()));
  if (wi.z() < 0 && !material.transmits())
    throw std::invalid_argument(fmt::format("analytic single scattering: light from below (wi.z = {}) reaches an "
                                            "opaque {} surface from inside", wi.z(), material.describe()));
}

// Where the lobes are: reflections and (dielectric) refractions about wi of visible normals drawn on a
// 64 x 64 lattice of u (normals on wi's side; m faces wi).
template <class Ndf> std::vector<Vec3<double>> lobe_focus(const Ndf& ndf, const Vec3<double>& wi, const Material& material) {
  constexpr int kSide = 64;
  std::vector<Vec3<double>> focus;
  const double eta = wi.z() > 0 ? material.eta() : 1.0 / material.eta();  // n_transmitted / n_incident
  for (int i = 0; i < kSide; ++i)
    for (int j = 0; j < kSide; ++j) {
      const auto s = sample_visible_normal(ndf, wi, Vec2<double>((i + 0.5) / kSide, (j + 0.5) / kSide));
      if (!s) continue;
      focus.push_back(reflect(wi, s->direction));
      Vec3<double> t;
      if (material.transmits() && refract(wi, s->direction, eta, t)) focus.push_back(t);
    }
  return focus;
}

template <class Ndf>
ScatterExpectation expectation_of(const Ndf& ndf, const Vec3<double>& wi, const Material& material, int rows_per_hemisphere,
                                  const RunControl& run) {
  check_analytic_inputs(wi, material);
  const DirectionBinning binning = DirectionBinning::hemispheres(rows_per_hemisphere);  // checks the rows
  ScatterExpectation e;
  e.binning_id = binning.describe().dump();
  e.reflection_bins.resize(std::size_t(binning.size()));
  for (int b = 0; b < binning.size(); ++b) e.reflection_bins[std::size_t(b)] = b < binning.size() / 2;
  e.producer = "scatter analytic";
  e.measurement = measurement_of(ndf, wi, material, rows_per_hemisphere);
  IntegrationOptions options;
  options.focus = lobe_focus(ndf, wi, material);
  options.z_breaks = {0.0};
  tbb::task_arena arena(run.threads > 0 ? run.threads : tbb::task_arena::automatic);
  for (int c = 0; c < material.channels(); ++c) {
    if (run.cancelled()) throw Cancelled("analytic single scattering");
    run.report("scatter analytic", std::uint64_t(c), std::uint64_t(material.channels()));
    const auto flux = [&](const Vec3<double>& wo) { return flux_of(ndf, material, c, wi, wo); };
    BinIntegrals r = arena.execute([&] { return binning.integrate(flux, options); });
    e.channel_names.push_back(material.channel_name(c));
    for (double& p : r.probability) p = std::max(p, 0.0);  // the integrand is >= 0; no rounding below it
    e.order1.push_back(std::move(r.probability));
    e.error_estimate.push_back(r.error_estimate);
  }
  if (run.cancelled()) throw Cancelled("analytic single scattering");
  run.report("scatter analytic", std::uint64_t(material.channels()), std::uint64_t(material.channels()));
  return e;
}

}  // namespace

ScatterExpectation analytic_single_scattering(const GGX<double>& ggx, const Vec3<double>& wi, const Material& material,
                                              int rows_per_hemisphere, const RunControl& run) {
  return expectation_of(ggx, wi, material, rows_per_hemisphere, run);
}
ScatterExpectation analytic_single_scattering(const Beckmann<double>& beckmann, const Vec3<double>& wi,
                                              const Material& material, int rows_per_hemisphere, const RunControl& run) {
  return expectation_of(beckmann, wi, material, rows_per_hemisphere, run);
}

}  // namespace microsim
