// experiment: the planner's pieces the kinds' planners share (plan.cpp); each kind plans its quantities in its
// own file (measurement_*.cpp), reached through the registry (measurement.h: quantity_planner).
#pragma once

#include "experiment/heightfield_measures.h"
#include "experiment/measurement.h"
#include "validate/sample_io.h"

#include <functional>
#include <string>
#include <utility>

namespace microsim::experiment {

// The derived_seed purposes of the pilots (the masking pilot's is kMaskingPilotSeed).
enum PlanSeedPurpose : std::uint64_t { kCapPilot = 1, kTablePilot = 2, kVndfPilot = 3, kScatterPilot = 4, kValidationPilot = 5 };

// The seed the pilots derive theirs from: the options', or the spec's.
std::uint64_t plan_seed(const ExperimentSpec& spec, const PlanOptions& options);

// A pilot of the walk at one cap: the weight left on the surface relative to the albedo, at the cell or view
// where that is largest.
using CapPilot = std::function<CapProbe(int cap)>;
// Paths per cell or view with which "none left" bounds the bias below `threshold` with room: the rule of
// three (3 / n) at half the threshold.
std::uint64_t paths_to_bound_bias(double threshold);
// Caps 4, 8, 16, ... probed until one leaves less than kBiasShare of the (relative) target on the surface;
// the cap and its reason.
std::pair<int, std::string> walk_order_cap(const CapPilot& pilot, double relative_target, const std::string& where);

// A dump's rows, every one read (a file that cannot be read as samples throws SampleFileError before anything
// runs); Cancelled when run is.
std::uint64_t count_dump_rows(DirectionSampleReader& reader, const RunControl& run);

// The tile a decision planned, into d.surface; false (with why it is not runnable) when none fits.
bool take_surface(const SurfaceDecision& s, Decision& d);

// How a kind plans one view: on Smith's model (`smith`), or on a tile (`tile`, its field and the cache that
// keeps its scene); `refusal` says why a quantity cannot be measured on a tile ("" when it can).
struct ViewPlanners {
  void (*smith)(const ExperimentSpec&, const SpecQuantity&, const PlanOptions&, Decision&);
  void (*tile)(const ExperimentSpec&, const SpecQuantity&, const PlanOptions&, const microgeom::Heightfield&, SurfaceCache&,
               Decision&);
  std::string (*refusal)(const SpecQuantity&) = nullptr;
  bool sees_heights = true;  // false: it sees a tile's visible normals only (plan_surface)
};
// One decision per alpha and view of quantity `index`, each planned by the kind's planners.
void plan_views(const ExperimentSpec& spec, std::size_t index, const PlanOptions& o, SurfaceCache& cache,
                const ViewPlanners& kind, std::vector<Decision>& out);

}  // namespace microsim::experiment
