// microsim: the traced oracle in statistical tests.
//
// 1. A traced VNDF histogram against the analytic D_v (what `microsim trace vndf` reports): Pearson
//    goodness of fit per binning (chi2.h, expected counts from the same cubature the analytic validator
//    uses, validate.h vndf_reference) and the total-variation distance
//      TV = 1/2 sum_bins | count_i / hits - p_i |,
//    whose Monte Carlo noise floor is about sum_i sqrt(p_i (1 - p_i) / (2 pi hits)) (the mean absolute
//    deviation of a binomial proportion, sqrt(2/pi) sigma, halved); compare TV with the floor
//    (noise_floor_tv) or with the exact quadric's TV at the same ray count.
// 2. A sampler (or samples from a file) against a traced histogram, loaded from HIST.exr or traced on the
//    fly: the two-sample chi-square homogeneity test (chi2.h: unequal totals handled by the K1/K2
//    weights) in each binning of the histogram, combined with the Sidak correction exactly as the
//    analytic validator combines its tests. Returns the analytic validator's ValidationReport, so the
//    verdict, exit codes and JSON keys are the same. The samples are drawn exactly as validate_sampler
//    draws them (sample i from CounterRng(seed, i)), so the same seed gives the same samples.
#pragma once

#include "stats/chi2.h"
#include "stats/histogram_io.h"
#include "core/random.h"
#include "trace/trace_vndf.h"
#include "validate/validate.h"

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace microsim {

// ---- traced histogram vs analytic D_v ------------------------------------------------------------------

double total_variation(std::span<const std::uint64_t> counts, std::uint64_t hits, std::span<const double> probability);
// Expected TV of an exact sampler with `hits` samples in bins of these probabilities (large-count limit).
double noise_floor_tv(std::span<const double> probability, std::uint64_t hits);

struct TraceFit {
  std::string binning;     // "sphere" or "lobe"
  double total_variation = 0;
  double noise_floor_tv = 0;
  ChiSquareResult chi2;    // goodness of fit against D_v (remainder cell: hits outside the binning)
};

struct TraceAnalysis {
  std::vector<TraceFit> fits;  // one per binning of the histogram
  double significance = 0.01;  // family-wise
  double p_value = 1;          // Sidak-adjusted smallest p
  bool rejected = false;
};

// Bin probabilities under D_v for the histogram's binnings (vndf_reference of validate.h, which must use
// the histogram's rows), stored into histogram.probability, then the fits. histogram.binnings must be
// {sphere(rows), lobe(ggx, wi, microfacet_normal, rows)} in any order.
TraceAnalysis analyse_against_vndf(TracedHistogram& histogram, const GGX<double>& ggx, const Vec3<double>& wi,
                                   std::span<const std::uint64_t> unbinned = {}, double significance = 0.01);
nlohmann::json to_json(const TraceAnalysis& analysis);

// The seed of the oracle's trace when a sampler is compared with it on the fly: a mix of the sampler's
// seed, so that the two samples never share counter-based streams (CounterRng(seed, i) for sample i and
// CounterRng(seed, b) for ray block b would otherwise coincide).
constexpr std::uint64_t oracle_seed(std::uint64_t sampler_seed) { return mix64(sampler_seed ^ 0x6f7261636c65ULL); }

// Traces the exact (mesh_level < 0) or meshed ellipsoid for (ggx, wi) into a histogram with the
// validator's binnings of `rows` rows, run parameters in histogram.attributes; no analytic fit.
struct OracleTraceOptions {
  std::uint64_t rays = 4'000'000;
  std::uint64_t seed = 1;
  int rows = 31;
  int mesh_level = -1;
  RunControl run;
};
// The attributes naming the traced ellipsoid: surface, target, mesh_level, alpha (enough to rebuild it).
void record_ellipsoid_target(TracedHistogram& histogram, const EllipsoidTarget& target);
TracedHistogram trace_vndf_histogram(const GGX<double>& ggx, const Vec3<double>& wi, const OracleTraceOptions& options,
                                     TraceResult* raw = nullptr);

// ---- a traced reference's own departure from D_v ---------------------------------------------------------

// A traced histogram stands for D_v only as far as its surface is exactly GGX with Smith's masking: a finite
// tile holds few facets in the NDF's tail, a meshed ellipsoid is faceted, and a heightfield's masking is not
// exactly Smith's. The two-sample test then rejects even an exact sampler once the samples resolve that
// difference, and the verdict would be the reference's, not the sampler's. Estimated from the trace's own
// Pearson fit to D_v (X^2 with d degrees of freedom at H hits): E[X^2] - d = H sum_i (t_i - q_i)^2 / q_i, so
// at S samples the two-sample statistic is non-central chi-square with lambda(S) = (X^2 - d) S / (S + H)
// (the limiting power of Pearson's test: Mitra 1958, "On the limiting power function of the frequency
// chi-square test", Ann. Math. Statist. 29). The estimate is taken low: X^2 - d less 3.09 of its null standard deviations sqrt(2 d) (an exact
// oracle is flagged in 0.1% of its traces), and at most the observed excess.
struct ReferenceBias {
  std::vector<std::string> binnings;  // per binning of the histogram:
  std::vector<double> excess;         // max(0, X^2 - d - 3.09 sqrt(2 d)) of the trace against D_v
  std::vector<int> dof;
  std::uint64_t samples = 0;          // the comparison's sample count
  double false_rejection = 0;         // probability that it rejects an exact sampler at `samples`
  double bound = 0;                   // what a usable reference may cost: twice the family-wise level
  std::uint64_t max_samples = 0;      // the largest sample count within the bound (UINT64_MAX: any)
  bool usable() const { return false_rejection <= bound; }
  std::string describe() const;       // one sentence: the false-rejection probability, the bound, max_samples
};
// The bias of `traced` (its alpha and wi: histogram_ggx/histogram_wi) for a comparison with `samples` samples
// at the family-wise level `significance` (Sidak over the histogram's binnings, as the comparison combines them).
ReferenceBias reference_bias(const TracedHistogram& traced, std::uint64_t samples, double significance);
// Thrown by the comparisons below (before any sample is drawn, or once a file's samples are counted) when the
// reference is not usable at that sample count: no verdict about the sampler can be given.
struct BiasedReference : std::invalid_argument {
  explicit BiasedReference(ReferenceBias b);
  ReferenceBias bias;
};

// ---- sampler vs traced histogram -------------------------------------------------------------------------

// The view and roughness a histogram was traced for (from its attributes "alpha" and "wi"); throws
// HistogramIoError when they are missing or malformed.
GGX<double> histogram_ggx(const TracedHistogram& histogram);
Vec3<double> histogram_wi(const TracedHistogram& histogram);

// Draws options.samples samples from the sampler (microfacet-normal samplers only; throws
// std::invalid_argument for a sampler of reflected directions) and compares them with the traced
// histogram. options.rows is ignored (the histogram's binnings are used).
ValidationReport compare_sampler_to_trace(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                                          const ValidationOptions& options, const TracedHistogram& traced);
// Samples from elsewhere (microfacet normals, unit vectors) against the traced histogram; the file version
// streams the file (SampleFileError on a bad row).
ValidationReport compare_samples_to_trace(std::span<const Vec3<double>> samples, std::string source,
                                          const GGX<double>& ggx, const Vec3<double>& wi,
                                          const ValidationOptions& options, const TracedHistogram& traced);
ValidationReport compare_sample_file_to_trace(DirectionSampleReader& reader, std::string source, const GGX<double>& ggx,
                                              const Vec3<double>& wi, const ValidationOptions& options,
                                              const TracedHistogram& traced);
// A reference too biased for the sample count throws BiasedReference; the report's check "reference_bias"
// states the bias of a usable one.
// Too few samples (or oracle hits) throw InsufficientData (chi2.h) before any sample is drawn (after the
// file is read): the two-sample tests need, on each side, goodness_of_fit_minimum_samples of the
// oracle's proportions (with its remainder cell): trace_minimum_samples.
std::uint64_t trace_minimum_samples(const TracedHistogram& traced);

}  // namespace microsim
