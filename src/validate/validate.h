// microsim: the statistical validator of direction samplers (docs/reference/validator.md).
//
// One validation draws N samples (or takes them from a file) for one configuration (alpha, view wi)
// and runs, in one report:
//  1. chi-square goodness of fit in equal-area SPHERE bins (DirectionBinning::sphere);
//  2. chi-square goodness of fit in LOBE bins (DirectionBinning::lobe: the Heitz 2018 hemisphere
//     configuration), which keeps its power at small alpha where the sphere bins see one cell;
//  3. E[weight] against the projected area |wi.z| / G1(wi) (microfacet-normal samplers that return a
//     pdf): weight = D(m) <wi, m>+ / pdf(m) has that mean for ANY correct sampler of normals whose pdf
//     covers the visible normals; z-test with the sample standard error;
// and the hard checks: no sample outside the domain (non-finite, or |w| off 1 by more than
// unit_tolerance), the claimed pdf's integral over the sphere at most 1 + integral_tolerance, the pdf
// returned with each sample equal to the claimed analytic pdf within pdf_tolerance (relative).
// The verdict combines the statistical tests (1-3) with the Sidak correction at the family-wise level
// `significance`; any failed hard check fails the validation.
//
// The tests are the stages of one battery shared with the comparison against the traced oracle
// (battery.h, compare.h). Expected counts come from adaptive cubature of the claimed pdf over each bin
// (binning.h); a sampler that fails (returns nothing) is counted in a remainder cell whose expected
// probability is the mass the claimed pdf leaves outside the bins (1 - the bins' total).
//
// Reproducible: sample i uses CounterRng(seed, i) (two uniforms), whatever the thread count.
#pragma once

#include "core/block_runner.h"
#include "core/run_control.h"
#include "stats/binning.h"
#include "stats/chi2.h"
#include "stats/figure.h"
#include "microfacet/ggx.h"
#include "microfacet/bsdf_convention.h"
#include "microfacet/material.h"
#include "microfacet/samplers.h"
#include "validate/sample_io.h"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace microsim {

enum class Precision { float32, float64 };

// Default relative pdf tolerances (returned vs analytic pdf, per sample, |a - b| / max(a, b)), beyond what
// the rounding of the direction explains: double samplers agree to ~1e-12; the zoo's float samplers lose
// between 1e-5 and 1e-4 (bounded2023 at alpha 1e-3; docs/reference/validator.md).
inline constexpr double kPdfToleranceDouble = 1e-6;
inline constexpr double kPdfToleranceFloat = 1e-4;

struct ValidationOptions {
  std::uint64_t samples = 1'000'000;
  std::uint64_t seed = 1;
  int rows = 31;               // rows of both binnings (odd); cols = 2 rows
  double significance = 0.01;  // family-wise level of the verdict
  Precision precision = Precision::float64;
  int worst_cells = 8;
  double pdf_tolerance = 0;            // 0: kPdfToleranceDouble / kPdfToleranceFloat by precision
  // A sample fails the returned-pdf check when its relative error exceeds pdf_tolerance plus twice the
  // relative change of the claimed pdf under a perturbation of the stored vector by its rounding (2^-23
  // in float, 2^-52 in double; a rotation along either tangent or a change of its length): float
  // rounding alone can carry a sample across a jump of the claimed pdf (the bounded sampler's cap edge)
  // or move D by percents at alpha = 1e-3 when the half vector of two nearly opposite grazing
  // directions is recomputed; in double, the lengths of wi and wo off 1 by an ulp move D by 5e-6 at
  // alpha = 1e-4, theta = 89.99 deg (battery.cpp, rounding_sensitivity). Fraction allowed to fail: 0.
  double pdf_outlier_fraction = 0;
  double integral_tolerance = 1e-5;    // the claimed pdf may integrate to at most 1 + this
  double unit_tolerance = 1e-5;        // samples with | |w| - 1 | above this are outside the domain
  // Relative floor of the weight test's standard error (rounding of pdf and D, not statistics):
  // 0 means 1e-9 in double, 1e-5 in float.
  double weight_rounding = 0;
  // With a reference conditioned on the upper hemisphere: how many reflections the renderer dropped below
  // the horizon besides the samples given (dropped_fraction_test); unset: not known.
  std::optional<std::uint64_t> dropped_below_horizon;
  // The BSDF a file's weight columns are tested against (weight_test.h; reflected directions, mirror or
  // conductor); unset: the weights are not tested.
  std::optional<Material> bsdf;
  // The convention of the renderer's BSDF that the weights are tested in (transport mode, masking form).
  BsdfConvention convention;
  RunControl run;  // threads, cancel token, progress ("sampling")
  // Draw only these blocks of kSampleBlock samples (a shard: validation_part.h); all when unset.
  std::optional<BlockRange> blocks;
};

