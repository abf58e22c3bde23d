// microsim: numerical stability of the sampler zoo and of the analytic Smith-GGX functions at the
// extremes. One sweep, shared by tests/test_stability.cpp (which asserts the
// bounds) and `microsim stability` (which prints the table that docs/records/stability.md quotes).
//
// What is measured, per (subject, regime), as worst cases over the grid:
// - subjects: every sampler of sampler_registry() (float and double) and the analytic functions of
//   GGX<T> and bsdf.h;
// - non-finite outputs (NaN or infinity in a direction or pdf/value; Lambda's +inf at exactly
//   wz == 0 is its documented value and is not counted), negative pdfs/values, empty results;
// - | |direction| - 1 | in float and in double;
// - float against double ON THE SAME INPUTS: the double implementation is run at the float-rounded
//   alpha, view and u (exactly representable in double), so the figures measure the float arithmetic,
//   not the rounding of the inputs. Direction: angle between the two (radians). Pdf or value: the
//   symmetric relative difference |f - d| / max(|f|, |d|) (0 when both are 0, 1 when one is 0);
// - for functions, also that difference in units of the function's conditioning at the input
//   ("cond ratio"): |f - d| / (eps_f |d| + spread), where spread is the largest change of the double
//   value when every float input moves by one float ulp (four sign patterns). A function evaluated
//   near one of its zeros (<w, m> -> 0 at the edge of visibility, wo -> -wi) has an unbounded relative
//   condition number; the ratio stays O(1) for an implementation that is as accurate as its inputs;
// - the sampler's returned pdf against its claimed analytic pdf (SamplerInfo::claimed_pdf) at the
//   returned direction, in double at the exact inputs: the relative difference, and the same cond
//   ratio with the spread over +-4 double ulps of the direction (the sampled direction is accurate to a
//   few ulps; the claimed pdf is a function of the direction only and can be far worse conditioned
//   than the sampler's own pdf, e.g. D_v as <w, m> -> 0).
// Regimes partition the configurations, first match wins (see stability_regime_name):
//   non-finite input, below horizon (theta > 90), exactly grazing (theta == 90), grazing
//   (85 < theta < 90), anisotropy >= 1:100, small alpha (max alpha <= 1e-3), large alpha (min > 2),
//   u at an end of [0, 1) (a component 0 or >= 1 - 2^-24), moderate (the rest).
#pragma once

#include "core/block_runner.h"
#include "core/run_control.h"
#include "microfacet/samplers.h"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace microsim {

struct StabilityGrid {
  std::vector<std::pair<double, double>> alphas;  // (alpha_x, alpha_y)
  std::vector<double> thetas_deg;                 // 90 gives wi.z == 0 exactly, 180 gives (0, 0, -1)
  std::vector<double> phis_deg;
  std::vector<double> u_values;    // per component; every pair (u0, u1) is used
  int random_u_per_view = 48;      // plus this many random u per view, from CounterRng(seed, view index)
  std::uint64_t seed = 20240611;

  // The extreme grid: alpha in {1e-4, 1e-3, 0.01, 0.1, 0.5, 1, 2, 10}, anisotropy 1:1000 both
  // ways (and 1:10), theta in {0, 0.001, 45, 80, 89, 89.9, 89.99, 89.999, 90, 95, 120, 179.9, 180},
  // phi in {0, 45, 90, 137}, u in {0, 0.5, 1 - 2^-24, 1 - 2^-53}^2 plus random u.
  static StabilityGrid standard();
};

enum class StabilityRegime : int {
  moderate,
  u_at_ends,
  small_alpha,
  large_alpha,
  anisotropic,
  grazing,
  exactly_grazing,
  below_horizon,
  non_finite_input,
};
inline constexpr int kStabilityRegimeCount = 9;
const char* stability_regime_name(StabilityRegime r);

// What limits an analytic function's float accuracy beyond its conditioning at the input: the trait that
// loosens its row's bound (stability_bound; docs/reference/stability.md), set where the function is listed.
enum class FloatAccuracyCaveat {
  none,
  // A generalised half vector -(wi + eta wo) that cancels at grazing incidence (dielectric transmission):
  // 64 units of the conditioning instead of 8 in the grazing, exactly grazing and below-horizon regimes.
  cancelling_half_vector_at_grazing,
  // A threshold test whose rounding slack is proportional to the type's eps (the bounded sampler's cap
  // test): the two precisions may take different sides of it (zero flips) where u is at an end of [0, 1).
  threshold_slack_of_eps,
};

