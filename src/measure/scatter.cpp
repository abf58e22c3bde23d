// measure: the scattering measurement (scatter.h).
#include "measure/scatter.h"

#include <cstdlib>

namespace microsim {

ScatterExpectation measure_analytic_scatter(NdfKind ndf, std::pair<double, double> alpha, const Vec3<double>& wi,
                                            const Material& material, int rows, const RunControl& run) {
  const auto [ax, ay] = alpha;
  if (ndf == NdfKind::beckmann) return analytic_single_scattering(Beckmann<double>(ax, ay), wi, material, rows, run);
  return analytic_single_scattering(GGX<double>(ax, ay), wi, material, rows, run);
}

ScatterPaths smith_walk_paths(const SmithMicrosurface& surface) {
  return [surface](const ScatterOptions& options) { return smith_walk_scatter(surface, options); };
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

}  // namespace microsim