// One binning of a reference and its bin probabilities under the claimed pdf.
struct ReferenceBins {
  const DirectionBinning& binning;
  const BinIntegrals& probability;
};

// The claimed distribution of one configuration and its bin probabilities (expensive: adaptive
// cubature over two binnings; share it between samplers that claim the same pdf).
struct ReferenceDistribution {
  SampleDomain domain;
  GGX<double> ggx;
  Vec3<double> wi;
  std::function<double(const Vec3<double>&)> pdf;  // per unit solid angle of the sample direction
  DirectionBinning sphere;
  DirectionBinning lobe;
  BinIntegrals sphere_probability;
  BinIntegrals lobe_probability;
  // The mass of the claimed pdf this reference keeps: 1, or for a dump of the kept samples only their
  // probability (kept_samples_reference, above_horizon_reference: pdf and probabilities divided by it).
  double kept_mass = 1;
  bool kept_only = false;  // conditioned on the kept samples (kept_samples_reference, above_horizon_reference)
  // A dielectric's index across over wi's side, for the half vector of a refracted sample (0: no refraction).
  double refraction_eta = 0;
  // The pdf the sampler returns with a sample: the claimed pdf before any conditioning on the kept samples.
  double returned_pdf(const Vec3<double>& w) const { return pdf(w) * kept_mass; }
  // The binnings the samples are tested in, in this order (sphere, lobe).
  std::vector<ReferenceBins> binned() const { return {{sphere, sphere_probability}, {lobe, lobe_probability}}; }
};

// `breaks`: functions of the direction whose zero sets are curves where the pdf jumps (see
// IntegrationOptions::breaks); the curves where every pdf of the zoo jumps or kinks (the horizon of
// the half vector, the visibility boundary wi . m = 0) are added automatically. `focus`: directions where
// the pdf has mass beside the lobe binning's lattice (a dielectric's refracted lobe).
using DirectionFunction = std::function<double(const Vec3<double>&)>;
std::shared_ptr<const ReferenceDistribution> prepare_reference(DirectionFunction pdf, SampleDomain domain,
                                                               const GGX<double>& ggx, const Vec3<double>& wi, int rows,
                                                               std::vector<DirectionFunction> breaks = {},
                                                               const std::vector<Vec3<double>>& focus = {},
                                                               double rel_tolerance = 1e-7);
// The reference a sampler claims (its claimed_pdf), and the analytic VNDF reference of a domain:
// D_v(wi, m) for normals, GGX::visible_reflection_pdf(wi, wo) for reflected directions.
std::shared_ptr<const ReferenceDistribution> claimed_reference(const SamplerInfo& sampler, const GGX<double>& ggx,
                                                               const Vec3<double>& wi, int rows);
std::shared_ptr<const ReferenceDistribution> vndf_reference(SampleDomain domain, const GGX<double>& ggx,
                                                            const Vec3<double>& wi, int rows);

