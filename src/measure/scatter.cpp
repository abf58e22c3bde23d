// measure: the scattering measurement (scatter.h).
#include "measure/scatter.h"

#include "core/math.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace microsim {

ScatterExpectation measure_analytic_scatter(NdfKind ndf, std::pair<double, double> alpha, const Vec3<double>& wi,
                                            const Material& material, int rows, const RunControl& run) {
  const auto [ax, ay] = alpha;
  if (ndf == NdfKind::beckmann) return analytic_single_scattering(Beckmann<double>(ax, ay), wi, material, rows, run);
  return analytic_single_scattering(GGX<double>(ax, ay), wi, material, rows, run);
}

ScatterPaths smith_walk_paths(const SmithMicrosurface& surface, WalkKernel kernel) {
  return [surface, kernel](const ScatterOptions& options) { return smith_walk_scatter(surface, options, kernel); };
}

ScatterPaths surface_paths(const HeightfieldScene& scene, SurfaceScatterDiagnostics* diagnostics) {
  return [&scene, diagnostics](const ScatterOptions& options) { return scatter_on_surface(scene, options, diagnostics); };
}

nlohmann::json scatter_report_json(nlohmann::json summary, const std::map<std::string, std::string>& notes) {
  const auto theta = notes.find("theta");
  if (theta == notes.end()) summary["hemispheres"] = {{"upper", ""}, {"lower", ""}};
  else if (std::strtod(theta->second.c_str(), nullptr) > 90)
    summary["hemispheres"] = {{"upper", "transmitted"}, {"lower", "reflected"}};
  else summary["hemispheres"] = {{"upper", "reflected"}, {"lower", "transmitted"}};
  summary["notes"] = notes;
  return summary;
}

double scatter_order_floor(const ScatterHistogram& h, int order_bin) {
  const Histogram& lobe = h.histogram(0, order_bin);
  double total = 0, spread = 0;
  const double n = double(std::max<std::uint64_t>(h.paths(), 1));
  for (std::size_t i = 0; i < lobe.size(); ++i) {
    total += lobe.weight(i);
    spread += std::sqrt(std::max(0.0, lobe.weight_squared(i) - lobe.weight(i) * lobe.weight(i) / n));
  }
  if (!(total > 0)) return 0;
  return 0.5 * std::sqrt(2 / kPi<double>) * spread / total;
}

std::vector<int> targeted_order_bins(const ScatterHistogram& h, double target) {
  const double all = h.albedo(0, -1).value;
  std::vector<int> out;
  if (!(all > 0)) return out;
  for (int k = 0; k < kScatterOrderBins; ++k) {
    const Estimate order = h.albedo(0, k);
    if (order.value > 0 && order.value + kShareMargin * order.standard_error >= target * all) out.push_back(k);
  }
  return out;
}

double scatter_noise_floor(const ScatterHistogram& h, const std::vector<int>& order_bins) {
  double worst = 0;
  for (int k : order_bins) worst = std::max(worst, scatter_order_floor(h, k));
  return worst;
}

double extrapolated_scatter_floor(const ScatterHistogram& quarter, const ScatterHistogram& whole,
                                  const std::vector<int>& order_bins) {
  const double root_ratio = std::sqrt(double(std::max<std::uint64_t>(quarter.paths(), 1)) /
                                      double(std::max<std::uint64_t>(whole.paths(), 1)));
  double worst = 0;
  for (int k : order_bins) {
    const double at_whole = scatter_order_floor(whole, k);
    // In units of the whole pilot's floor: C(n/4) / sqrt(n) = floor(n/4) sqrt(n/4) / sqrt(n).
    const double at_quarter = scatter_order_floor(quarter, k) * root_ratio;
    worst = std::max(worst, std::max(at_whole, 2 * at_whole - at_quarter));
  }
  return worst;
}

}  // namespace microsim