// The worst cases of one (subject, regime).
struct StabilityMetrics {
  std::string subject;           // sampler name ("heitz2018") or function ("GGX::D", "dielectric_bsdf(T)")
  bool is_sampler = false;
  bool negative_control = false;
  ReturnedPdfCheck returned_pdf_check = ReturnedPdfCheck::everywhere;  // samplers: SamplerInfo's trait
  FloatAccuracyCaveat float_caveat = FloatAccuracyCaveat::none;        // functions: the function's trait
  StabilityRegime regime = StabilityRegime::moderate;
  std::uint64_t evaluations = 0;       // configurations evaluated (each in double and in float)
  std::uint64_t empty_double = 0;      // samplers: nullopt results in double
  std::uint64_t empty_float = 0;       // samplers: nullopt results in float
  std::uint64_t empty_mismatch = 0;    // float and double (same inputs) disagree on returning a sample
  std::uint64_t non_finite_double = 0; // NaN or infinity in an output (double)
  std::uint64_t non_finite_float = 0;  // NaN or infinity in an output (float)
  std::uint64_t negative = 0;          // negative pdf or value (double or float)
  double norm_error_double = 0;        // max | |direction| - 1 |
  double norm_error_float = 0;
  double angle_float_double = 0;       // max angle between float and double directions, radians
  double rel_float_double = 0;         // max relative difference float vs double of the pdf or value
  double cond_float_double = 0;        // functions: max cond ratio float vs double (see above)
  double rel_claimed = 0;              // samplers: max relative difference returned vs claimed pdf (double)
  double cond_claimed = 0;             // samplers: max cond ratio returned vs claimed pdf (double)
  // Reflected-direction samplers: samples with |wi + wo| < 2^-20, where the claimed pdf (a function of
  // wo that recovers m = normalize(wi + wo)) cannot be evaluated in double; not compared.
  std::uint64_t claimed_unverifiable = 0;
  std::uint64_t claimed_unverifiable_interior = 0;  // of which with both u components inside (0, 1 - 2^-24)
  // Functions: evaluations where exactly one of float and double is 0 (the two precisions took
  // different sides of a decision, e.g. a visibility or cap test); not in the cond ratio.
  std::uint64_t zero_flips = 0;
  std::uint64_t zero_flips_interior = 0;  // of which with both u components inside (0, 1 - 2^-24)
  std::string worst_angle_config, worst_rel_config, worst_cond_config, worst_claimed_config;
};

// The bounds that the tests assert, per (subject, regime); docs/reference/stability.md explains each. Unverifiable
// samples and zero flips may be allowed at u on the ends of [0, 1) (rim samples), never inside: a bound
// that does not depend on how many random u the grid adds.
struct StabilityBound {
  double norm_double = 0;
  double norm_float = 0;
  double angle_float_double = 0;         // samplers, radians
  double rel_float_double = 0;           // samplers (functions: see cond_float_double)
  double cond_float_double = 0;          // functions
  double rel_claimed = 0;                // samplers; ignored for negative controls
  double cond_claimed = 0;               // samplers; ignored for negative controls
  bool claimed_unverifiable_at_u_ends = false;  // allowed where a u component is 0 or >= 1 - 2^-24
  bool zero_flips_at_u_ends = false;            // allowed where a u component is 0 or >= 1 - 2^-24
  bool allow_empty = false;              // whether a sampler may return nullopt in this regime
  bool require_empty = false;            // every result must be nullopt (non-finite input)
  std::string note;                      // why a bound is looser than the default, if it is
};
StabilityBound stability_bound(const StabilityMetrics& row);
// Empty when the row is within its bound; otherwise says which figure exceeds which bound.
std::string stability_violations(const StabilityMetrics& row);

struct StabilityTable {
  StabilityGrid grid;
  std::vector<StabilityMetrics> rows;  // subjects in registry order, then functions; regimes in enum order
  BlockRange blocks;                   // the sweep's blocks these rows hold (stability_blocks)
  std::uint64_t total_blocks = 0;
  bool partial = false;                // cancelled: the rows of the completed prefix of the blocks
  std::uint64_t total_evaluations() const;
  std::size_t violation_count() const;
};

// The sweep runs in blocks (core/block_runner.h): block b < V is view b of the grid (alpha pairs, then
// thetas, then phis: V views), with its corner u and its random u from CounterRng(grid.seed, b); block V
// is the non-finite inputs. A block's rows are reduced into the table in block order (merge_metrics), so
// the table depends only on the grid and the blocks, never on threads, and the tables of shards merge
// into the whole sweep's bit for bit (stability_part.h).
std::uint64_t stability_blocks(const StabilityGrid& grid);

struct StabilityRun {
  std::optional<BlockRange> blocks;  // a shard; all blocks when unset
  RunControl run;                    // threads, cancel token, progress ("stability sweep": blocks)
};

// Sweeps `samplers` (the registry by default; tests pass deliberately broken ones to show that the
// sweep catches them) and, when include_functions, the analytic functions. Throws std::invalid_argument
// for blocks outside the sweep.
StabilityTable run_stability_sweep(const StabilityGrid& grid = StabilityGrid::standard(),
                                   std::span<const SamplerInfo> samplers = sampler_registry(),
                                   bool include_functions = true, const StabilityRun& run = {});

// Every (subject, regime) row of a sweep of these subjects, not yet evaluated, in the table's order, with
// the subjects' traits.
std::vector<StabilityMetrics> stability_rows(std::span<const SamplerInfo> samplers, bool include_functions);
// Adds the metrics of a later block range of the same (subject, regime) to `into`: counts summed, maxima
// taken, a worst configuration replaced only by a strictly larger worst (as the sweep does value by value).
void merge_metrics(StabilityMetrics& into, const StabilityMetrics& later);

// A markdown table (one row per subject and regime) with a status column.
std::string stability_table_markdown(const StabilityTable& table);
nlohmann::json stability_table_json(const StabilityTable& table);

}  // namespace microsim