// The densities a file of samples can claim (`validate --from --pdf`): the zoo's, as the claimed pdf of
// its reference sampler of that density (samplers.h, reference_sampler), and the pdf of reflection by
// VNDF sampling (GGX::visible_reflection_pdf).
enum class FilePdf {
  vndf,        // normals, D_v(wi, m): VNDF samplers (Heitz 2018, Dupuy & Benyoub 2023, ...)
  ndf,         // normals, D(m) m.z: samplers of the NDF (Walter et al. 2007)
  bounded,     // reflected directions, the bounded VNDF (Eto & Tokuyoshi 2023)
  reflection,  // reflected directions of VNDF sampling, D_v(wi, m) / (4 <wi, m>)
  bsdf,        // outgoing directions of a BSDF's VNDF sampling (bsdf_validation.h, file_claimed_density):
               // a conductor's reflections, a dielectric's reflections and refractions over the whole sphere
};
struct ClaimedDensity {
  SampleDomain domain;
  DirectionFunction pdf;                  // per unit solid angle
  std::vector<DirectionFunction> breaks;  // where it jumps beyond the common curves (prepare_reference)
  std::vector<Vec3<double>> focus;        // where it has mass beside the lobe's lattice (prepare_reference)
  double rel_tolerance = 1e-7;            // of each bin's cubature (IntegrationOptions::rel_tolerance)
};
// FilePdf::bsdf needs the BSDF: std::invalid_argument here (bsdf_validation.h, file_claimed_density).
ClaimedDensity claimed_density(FilePdf pdf, const GGX<double>& ggx, const Vec3<double>& wi);
inline bool claims_reflected_directions(FilePdf pdf) { return pdf != FilePdf::vndf && pdf != FilePdf::ndf; }
// Parses "vndf", "ndf", "bounded", "reflection", "bsdf" (std::invalid_argument naming the valid ones otherwise).
FilePdf parse_file_pdf(std::string_view name);
std::shared_ptr<const ReferenceDistribution> density_reference(const ClaimedDensity& density, const GGX<double>& ggx,
                                                               const Vec3<double>& wi, int rows);
// Reflected directions as renderers emit them: only those above the horizon (a reflection with wo.z <= 0
// is dropped). The density conditioned on wo.z > 0: pdf(wo) [wo.z > 0] / P_up, with P_up its mass above
// the horizon (by the same cubature, kept_mass). Throws std::invalid_argument for a density of normals or
// when the view leaves no mass above the horizon.
std::shared_ptr<const ReferenceDistribution> above_horizon_reference(const ClaimedDensity& density, const GGX<double>& ggx,
                                                                     const Vec3<double>& wi, int rows);
// A dump that holds only the samples its sampler kept, when the claimed density is already 0 where samples
// are lost (a BSDF's sampling density, bsdf_validation.h: a dielectric loses its reflections below the
// horizon and its refractions above it): the density conditioned on its own mass, pdf(wo) / P_kept.
// Throws std::invalid_argument when the density has no mass for this view.
std::shared_ptr<const ReferenceDistribution> kept_samples_reference(const ClaimedDensity& density, const GGX<double>& ggx,
                                                                    const Vec3<double>& wi, int rows);
// The binnings and the claimed pdf of claimed_reference, without the bin probabilities (no cubature):
// enough to tally samples (validation_part.h), not to test them (its probabilities are empty).
std::shared_ptr<const ReferenceDistribution> claimed_reference_bins(const SamplerInfo& sampler, const GGX<double>& ggx,
                                                                    const Vec3<double>& wi, int rows);

// The words of the weight_mean test's detail when returned pdfs printed as 0 leave it not applicable (a dump's
// notes repeat that detail, found by these words).
inline constexpr std::string_view kPdfsPrintedAsZero = "returned pdf(s) printed within their rounding of 0";

// A deterministic check or a statistical test of the report (every test but the binned chi-square ones).
struct SubTest {
  std::string name;
  bool applicable = true;
  bool statistical = false;  // enters the Sidak combination
  bool passed = true;
  double p_value = 1;        // statistical tests only
  double value = 0;          // the measured quantity (see detail)
  double tolerance = 0;      // its bound (hard checks)
  std::string detail;
  // How a failure names the test: a hard check's failure reads "label: detail" (the detail alone when
  // empty), a statistical test's "label test rejects: p = .. < ..: detail".
  std::string label;
};

// A chi-square test of the counts in one binning: goodness of fit against the bin probabilities of a
// claimed pdf, or the two-sample test against a traced oracle's counts (compare.h).
struct BinnedTest {
  std::string name;     // its key in the JSON report: "chi2_" + binning
  std::string binning;  // the binning's name (DirectionBinning::name: "sphere", "lobe")
  std::string label;    // how a rejection names the test: "chi-square", "two-sample chi-square against ..."
  ChiSquareResult chi2;
};

