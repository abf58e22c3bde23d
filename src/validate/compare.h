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
// Too few samples (or oracle hits) throw InsufficientData (chi2.h) before any sample is drawn (after the
// file is read): the two-sample tests need, on each side, goodness_of_fit_minimum_samples of the
// oracle's proportions (with its remainder cell): trace_minimum_samples.
std::uint64_t trace_minimum_samples(const TracedHistogram& traced);

}  // namespace microsim
