// measure: the masking table of `microsim trace masking --table` (docs/reference/masking.md), as a library call.
// For every assembly, roughness and seed it builds a surface (microgeom/assembly.h) and, for every view,
// traces the VNDF (lobe bins, against Smith with the analytic and the surface's own NDF) and measures the
// masking in the specular pair configuration (l = v mirrored through the mean normal). A cancelled run
// (RunControl's token: between surfaces, inside a build, between and inside views) returns what it
// measured, marked partial; the table holds the complete views only.
#pragma once

#include "core/run_control.h"
#include "microgeom/assembly.h"
#include "trace/masking.h"

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace microsim {

struct MaskingTableRequest {
  std::vector<std::string> assemblies;  // microgeom::assembly_registry names
  std::vector<double> alphas;           // isotropic roughness of each surface
  std::vector<double> thetas;           // view polar angles (degrees, [0, 90))
  double phi_deg = 30;                  // view azimuth of every view
  int resolution = 1024;                // vertices per side of each surface
  double corr_cells = 0;                // correlation length in cells (0: the assembly's default)
  std::vector<std::uint64_t> seeds{1};  // surface realisations per cell (also the seed of the tracing)
  microgeom::NdfMatch ndf_match = microgeom::NdfMatch::radial;  // how each surface's NDF is matched
  std::uint64_t samples = 1'000'000;    // surface points per view
  std::uint64_t vndf_rays = 2'000'000;  // VNDF rays per view
  double grazing_share = 0.02;          // share of the near-grazing class of G1(v | m)
  // Threads and the cancel token of every step; progress: "masking table" (views done of views
  // requested) and "build surface" (thousandths of the build).
  RunControl run;
};

// One view of one surface: the row of the table, with its estimates.
struct MaskingTableView {
  std::string assembly;
  double alpha = 0;
  std::uint64_t seed = 0;
  double theta = 0;
  VndfComparison vndf;  // lobe bins
  std::uint64_t vndf_rays = 0;
  double vndf_rays_per_second = 0;
  MaskingResult masking;
  bool partial = false;  // cancelled during the view: not in the table
  double seconds = 0;    // wall time of the view (VNDF and masking)
};

// One surface of the table and its views (in the request's order of thetas).
struct MaskingTableSurface {
  std::string assembly;
  double alpha = 0;
  std::uint64_t seed = 0;
  double corr_cells = 0;           // the correlation length the build used
  double build_seconds = 0;        // the surface's build
  double scene_seconds = 0;        // its ray-tracing scene's build
  std::string analytic_reference;  // AnalyticSmith::describe()
  std::vector<MaskingTableView> views;
};

struct MaskingTable {
  MaskingTableRequest request;
  std::vector<MaskingTableSurface> surfaces;  // every surface built (a cancelled build is left out)
  bool partial = false;                       // cancelled before every view was complete
  double seconds = 0;                         // wall time of the whole table
  std::size_t views_requested() const;
  std::vector<const MaskingTableView*> complete_views() const;  // the rows of the table, in run order
};

// One cell of the table, (assembly, alpha, theta): its complete views, one per realisation (seed).
struct MaskingTableCell {
  std::string assembly;
  double alpha = 0, theta = 0;
  std::vector<const MaskingTableView*> views;
};
// The cells with at least one complete view, in the request's order (assembly, alpha, theta).
std::vector<MaskingTableCell> masking_table_cells(const MaskingTable& table);

// A quantity over the realisations of a cell: the mean, the standard deviation across realisations and
// the standard error of the mean (sd / sqrt(k); it contains the Monte Carlo noise too), and the Monte
// Carlo error of the mean, sqrt(sum se_i^2) / k.
struct RealisationSummary {
  std::vector<double> values;
  double mean = 0, sd = 0, se_across = 0, mc_se = 0, min = 0, max = 0;
};
// Throws std::invalid_argument for no estimates.
RealisationSummary summarise_realisations(const std::vector<Estimate>& estimates);

// Called after each view (complete or not), on the calling thread: a caller's log of the run.
using MaskingTableViewDone = std::function<void(const MaskingTableView&)>;

// Measures the table. Throws std::invalid_argument for an empty list, a theta outside [0, 90), no samples
// or rays, and what microgeom::build_assembly (std::invalid_argument: unknown assembly, bad parameters)
// or estimate_masking refuse.
MaskingTable measure_masking_table(const MaskingTableRequest& request, const MaskingTableViewDone& view_done = {});

}  // namespace microsim