struct ValidationReport {
  std::string sampler;  // sampler name, or the source of the samples
  SampleDomain domain = SampleDomain::microfacet_normal;
  double alpha_x = 0, alpha_y = 0;
  Vec3<double> wi = Vec3<double>(0, 0, 1);
  std::uint64_t samples = 0, seed = 0;
  Precision precision = Precision::float64;
  std::uint64_t failed_samples = 0;   // sampler returned nothing
  std::uint64_t outside_domain = 0;   // non-finite or non-unit samples
  bool seeded = true;                 // drawn from `seed` (false: samples from elsewhere, nothing drawn)
  std::string storage;                // how samples from a file were stored ("float32 .npy", "text"), else ""
  // Rows of a sample file that hold the sampler's failures (non-finite values, the zero vector; they
  // are counted in outside_domain), and where the first few are ("row 5 (0-based)", "line 12").
  std::uint64_t invalid_rows = 0;
  std::vector<std::string> first_invalid_rows;
  // Samples in sphere bins where the claimed pdf has no mass at all (a lower bound of those where it is
  // zero; 0 against a traced oracle): most of them means a frame mistake (diagnose_sample_frame).
  std::uint64_t samples_where_pdf_is_zero = 0;

  // The tests: one chi-square test per binning (in the binnings' order), then the other tests in the
  // order their failures are listed: the hard checks "domain", "pdf_integral", "returned_pdf", then the
  // statistical "weight_mean" (E[weight] vs |wi.z| / G1; not applicable where it cannot be run).
  std::vector<BinnedTest> binned;
  std::vector<SubTest> checks;
  // The chi-square test in the binning of that name, the check of that name (std::out_of_range if none).
  const ChiSquareResult& chi2(std::string_view binning) const;
  const SubTest& check(std::string_view name) const;

  int statistical_tests = 0;
  double per_test_significance = 0;  // Sidak level of each statistical test
  double significance = 0.01;        // family-wise level
  double p_value = 1;                // Sidak-adjusted smallest p of the statistical tests
  double statistic = 0;              // of the chi-square test with the smallest p
  int dof = 0;
  bool passed = false;
  std::vector<std::string> failures;  // why it failed (empty when passed)
  // What would explain a rejection (a frame mistake, samples a renderer dropped), and what the user must know
  // whatever the verdict (what a dump could not show: dump_validation.h).
  std::vector<std::string> hints, notes;
  double seconds = 0;
  // The binned counts behind the chi-square tests (one per binning, in the same order; bins only,
  // without the remainder cell), for figures (figure.h): expected = samples x the reference's bin
  // probability, or, against a traced oracle, the oracle's counts rescaled to the samples' total (then
  // the figure's residual ignores the oracle's own noise: trace many more rays than samples for a fair
  // picture).
  std::vector<BinnedComparison> histograms;
};

// ---- samples in blocks ------------------------------------------------------------------------------
// A validation streams its samples: each block is drawn (or read), binned and checked, then dropped, so
// that memory does not grow with the number of samples. Block b holds samples [b kSampleBlock,
// (b + 1) kSampleBlock); per-block partial sums are combined in block order, so every floating-point
// result is independent of the thread count and of how the blocks were produced.
inline constexpr std::uint64_t kSampleBlock = std::uint64_t(1) << 16;
inline constexpr std::size_t kChunkBlocks = 16;  // blocks processed concurrently (then reduced in order)

struct SampleBlockView {
  std::uint64_t first = 0;                  // index of its first sample
  std::span<const Vec3<double>> directions;
  std::span<const double> pdfs;             // returned pdfs; empty when the samples came without one
  std::span<const std::uint8_t> valid;      // 0 where the sampler returned nothing; empty: all valid
  std::span<const PrintedRounding> rounding;  // a text file's printed digits per sample; empty: binary storage
};
// visit(block, slot) runs concurrently for the blocks of a chunk (slot: the block's place in its chunk,
// < kChunkBlocks); chunk_done(blocks) runs after each chunk, in order, on the calling thread.
using SampleBlockVisitor = std::function<void(const SampleBlockView& block, std::size_t slot)>;
using ChunkDone = std::function<void(std::size_t blocks)>;

// Samples as every validation draws them (validate_sampler, and compare.h against the traced oracle):
// sample i from CounterRng(options.seed, i), two uniforms, in the sampler's float or double version
// (options.precision), options.samples of them (or those of the blocks options.blocks); identical
// whatever the thread count. Chunks of kChunkBlocks blocks start at the first block drawn.
void for_each_drawn_block(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                          const ValidationOptions& options, const SampleBlockVisitor& visit,
                          const ChunkDone& chunk_done = {});
