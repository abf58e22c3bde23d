// experiment: the planner: for each measurement of a spec, one decision with its reason.
//
//   model     the cheapest sufficient one (choose_model):
//               vndf        the analytic D_v is exact for the Smith model, but a measured histogram is wanted:
//                           the exact ellipsoid oracle (Heitz 2018: a convex GGX ellipsoid's visible normals
//                           are D_v, only Monte Carlo noise remains);
//               albedo / scattering, orders single, surface auto: analytic single scattering (Walter et al.
//                           2007 with the Smith masking; quadrature or cubature, no noise);
//               albedo / scattering, orders all, surface auto: the Smith random walk (Heitz et al. 2016);
//               validation  the analytic validator (the sampler against the pdf it claims);
//               a surface named in the spec (assembly, heightmap): the explicit heightfield, whose effects
//                           (conditional masking, its own multiple scattering) only it has; vndf and scattering
//                           run on it, the tile sized by the trade table (heightfield_trade.h) and built once
//                           (surface_cache.h).
//   order cap the smallest cap of the walk at which the weight still on the surface (the walk's `unfinished`,
//             measured by a pilot at the worst view) is below kBiasShare of the target (order_cap_for).
//   count     from a pilot's standard error: n = n_pilot (se_pilot / se_target)^2 (units_for_standard_error);
//             for a histogram the TV noise floor ~ 1/sqrt(n) likewise; for a validation the chi-square power
//             (validation_samples). The time predicted from the pilot's measured rate.
// The decision rules are pure functions (tested in tests/test_experiment_plan.cpp); plan_experiment runs
// the pilots (library calls with a RunControl) and applies them. Never prints.
#pragma once

#include "core/run_control.h"
#include "experiment/spec.h"
#include "measure/heightfield_trade.h"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace microsim {
class SurfaceCache;  // measure/surface_cache.h
}  // namespace microsim

