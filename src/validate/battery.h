// microsim: the one test battery behind `validate` (the analytic pdf, validate.h) and the comparison
// with the traced oracle (compare.h).
//
// As in Mitsuba 3's chi-square harness, a run keeps apart
//  - the domain: the binnings the samples are counted in, each with a remainder cell (binning.h);
//  - the subject: the samples (SampleSource: a sampler of the zoo drawn in blocks, a span, a file);
//  - the expectation of each binning (BinnedExpectation: the bin probabilities of the claimed pdf, or the
//    counts of a traced oracle), against which its counts are tested;
//  - the test stages: the tally (one pass over the samples: bin counts, and the per-sample checks against
//    a claimed pdf), one chi-square test per binning, the other checks (domain, pdf integral, returned
//    pdf, E[weight]) and the verdict (Sidak combination of the statistical tests, the failures).
// validate.cpp and compare.cpp choose the expectations and the checks; the stages are shared.
#pragma once

#include "core/exact_sum.h"
#include "validate/sample_io.h"
#include "validate/validate.h"

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace microsim::battery {

// ---- the subject --------------------------------------------------------------------------------------

struct SampleSource {
  std::string name;  // the sampler's name, or where the samples come from
  Precision precision = Precision::float64;
  bool returns_pdf = false;  // each sample comes with the pdf its sampler claims for it
  // Streams the samples block by block (validate.h, SampleBlockVisitor and ChunkDone).
  std::function<void(const SampleBlockVisitor&, const ChunkDone&)> stream;
  bool seeded = true;    // drawn from the options' seed (false: given samples, nothing random drawn)
  std::string storage;   // how given samples were stored ("float32 .npy", "text"; "" when drawn or in memory)
  // After the stream: the rows a file marked as the sampler's failures (none for other sources).
  std::function<InvalidRows()> invalid_rows;
};

// The samples every validation draws from a sampler (for_each_drawn_block), for view `wi`.
SampleSource drawn_samples(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                           const ValidationOptions& options);
// Samples from elsewhere, in double, without pdfs.
SampleSource given_samples(std::span<const Vec3<double>> samples, std::string name, const RunControl* run = nullptr);
SampleSource given_samples(DirectionSampleReader& reader, std::string name, const RunControl* run = nullptr);

// ---- the tally ----------------------------------------------------------------------------------------

// Mean and sum of squared deviations (Welford), combined across blocks in order (Chan, Golub, LeVeque 1983).
struct Moments {
  double n = 0, mean = 0, m2 = 0;
  void add(double x);
  void merge(const Moments& other);
};

// The per-sample checks against a claimed pdf, per block, reduced in block order.
struct PdfChecks {
  Moments weight;  // D(m) <wi, m>+ / returned pdf (microfacet normals with a returned pdf)
  double pdf_worst = 0;  // largest relative difference returned vs claimed pdf
  std::uint64_t pdf_worst_index = 0, pdf_outliers = 0;
  Vec3<double> worst_direction = Vec3<double>::Zero();
  double worst_returned = 0;
  bool printed = false;  // some pdf came from text: its printed digits' rounding was allowed for
  // Text: the sum over samples of how far their printed digits can move the weight (pdf and direction rounding),
  // and the samples whose pdf is printed within its rounding of 0 (their weight is unbounded).
  double weight_rounding = 0;
  std::uint64_t weight_unbounded = 0;
  // The sum over samples of how far D's cancellation in a renderer's pdf can move the weight (GGX::cancellation_of_D):
  // exact, so that blocks merged in any grouping (threads, ranks, shards) give the same bits.
  ExactSum weight_cancellation;
  // Returned pdfs checked, and those that are float32 data stored as float64 or printed as a float fills (every
  // one of them: the sampler's arithmetic was float32, and its weights carry float32's rounding).
  std::uint64_t pdfs_checked = 0, pdfs_from_float = 0;
  void merge(const PdfChecks& other);
};

struct Tally {
  std::uint64_t samples = 0;  // all of them, failed and outside the domain included
  std::uint64_t failed = 0;   // the sampler returned nothing: counted in every remainder cell
  std::uint64_t outside = 0;  // non-finite or not unit: in no cell
  std::uint64_t below_horizon = 0;  // inside the domain with w.z < 0
  std::vector<std::vector<double>> counts;  // per binning: its bins, then the remainder cell (integers)
  bool has_pdf = false;       // the samples came with returned pdfs
  PdfChecks checks;           // against the claimed pdf, when one was given: block_checks reduced in order
  // Each block's checks, in block order (empty when no claimed pdf was checked). The reduction of Moments
  // is not associative in floating point, so a merge of tallies reduces these again, from the first block.
  std::vector<PdfChecks> block_checks;
};

// The checks of blocks reduced in their order from an empty PdfChecks: Tally::checks of those blocks.
PdfChecks reduce_block_checks(const std::vector<PdfChecks>& blocks);

// Expected probabilities with the remainder cell last: the mass the claimed pdf leaves outside the bins,
// where failed samples (and samples outside a lobe's parameter space) are counted.
std::vector<double> with_remainder(const BinIntegrals& bins);

// The returned-pdf tolerance of a validation (ValidationOptions::pdf_tolerance, or its default by precision).
double returned_pdf_tolerance(const ValidationOptions& options, Precision precision);

// One pass over the samples: counts in `binnings`, and with `claimed` the checks of each returned pdf
// against claimed->pdf and of the weight. Integer counts summed per thread, checks reduced in block
// order: the tally depends only on the samples, not on the thread count.
Tally tally_samples(const SampleSource& source, const std::vector<const DirectionBinning*>& binnings,
                    const ValidationOptions& options, const ReferenceDistribution* claimed = nullptr);

// ---- the expectation of one binning ----------------------------------------------------------------------

class BinnedExpectation {
public:
  virtual ~BinnedExpectation() = default;
  virtual const DirectionBinning& binning() const = 0;
  // The chi-square test of the counts of this binning (bins, then the remainder cell).
  virtual ChiSquareResult test(const std::vector<double>& counts, const Tally& tally,
                               const ChiSquareOptions& options) const = 0;
  // The bins' expected counts for a figure of these counts.
  virtual BinnedComparison figure(const std::vector<double>& counts, const Tally& tally) const = 0;
  // How a rejection names the test ("chi-square", "two-sample chi-square against the traced oracle").
  virtual std::string label() const = 0;
};
using Expectations = std::vector<std::unique_ptr<const BinnedExpectation>>;

// Goodness of fit against the bin probabilities of a claimed pdf, for each binning of the reference.
Expectations analytic_expectations(const ReferenceDistribution& reference);
// The two-sample test against a traced oracle's counts (with its remainder cell: hits outside the bins).
// Throws InsufficientData when the samples pool into one cell (the test could not reject).
std::unique_ptr<const BinnedExpectation> oracle_expectation(const DirectionBinning& binning,
                                                            std::vector<double> oracle_counts);

std::vector<const DirectionBinning*> binnings_of(const Expectations& expectations);

// ---- the stages -----------------------------------------------------------------------------------------

// The report's description of the run: subject, configuration, sample counts, levels.
ValidationReport report_header(const SampleSource& source, SampleDomain domain, const GGX<double>& ggx,
                               const Vec3<double>& wi, const Tally& tally, const ValidationOptions& options);
// One chi-square test per binning, and its figure.
void add_binned_tests(ValidationReport& report, const Expectations& expectations, const Tally& tally,
                      const ValidationOptions& options);

// The report's rows outside the domain; given samples name the first invalid rows of their file.
SubTest domain_check(const ValidationReport& report, const Tally& tally, const ValidationOptions& options);
SubTest integral_check(const ReferenceDistribution& reference, const ValidationOptions& options);
SubTest returned_pdf_check(const Tally& tally, const ReferenceDistribution& reference, const ValidationOptions& options,
                           Precision precision);
SubTest weight_test(const Tally& tally, const ReferenceDistribution& reference, const ValidationOptions& options,
                    Precision precision);
SubTest not_applicable(std::string name, std::string detail);
// For a reference conditioned on the upper hemisphere (above_horizon) and a dump that says how many
// reflections it dropped below the horizon (options.dropped_below_horizon): that count against
// Binomial(samples + dropped, 1 - kept_mass), exact two-sided p-value. Not applicable without the count.
SubTest dropped_fraction_test(const Tally& tally, const ReferenceDistribution& reference,
                              const ValidationOptions& options);
// The note a rejection of reflected directions from a file gets when the file has no sample below the
// horizon although the claimed pdf puts mass there (a renderer's dump that drops them); "" otherwise.
std::string no_samples_below_horizon_note(const Tally& tally, const ReferenceDistribution& reference);

// The verdict: the Sidak combination of the statistical tests (every binned test, and the checks marked
// statistical), the headline (the binned test with the smallest p; among tests of equal p, in practice
// two p-values that underflow to 0, the last binning's: the lobe bins, which resolve the lobe at every
// alpha), the failures, in the order of report.checks: hard checks, then the binned tests, then the
// statistical checks. One rule for the analytic validator and the comparison with the oracle.
void decide(ValidationReport& report);

// The analytic validator's report of a tally of the samples of `source` against the claimed pdf of `ref`
// (its expectations: analytic_expectations(ref)): header, binned tests, the four checks, the verdict.
// `extra_checks` (the weight tests of a file) join the checks before the verdict.
ValidationReport analytic_report(const SampleSource& source, const Tally& tally, const Expectations& expectations,
                                 const ReferenceDistribution& ref, const ValidationOptions& options,
                                 std::vector<SubTest> extra_checks = {});

}  // namespace microsim::battery