// Samples from elsewhere: a span, or a file read block by block (sample_io.h); all valid, no pdfs. With `run`,
// a cancelled run stops before the next chunk (Cancelled thrown).
void for_each_block(std::span<const Vec3<double>> samples, const SampleBlockVisitor& visit,
                    const ChunkDone& chunk_done = {}, const RunControl* run = nullptr);
void for_each_block(DirectionSampleReader& reader, const SampleBlockVisitor& visit, const ChunkDone& chunk_done = {},
                    const RunControl* run = nullptr);

// The drawn samples held in memory (for a dump; validations stream them instead).
struct SampleSet {
  std::vector<Vec3<double>> directions;
  std::vector<double> pdfs;         // returned pdfs; empty when the samples came without one
  std::vector<std::uint8_t> valid;  // 0 where the sampler returned nothing
  // Samples from elsewhere (a file): all valid, no pdfs.
  static SampleSet from_directions(std::span<const Vec3<double>> directions);
};
SampleSet draw_samples(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                       const ValidationOptions& options);

// ---- how many samples a validation needs ------------------------------------------------------------
// Too few samples for a test is never a pass. Each chi-square test of a validation (sphere and lobe
// bins, each with its remainder cell) must be able to reject: after pooling it needs two cells, which
// takes goodness_of_fit_minimum_samples(probabilities) samples (chi2.h: the largest cell and the rest
// must both expect >= 5). The validation needs the larger of the two; fewer throw InsufficientData,
// saying how many were given and how many are needed (at least minimum_samples_for_any_test() = 10).
std::uint64_t minimum_samples(const ReferenceDistribution& reference);
// Throws InsufficientData when `given` < minimum_samples(reference).
void require_samples(std::uint64_t given, const ReferenceDistribution& reference);
// Throws InsufficientData when `given` is below the bound of any binning (10): checkable before any work.
void require_samples_for_any_test(std::uint64_t given);

// Draws options.samples samples from the sampler (float or double version) and validates them
// against the pdf the sampler claims (reference: claimed_reference unless given). Throws
// InsufficientData before drawing when options.samples is too few.
ValidationReport validate_sampler(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                                  const ValidationOptions& options,
                                  std::shared_ptr<const ReferenceDistribution> reference = nullptr);

// Validates samples produced elsewhere against the analytic VNDF of `domain` (or the reference given).
// No returned pdf: the pdf and weight tests are not applicable. The file version streams the file
// (SampleFileError on a bad row; InsufficientData at its end when it held too few rows).
ValidationReport validate_samples(std::span<const Vec3<double>> samples, SampleDomain domain, const GGX<double>& ggx,
                                  const Vec3<double>& wi, const ValidationOptions& options,
                                  std::shared_ptr<const ReferenceDistribution> reference = nullptr);
ValidationReport validate_sample_file(DirectionSampleReader& reader, SampleDomain domain, const GGX<double>& ggx,
                                      const Vec3<double>& wi, const ValidationOptions& options,
                                      std::shared_ptr<const ReferenceDistribution> reference = nullptr);

// Samples (a file or an array, read again from their start) rejected with many of them where the claimed pdf
// is zero: the common frame mistakes of renderers' dumps (SampleFrame y_up, z_down, negated) undone one at a
// time, each a full validation of the samples read in that frame against `reference`. The first that passes; else the one that leaves the
// fewest samples where the pdf is zero, if under 1%; else nothing (no frame mistake explains it).
struct FrameHint {
  SampleFrame frame;
  ValidationReport report;  // of the file read in that frame
};
std::optional<FrameHint> diagnose_sample_frame(const DirectionSampleReader& samples,
                                               std::shared_ptr<const ReferenceDistribution> reference,
                                               const ValidationOptions& options);
// Whether a rejection's report calls for diagnose_sample_frame: more than 5% of its samples fall where the
// claimed pdf is zero (a correct dump has none there; a y-up dump of normals seen from phi = 0 about half).
inline bool looks_like_a_frame_mistake(const ValidationReport& r) {
  return !r.passed && 20 * r.samples_where_pdf_is_zero > r.samples;
}

std::string to_string(Precision precision);
nlohmann::json to_json(const SubTest& test);
nlohmann::json to_json(const ValidationReport& report);

}  // namespace microsim
