#include "measure/masking_table.h"
#include "core/wall_clock.h"

#include "measure/masking.h"
#include "microgeom/assembly.h"
#include "stats/binning.h"
#include "trace/heightfield_trace.h"
#include "trace/smith_prediction.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <stdexcept>

namespace microsim {

namespace {

using Clock = std::chrono::steady_clock;


void check_request(const MaskingTableRequest& r) {
  if (r.assemblies.empty() || r.alphas.empty() || r.thetas.empty() || r.seeds.empty())
    throw std::invalid_argument("masking table: every list (assemblies, alphas, thetas, seeds) needs an item");
  for (const double theta : r.thetas)
    if (!(theta >= 0 && theta < 90)) throw std::invalid_argument("masking table: a theta is outside [0, 90) degrees");
  if (r.samples == 0 || r.vndf_rays == 0) throw std::invalid_argument("masking table: no samples or no VNDF rays");
}

// Threads and the cancel token of the request, without its progress (the table reports its own).
RunControl step_control(const RunControl& run) {
  RunControl step;
  step.threads = run.threads;
  step.cancel = run.cancel;
  return step;
}

// A surface of the table, or nothing when the run was cancelled during its build.
std::optional<microgeom::Heightfield> build_surface(const microgeom::AssemblyParams& p, const RunControl& run,
                                                    microgeom::BuildReport& report) {
  const auto progress = [&run](std::string_view, double fraction) {
    run.report("build surface", std::uint64_t(std::clamp(fraction, 0.0, 1.0) * 1000), 1000);
  };
  try {
    return microgeom::build_assembly(p, &report, progress, [&run] { return run.cancelled(); });
  } catch (const microgeom::BuildCancelled&) {
    return std::nullopt;
  }
}

// What the views of one surface share: its Smith predictions and its scene.
struct SurfaceSetup {
  explicit SurfaceSetup(const microgeom::Heightfield& field)
      : analytic(analytic_reference(field)), empirical(field), scene(field) {}
  AnalyticSmith analytic;
  EmpiricalSmith empirical;
  HeightfieldScene scene;
};

// The VNDF of one view in lobe bins, against Smith with both NDFs.
void trace_view_vndf(const SurfaceSetup& s, const MaskingTableRequest& r, const Vec3<double>& v,
                     MaskingTableView& view, bool& partial) {
  const std::vector<DirectionBinning> binnings = {DirectionBinning::lobe(
      GGX<double>(s.analytic.alpha_x(), s.analytic.alpha_y()), v, SampleDomain::microfacet_normal, kMaskingVndfRows)};
  TraceOptions to;
  to.rays = r.vndf_rays;
  to.seed = view.seed;
  to.run = step_control(r.run);
  const TraceResult traced = trace_vndf_heightfield(s.scene, v, binnings, to);
  view.vndf = compare_vndf(traced.counts[0], traced.unbinned[0], binnings[0], v, s.analytic, s.empirical);
  view.vndf_rays = traced.rays;
  view.vndf_rays_per_second = traced.rays_per_second();
  partial = traced.partial;
}

// The masking of one view; G2 for the specular pair: l = v mirrored through the mean normal, facets
// within the cone around z.
void measure_view_masking(const SurfaceSetup& s, const MaskingTableRequest& r, const Vec3<double>& v,
                          MaskingTableView& view) {
  MaskingOptions mo;
  mo.samples = r.samples;
  mo.seed = view.seed;
  mo.run = step_control(r.run);
  mo.grazing_share = r.grazing_share;
  mo.light = Vec3<double>(-v.x(), -v.y(), v.z());
  view.masking = estimate_masking(s.scene, s.analytic, s.empirical, v, mo);
}

MaskingTableView measure_view(const SurfaceSetup& s, const MaskingTableSurface& surface, const MaskingTableRequest& r,
                              double theta) {
  const auto start = Clock::now();
  MaskingTableView view;
  view.assembly = surface.assembly;
  view.alpha = surface.alpha;
  view.seed = surface.seed;
  view.theta = theta;
  const Vec3<double> v = direction_from_degrees(theta, r.phi_deg);
  bool vndf_partial = false;
  trace_view_vndf(s, r, v, view, vndf_partial);
  measure_view_masking(s, r, v, view);
  view.partial = vndf_partial || view.masking.partial;
  view.seconds = seconds_since(start);
  return view;
}

microgeom::AssemblyParams assembly_params(const MaskingTableRequest& r, const std::string& assembly, double alpha,
                                          std::uint64_t seed) {
  microgeom::AssemblyParams p;
  p.assembly = assembly;
  p.alpha_x = p.alpha_y = alpha;
  p.resolution = r.resolution;
  p.seed = seed;
  p.corr_cells = r.corr_cells;
  p.ndf_match = r.ndf_match;
  return p;
}

// Builds one surface and measures its views into `table`; false when cancelled (the table is partial).
bool measure_surface_views(MaskingTable& table, const std::string& assembly, double alpha, std::uint64_t seed,
                           std::size_t& views_done, const MaskingTableViewDone& view_done) {
  const MaskingTableRequest& r = table.request;
  const auto start = Clock::now();
  microgeom::BuildReport report;
  const std::optional<microgeom::Heightfield> field = build_surface(assembly_params(r, assembly, alpha, seed), r.run, report);
  if (!field) return false;
  MaskingTableSurface surface;
  surface.assembly = assembly;
  surface.alpha = alpha;
  surface.seed = seed;
  surface.corr_cells = report.corr_cells;
  surface.build_seconds = seconds_since(start);
  const SurfaceSetup setup(*field);
  surface.scene_seconds = setup.scene.build_seconds();
  surface.analytic_reference = setup.analytic.describe();
  bool complete = true;
  for (const double theta : r.thetas) {
    if (r.run.cancelled()) {
      complete = false;
      break;
    }
    surface.views.push_back(measure_view(setup, surface, r, theta));
    complete = complete && !surface.views.back().partial;
    if (view_done) view_done(surface.views.back());
    r.run.report("masking table", ++views_done, table.views_requested());
  }
  table.surfaces.push_back(std::move(surface));
  return complete;
}

}  // namespace

std::size_t MaskingTable::views_requested() const {
  return request.assemblies.size() * request.alphas.size() * request.seeds.size() * request.thetas.size();
}

std::vector<const MaskingTableView*> MaskingTable::complete_views() const {
  std::vector<const MaskingTableView*> views;
  for (const auto& s : surfaces)
    for (const auto& v : s.views)
      if (!v.partial) views.push_back(&v);
  return views;
}

MaskingTable measure_masking_table(const MaskingTableRequest& request, const MaskingTableViewDone& view_done) {
  check_request(request);
  const auto start = Clock::now();
  MaskingTable table;
  table.request = request;
  std::size_t views_done = 0;
  for (const auto& assembly : request.assemblies) {
    for (const double alpha : request.alphas) {
      for (const std::uint64_t seed : request.seeds) {
        if (request.run.cancelled()) {
          table.partial = true;
          break;
        }
        if (!measure_surface_views(table, assembly, alpha, seed, views_done, view_done)) table.partial = true;
      }
    }
  }
  table.seconds = seconds_since(start);
  return table;
}

std::vector<MaskingTableCell> masking_table_cells(const MaskingTable& table) {
  const std::vector<const MaskingTableView*> rows = table.complete_views();
  std::vector<MaskingTableCell> cells;
  for (const auto& assembly : table.request.assemblies) {
    for (const double alpha : table.request.alphas) {
      for (const double theta : table.request.thetas) {
        MaskingTableCell cell{assembly, alpha, theta, {}};
        for (const MaskingTableView* r : rows)
          if (r->assembly == assembly && r->alpha == alpha && r->theta == theta) cell.views.push_back(r);
        if (!cell.views.empty()) cells.push_back(std::move(cell));
      }
    }
  }
  return cells;
}

RealisationSummary summarise_realisations(const std::vector<Estimate>& xs) {
  if (xs.empty()) throw std::invalid_argument("summarise_realisations: no estimates");
  RealisationSummary c;
  const double k = double(xs.size());
  double mc = 0;
  c.min = xs.front().value;
  c.max = xs.front().value;
  for (const auto& x : xs) {
    c.values.push_back(x.value);
    c.mean += x.value / k;
    mc += x.standard_error * x.standard_error;
    c.min = std::min(c.min, x.value);
    c.max = std::max(c.max, x.value);
  }
  double ss = 0;
  for (const auto& x : xs) ss += sqr(x.value - c.mean);
  c.sd = xs.size() > 1 ? std::sqrt(ss / (k - 1.0)) : 0.0;
  c.se_across = c.sd / std::sqrt(k);
  c.mc_se = std::sqrt(mc) / k;
  return c;
}

}  // namespace microsim
