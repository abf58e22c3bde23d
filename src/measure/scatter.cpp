// measure: the scattering measurement (scatter.h).
#include "measure/scatter.h"

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

}  // namespace microsim
