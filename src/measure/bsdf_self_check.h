// measure: the tests of the BSDF battery (bsdf_battery.h) that need no exact reference, so that a compensated or
// a multiple-scattering BSDF, whose eval() may be a noisy unbiased estimate (Heitz et al. 2016 sec. 6), is
// tested as honestly as a single-scattering one:
//   - density:  its samples' directions against its own pdf() (when it has one): the counts per cell of an
//               equal-area partition of the sphere against the integral of pdf() over the cell;
//   - integral: its weighted sample histogram against the integral of eval() over each cell: E[weight 1_cell(wo)]
//               = integral over the cell of f |cos wo| for any sampler (the "eval is the integral its sampler
//               implies" of Cycles' mf_eval against mf_sample), shapes by the weighted chi-square of
//               stats/chi2.h (the integral's own noise in its variance: a stochastic eval's too);
//   - furnace:  the mean sample weight (lost samples weigh 0) against the integral of eval() over the sphere,
//               both with standard errors (the white furnace with an error bar), two-sided normal test.
// The cell integrals: one point jittered in each stratum of an n x n grid per cell (z, phi; n even), their mean
// times the cell's solid angle; the variance of that mean by collapsed strata (neighbouring strata paired), an
// overestimate: a conservative test.
// Against a stochastic reference (the Smith walk of scatter/smith_walk.h) or with a stochastic eval():
//   - the walk's sampling: the weighted histograms of the BSDF's samples and the walk's own samples per cell
//     (weighted chi-square) and their albedos (difference with both errors);
//   - eval against the walk's next-event estimate at query pairs, by a chi-square over pairs with both
//     standard errors (the BSDF's from repeated calls);
//   - reciprocity of a stochastic eval by the same chi-square.
// A test of a stochastic eval() (integral, eval, reciprocity) that rejects is run again on fresh calls, and rejects
// only if this second stage rejects too: a heavy-tailed estimate (the Smith walk's) gets from its own few hundred
// calls a standard error too small and a mean mostly too low. The pair tests' second stage: 64 times the calls per
// pair (4 times the reference's walks), each standard error at least the first stage's scaled to the larger count
// and at least |mean| times the largest relative standard deviation per call over all pairs (a robust upper
// bound: the tail one pair's calls missed, another's met); the integral test's: 4 times the points per cell, each
// cell's variance at least the first stage's scaled. The second stage tests on data of its own: the level holds.
// Weights and values of several channels are averaged over the channels.
#pragma once

#include "measure/bsdf_battery.h"
#include "validate/bsdf_queries.h"

#include <cstdint>
#include <string>
#include <vector>

namespace microsim::battery {

// One view's samples (lost ones counted, not kept).
struct ViewSamples {
  std::vector<Vec3<double>> wo;
  std::vector<double> pdf, weight;  // weight: channels per row
  std::uint64_t drawn = 0, lost = 0, non_finite = 0;
};

// The cell of the sphere's equal-area partition (kCellsZ slices of z by kCellsPhi of phi) that holds w.
inline constexpr int kCellsZ = 16, kCellsPhi = 16, kCells = kCellsZ * kCellsPhi;
int sphere_cell(const Vec3<double>& w);

// The points the cell integrals evaluate eval() and pdf() at: cell after cell in sphere_cell's order, in each an
// n x n grid of strata (n = cell_strata(points_per_cell): the even number nearest sqrt(points_per_cell), at least 2),
// z-major, one point jittered in each (CounterRng(seed ^ constant, cell)); neighbouring strata in pairs, as the
// variance by collapsed strata wants them.
int cell_strata(int points_per_cell);
std::vector<Vec3<double>> cell_points(int points_per_cell, std::uint64_t seed);

// density (when b has a pdf()), integral and furnace of one view, each at `level`.
// Their residual maps go to `residuals`.
std::vector<BatteryLine> self_tests(const BsdfUnderTest& b, const Vec3<double>& wi, const ViewSamples& s,
                                    const std::string& view, double level, const BatteryOptions& o,
                                    std::vector<BatteryResiduals>& residuals);

// The same tests from eval() and pdf() already known at a view's cell points (a file the renderer filled in):
// value the channel mean of eval() at each point, pdf() at each (empty: no density test); the points kCells
// blocks of equal size, cell after cell, an even number of points per cell, neighbouring strata in pairs.
std::vector<BatteryLine> cell_tests(const ViewSamples& s, int channels, const std::vector<double>& value,
                                    const std::vector<double>& pdf, const std::string& view, double level,
                                    std::vector<BatteryResiduals>& residuals);

// The BSDF's samples against the Smith walk's samples from wi (the walk of the claimed material on ggx's Smith
// microsurface): shapes and albedo, one line at `level`.
BatteryLine sampling_against_walk(const BsdfUnderTest& b, const Material& m, const GGX<double>& ggx,
                                  const Vec3<double>& wi, const ViewSamples& s, const std::string& view, double level,
                                  const BatteryOptions& o);

// The sample holding the largest share of the weights' spread (their channel mean per row, the lost samples as
// 0; stats/chi2.h, DominantValue). A test of the weights' mean from their own standard error (furnace,
// integral, sampling) is void when it dominates (a firefly raises the mean and its error together):
// fail_if_dominated fails `line`, its detail naming the sample.
DominantValue weight_dominance(const ViewSamples& s, int channels);
void fail_if_dominated(const DominantValue& d, BatteryLine& line);

// The pairs of `q` the stochastic tests use: off the horizon (|z| >= 0.1 both), at most `count`, spread over q.
std::vector<BsdfQuery> stochastic_pairs(const std::vector<BsdfQuery>& q, std::size_t count);

// eval() against the Smith walk's next-event estimate at the pairs (a chi-square over pairs, both errors).
BatteryLine eval_against_walk(const BsdfUnderTest& b, const Material& m, const GGX<double>& ggx,
                              const std::vector<BsdfQuery>& pairs, double level, const BatteryOptions& o);

// A stochastic eval()'s reciprocity at the pairs (a chi-square over pairs, both errors).
BatteryLine stochastic_reciprocity(const BsdfUnderTest& b, const Material& m, const std::vector<BsdfQuery>& pairs,
                                   double level, const BatteryOptions& o);

// f(b, a) / f(a, b) by reciprocity in the BSDF's transport mode (1 for a reflection).
double reciprocal_ratio(const Material& m, const BsdfConvention& c, const Vec3<double>& a, const Vec3<double>& b);

}  // namespace microsim::battery