namespace microsim::experiment {

// The share of a target a truncation bias (the order cap) or a tile's bias may take (measure/heightfield_trade.h).
using microsim::kBiasShare;
// A histogram resolves a TV distance d when its own noise floor (the expected TV of an exact sampler of that
// many counts, validate/compare.h noise_floor_tv) is at most kNoiseShare d: a true deviation d then stands
// out at twice the noise.
inline constexpr double kNoiseShare = 0.5;
// The TV distance a histogram resolves: its noise floor over kNoiseShare. The achieved error of a VNDF and of
// sampled per-order lobes, in the unit of their target_tv as the spec asks it (floor <= kNoiseShare d exactly
// when resolved_tv(floor) <= d: kNoiseShare is 1/2, the division exact).
inline double resolved_tv(double noise_floor) { return noise_floor / kNoiseShare; }
// Rounds of a sequential run: the next round aims this much beyond the predicted need (the pilot's variance
// is itself noisy), and a run gives up (target not met, reported) after kMaxRounds.
inline constexpr double kRoundMargin = 1.1;
inline constexpr int kMaxRounds = 8;

enum class Model { analytic, ellipsoid_oracle, smith_walk, heightfield, analytic_validator };
std::string to_string(Model model);  // "analytic", "ellipsoid-oracle", "smith-walk", "heightfield", "analytic-validator"

struct ModelChoice {
  Model model = Model::analytic;
  std::string reason;
};
// The cheapest sufficient model of a quantity on a material (see the header comment). Pure.
ModelChoice choose_model(const SpecQuantity& quantity, const SpecMaterial& material);

// n = n_pilot (se_pilot / se_target)^2, rounded up; at least 1. se_pilot 0 (no variance seen): n_pilot.
// Throws std::invalid_argument for target_se <= 0 or n_pilot 0. Saturates at UINT64_MAX / 2.
std::uint64_t units_for_standard_error(std::uint64_t pilot_units, double pilot_se, double target_se);

// The next round of a sequential run: with `done` units giving `achieved` (a standard error or noise floor
// ~ 1/sqrt(n)) and the target not met, the units to add so that done + more reaches the target, times
// kRoundMargin, at least done / 4 (each round a real step). 0 when the target is met.
std::uint64_t next_round_units(std::uint64_t done, double achieved, double target);

// A pilot of the walk at one cap: the weight left on the surface there (its mean and standard error).
struct CapProbe {
  int cap = 0;
  double unfinished = 0, unfinished_se = 0;
};
// The first probe (probes in increasing cap) whose unfinished weight is below `threshold` by two standard
// errors; nullopt if none is.
std::optional<int> order_cap_for(const std::vector<CapProbe>& probes, double threshold);

// Samples per view for a chi-square test of `degrees_of_freedom` at `significance` to detect any deviation
// of total variation `detect_tv` with probability `power`. Any such deviation has a noncentrality
// lambda = N sum (q - p)^2 / p >= N (sum |q - p|)^2 = 4 N tv^2 (Cauchy-Schwarz, sum p = 1), so N =
// lambda_needed / (4 tv^2), lambda_needed from the noncentral chi-square (Boost.Math): the count at which the
// least detectable deviation of that size is still detected. At least 5 per cell of the binning on average
// (2 rows^2 cells for df = 2 rows^2 - 1): fewer leave the chi-square too few cells to reject with. Pure; throws
// std::invalid_argument when more than kMaxSamples are needed.
std::uint64_t validation_samples(double detect_tv, int degrees_of_freedom, double significance, double power);
// The inverse: the smallest TV deviation `samples` samples detect with that power at that level,
// sqrt(lambda_needed / (4 N)) (a dump's rows are given: they fix it). Pure; throws std::invalid_argument as
// validation_samples does, or for 0 samples.
double detectable_tv(std::uint64_t samples, int degrees_of_freedom, double significance, double power);

// The validator's chi-square tests as the planner counts them: its sphere and lobe binnings of `rows` rows,
// 2 rows^2 bins each (degrees of freedom 2 rows^2 - 1), Sidak-combined: each at 1 - (1 - significance)^(1/2).
struct ValidationTests {
  int dof = 0;
  double level = 0;  // per binning
};
ValidationTests validation_tests(int rows, double significance);

// Seconds for `units` at the pilot's rate (pilot_units in pilot_seconds); 0 when the pilot measured nothing.
double predicted_seconds(std::uint64_t units, std::uint64_t pilot_units, double pilot_seconds);

// One measurement: a quantity at one alpha and view (vndf, scattering, validation) or a quantity's whole
// table (albedo).
struct Decision {
  std::size_t quantity = 0;  // index in spec.quantities
  std::string label;         // "quantity[0] albedo gold", "quantity[1] vndf gold alpha 0.3 theta 60 phi 0"
  ModelChoice model;
  std::pair<double, double> alpha{0, 0};  // vndf, scattering, validation: the alpha of this measurement
  Direction view;                          // vndf, scattering, validation
  std::uint64_t units = 0;   // planned: paths per cell (albedo), rays (vndf), samples (validation); 0: none
  std::string unit;          // "paths per cell", "rays", "samples", "" (deterministic)
  std::string count_reason;
  int order_cap = 0;         // the walk's cap; 0: not a walk
  std::vector<int> targeted_orders;  // scattering, walk: the order bins the target applies to (measures.h)
  std::string cap_reason;
  double tolerance = 0;      // analytic albedo: the quadrature's absolute tolerance per cell
  double predicted_seconds = 0;
  std::uint64_t pilot_units = 0;
  double pilot_seconds = 0;
  double pilot_error = 0;    // the pilot's achieved error, in the target's unit
  bool tests = false;        // its kind tests something (measurement.h kind_tests): the run's verdict needs it
  bool runnable = false;     // `microsim run` carries it out in this version
  std::string not_runnable;  // why not, when not
  SurfacePlan surface;       // Model::heightfield: the tile (measure/heightfield_trade.h)
  int realisation = 0;       // masking on a built surface: which realisation (masking_surface_seed)
};

struct ExperimentPlan {
  std::vector<Decision> decisions;
  double pilot_seconds = 0;      // the pilots' wall time (part of the plan's cost)
  double predicted_seconds = 0;  // the sum of the decisions'
};

struct PlanOptions {
  std::uint64_t pilot_paths = 2048;     // albedo walk: paths per cell of the pilot table
  std::uint64_t pilot_rays = 1 << 16;   // vndf: rays of each view's pilot
  std::uint64_t cap_pilot_paths = 1 << 15;  // the order cap's pilots at the worst view
  std::uint64_t seed = 0;               // 0: the spec's; pilots draw from seeds derived from it
  RunControl run;                       // threads, cancel (Cancelled thrown), progress
  // Where explicit surfaces are built once (surface_cache.h; the run reuses them); null: a cache in memory
  // for this call.
  SurfaceCache* surfaces = nullptr;
};

// Runs the pilots and returns every decision. Throws Cancelled when run.cancel is set.
ExperimentPlan plan_experiment(const ExperimentSpec& spec, const PlanOptions& options);

// A stream seed derived from (seed, purpose, index): pilots and rounds never share a stream.
std::uint64_t derived_seed(std::uint64_t seed, std::uint64_t purpose, std::uint64_t index);

}  // namespace microsim::experiment
