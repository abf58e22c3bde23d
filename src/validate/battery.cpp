// microsim: the test battery of validate and compare (battery.h).
#include "validate/battery.h"

#include "trace/trace_vndf.h"

#include <boost/math/distributions/binomial.hpp>
#include <fmt/core.h>
#include <fmt/ranges.h>
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <stdexcept>

namespace microsim {

const ChiSquareResult& ValidationReport::chi2(std::string_view binning_name) const {
  for (const BinnedTest& t : binned)
    if (t.binning == binning_name) return t.chi2;
  throw std::out_of_range(fmt::format("the report has no chi-square test in {} bins", binning_name));
}

const SubTest& ValidationReport::check(std::string_view name) const {
  for (const SubTest& t : checks)
    if (t.name == name) return t;
  throw std::out_of_range(fmt::format("the report has no test '{}'", name));
}

namespace battery {

// ---- the subject --------------------------------------------------------------------------------------

SampleSource drawn_samples(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                           const ValidationOptions& options) {
  SampleSource s;
  s.name = std::string(sampler.name);
  s.precision = options.precision;
  s.returns_pdf = true;
  s.stream = [&sampler, ggx, wi, &options](const SampleBlockVisitor& visit, const ChunkDone& chunk_done) {
    for_each_drawn_block(sampler, ggx, wi, options, visit, chunk_done);
  };
  return s;
}

SampleSource given_samples(std::span<const Vec3<double>> samples, std::string name, const RunControl* run) {
  SampleSource s;
  s.name = std::move(name);
  s.stream = [samples, run](const SampleBlockVisitor& visit, const ChunkDone& chunk_done) {
    for_each_block(samples, visit, chunk_done, run);
  };
  s.seeded = false;
  return s;
}

SampleSource given_samples(DirectionSampleReader& reader, std::string name, const RunControl* run) {
  SampleSource s;
  s.name = std::move(name);
  s.stream = [&reader, run](const SampleBlockVisitor& visit, const ChunkDone& chunk_done) {
    for_each_block(reader, visit, chunk_done, run);
  };
  s.seeded = false;
  s.storage = reader.storage();
  s.returns_pdf = reader.columns().has_pdf();  // the returned-pdf check, with the file's precision
  s.precision = reader.is_float32() ? Precision::float32 : Precision::float64;
  s.invalid_rows = [&reader] { return reader.invalid_rows(); };
  return s;
}

// ---- the tally ----------------------------------------------------------------------------------------

void Moments::add(double x) {
  n += 1;
  const double d = x - mean;
  mean += d / n;
  m2 += d * (x - mean);
}

void Moments::merge(const Moments& o) {
  if (o.n == 0) return;
  const double total = n + o.n, d = o.mean - mean;
  mean += d * o.n / total;
  m2 += o.m2 + d * d * n * o.n / total;
  n = total;
}

void PdfChecks::merge(const PdfChecks& o) {
  weight.merge(o.weight);
  pdf_outliers += o.pdf_outliers;
  printed = printed || o.printed;
  weight_rounding += o.weight_rounding;
  weight_cancellation += o.weight_cancellation;
  weight_unbounded += o.weight_unbounded;
  pdfs_checked += o.pdfs_checked;
  pdfs_from_float += o.pdfs_from_float;
  if (o.pdf_worst > pdf_worst) {
    pdf_worst = o.pdf_worst;
    pdf_worst_index = o.pdf_worst_index;
    worst_direction = o.worst_direction;
    worst_returned = o.worst_returned;
  }
}

PdfChecks reduce_block_checks(const std::vector<PdfChecks>& blocks) {
  PdfChecks total;
  for (const PdfChecks& b : blocks) total.merge(b);
  return total;
}

std::vector<double> with_remainder(const BinIntegrals& b) {
  std::vector<double> p = b.probability;
  p.push_back(std::max(0.0, 1.0 - b.total));
  return p;
}

double returned_pdf_tolerance(const ValidationOptions& options, Precision precision) {
  if (options.pdf_tolerance > 0) return options.pdf_tolerance;
  return precision == Precision::float32 ? kPdfToleranceFloat : kPdfToleranceDouble;
}

namespace {

double relative_difference(double a, double b) {
  if (a == b) return 0.0;  // both 0 included
  if (!std::isfinite(a) || !std::isfinite(b)) return std::numeric_limits<double>::infinity();
  return std::abs(a - b) / std::max(std::abs(a), std::abs(b));
}

// Largest relative change of the claimed pdf when the stored vector w moves by its rounding `step`:
// rotated by `step` radians along either tangent direction, or its length scaled by 1 +- step. How much
// of a pdf mismatch the rounding of w alone can explain.
// The length matters: the claimed pdf of a reflected direction recovers the half
// vector from wi + wo, unnormalised, and for nearly opposite grazing directions (alpha 1e-4, theta
// 89.99 deg: |wi + wo| ~ 1e-7) its tangential component is a difference of two numbers near 1 that is
// ~1e-11: a length of wi or wo off 1 by one ulp (their rounding) moves m by ~1e-5 relative and D by
// ~5e-6, although the returned pdf is exact (it matches the sampler run in long double to 1e-15, and the
// claimed pdf evaluated in long double at the exactly normalised vectors to 1e-8). No formula in double
// can remove this: the lengths' rounding is in the inputs. So the condition number of the claimed pdf
// with respect to that rounding enters the tolerance, like the tangential one.
double rounding_sensitivity(const ReferenceDistribution& ref, const Vec3<double>& w, double claimed, double step) {
  Vec3<double> t1, t2;
  orthonormal_basis(w, t1, t2);
  double s = 0;
  for (const Vec3<double>& t : {t1, Vec3<double>(-t1), t2, Vec3<double>(-t2)})
    s = std::max(s, relative_difference(ref.returned_pdf(Vec3<double>((w + step * t).normalized())), claimed));
  for (const double scale : {1 + step, 1 - step})
    s = std::max(s, relative_difference(ref.returned_pdf(Vec3<double>(w * scale)), claimed));
  return s;
}

// How far a float32 printed with 9 significant digits is from the decimal read back, relative: at most half a
// unit in the 9th digit.
constexpr double kNineDigits = 5e-9;

// How far a stored direction may be from the sampler's: twice the half-ulp of its precision.
constexpr double kFloatDirectionRounding = 2 * 0x1p-24, kDoubleDirectionRounding = 2 * 0x1p-53;

// The checks of each sample against a claimed pdf: the returned pdf, and the weight D <wi, m>+ / pdf.
class ClaimedPdfChecks {
public:
  // `given`: samples from a file or an array (their float64 values may be float32 data), not drawn here.
  ClaimedPdfChecks(const ReferenceDistribution& ref, const ValidationOptions& options, Precision precision, bool given)
      : ref_(ref),
        // The stored direction carries the rounding of its precision (a float sample has |dw| ~ 1e-7):
        // where the claimed pdf is ill-conditioned (a jump, or D at alpha = 1e-3 seen through a
        // cancelling half vector) that alone can change the analytic pdf by more than the tolerance.
        direction_rounding_(precision == Precision::float32 ? kFloatDirectionRounding : kDoubleDirectionRounding),
        pdf_tol_(returned_pdf_tolerance(options, precision)),
        float_tol_(returned_pdf_tolerance(options, Precision::float32)),
        widened_(given && precision == Precision::float64 && !(options.pdf_tolerance > 0)),
        float32_(precision == Precision::float32), back_(ref.wi.z() < 0),
        wi_front_(back_ ? Vec3<double>(-ref.wi) : ref.wi), weighs_(ref.domain == SampleDomain::microfacet_normal) {}

  // A failed sample contributes weight 0.
  void failed(PdfChecks& c) const {
    if (weighs_) c.weight.add(0.0);
  }

  // `printed`: a text file's digits (zero for binary storage and drawn samples).
  void inside(std::uint64_t i, const Vec3<double>& w, double pdf, const PrintedRounding& printed, PdfChecks& c) const {
    const double claimed = ref_.returned_pdf(w);
    const double amplification = d_amplification(w);
    const bool from_float = check_pdf(i, w, pdf, claimed, amplification, printed, c);
    if (!weighs_) return;
    const Vec3<double> m = back_ ? Vec3<double>(-w) : w;
    const double numerator = ref_.ggx.D(m) * std::max(wi_front_.dot(m), 0.0);
    double weight = 0;
    if (numerator > 0) weight = pdf > 0 ? numerator / pdf : std::numeric_limits<double>::infinity();
    if (printed.pdf > 0 && numerator > 0) printed_weight_rounding(w, claimed, pdf, weight, printed, c);
    // The pdf's D computed from cos theta_m biases the mean weight by at most a unit roundoff's effect on
    // average (measured a quarter of it: docs/records/validation.md), where the returned-pdf check allows 16.
    if (std::isfinite(weight))
      c.weight_cancellation.add(std::min(weight * (unit_roundoff(from_float) * amplification), ExactSum::kMaxTerm));
    c.weight.add(std::isfinite(weight) || printed.pdf == 0 ? weight : 0.0);
  }

private:
  // How far a text row's digits can move its weight D <wi, m> / pdf: the pdf by its half unit, the claimed
  // density (D <wi, m> over the projected area) by the direction's rounding. A pdf printed within its rounding
  // of 0 leaves the weight unbounded (counted; its weight taken as 0).
  void printed_weight_rounding(const Vec3<double>& w, double claimed, double pdf, double weight,
                               const PrintedRounding& printed, PdfChecks& c) const {
    if (!(pdf > printed.pdf)) {
      ++c.weight_unbounded;
      return;
    }
    const double moved = rounding_sensitivity(ref_, w, claimed, std::max(2 * printed.direction, direction_rounding_));
    c.weight_rounding += weight * (printed.pdf / (pdf - printed.pdf) + moved);
  }

  // The half vector of a sample (the normal itself, or that of the reflection or refraction it is), facing +z;
  // nullopt where there is none.
  std::optional<Vec3<double>> half_vector(const Vec3<double>& w) const {
    const Vec3<double> wo = back_ ? Vec3<double>(-w) : w;
    if (weighs_) return wo;
    Vec3<double> h = wo.z() > 0 ? Vec3<double>(wi_front_ + wo)
                     : ref_.refraction_eta > 0 ? Vec3<double>(-(wi_front_ + ref_.refraction_eta * wo))
                                               : Vec3<double>::Zero();
    const double len = h.norm();
    if (!(len > 0)) return std::nullopt;
    return h.z() < 0 ? Vec3<double>(-h / len) : Vec3<double>(h / len);
  }

  // A renderer's pdf holds D computed from cos theta_m, which loses about unit roundoff / alpha^2 near the peak
  // (pbrt-v4, Karis 2013): the factor a unit roundoff is amplified by in D at the sample (GGX::cancellation_of_D).
  double d_amplification(const Vec3<double>& w) const {
    const std::optional<Vec3<double>> h = half_vector(w);
    return h ? ref_.ggx.cancellation_of_D(*h) : 0.0;
  }
  // The unit roundoff of the sample's data: float32's for float32 data (or widened from it), else double's.
  double unit_roundoff(bool from_float) const { return from_float || float32_ ? 0x1p-24 : 0x1p-53; }

  // Checks one returned pdf; whether it is float32 data.
  bool check_pdf(std::uint64_t i, const Vec3<double>& w, double pdf, double claimed, double amplification,
                 const PrintedRounding& printed, PdfChecks& c) const {
    const double e = relative_difference(pdf, claimed);
    const bool text = printed.direction > 0 || printed.pdf > 0;
    // A float32 pdf widened to float64 (numpy's astype, Python's arrays), printed with digits a float32 fills, or
    // so printed with 9 significant digits and read back (np.loadtxt) came with float32's direction and
    // arithmetic: that sample gets float32's tolerance and rounding, as in a float32 file. (A float printed with
    // its last digit a tie, 969.1953125 as 969.195312, sits exactly a half unit away.)
    const double off_float = std::abs(double(float(pdf)) - pdf);
    const bool from_float =
        widened_ && (text ? off_float <= printed.pdf * (1 + 1e-6) : off_float <= kNineDigits * std::abs(pdf));
    // D's cancellation: 16 times (check-eval's K) one unit roundoff's effect.
    const double tol = (from_float ? float_tol_ : pdf_tol_) + 16 * (unit_roundoff(from_float) * amplification);
    ++c.pdfs_checked;
    if (from_float) ++c.pdfs_from_float;
    // Printed digits: the direction moved by up to their half unit per component, the pdf by its own.
    const double rounding = std::max(text ? 2 * printed.direction : 0.0,
                                     from_float ? kFloatDirectionRounding : direction_rounding_);
    const double printed_pdf = text ? printed.pdf / std::max(std::abs(pdf), std::abs(claimed)) : 0.0;
    c.printed = c.printed || text;
    if (e > tol + printed_pdf && e > tol + printed_pdf + 2 * rounding_sensitivity(ref_, w, claimed, rounding))
      ++c.pdf_outliers;
    if (e > c.pdf_worst) {
      c.pdf_worst = e;
      c.pdf_worst_index = i;
      c.worst_direction = w;
      c.worst_returned = pdf;
    }
    return from_float;
  }

  const ReferenceDistribution& ref_;
  const double direction_rounding_, pdf_tol_, float_tol_;
  const bool widened_;  // float64 storage with the default tolerance: float32-exact pdfs are float32 data
  const bool float32_;
  const bool back_;
  const Vec3<double> wi_front_;
  const bool weighs_;
};

// A thread's integer counts (summed in any order: exact).
struct ThreadCounts {
  std::vector<std::vector<std::uint64_t>> counts;  // per binning, the remainder cell last
  std::uint64_t samples = 0, failed = 0, outside = 0, below_horizon = 0;
};

// Streams the samples through the binnings and, with a claimed pdf, its per-sample checks.
// FastDirectionBinner gives exactly DirectionBinning::bin_of, three times faster.
class Tallier {
public:
  Tallier(const std::vector<const DirectionBinning*>& binnings, const ValidationOptions& options,
          const ClaimedPdfChecks* checks)
      : unit_tolerance_(options.unit_tolerance), checks_(checks), counts_([this] {
          ThreadCounts c;
          for (const std::size_t n : cells_) c.counts.emplace_back(n, 0);
          return c;
        }) {
    for (const DirectionBinning* b : binnings) {
      binners_.emplace_back(*b);
      cells_.push_back(std::size_t(b->size()) + 1);
    }
  }

  void visit(const SampleBlockView& block, std::size_t slot) {
    PdfChecks& c = chunk_[slot];
    c = PdfChecks{};
    ThreadCounts& counts = counts_.local();
    counts.samples += block.directions.size();
    const bool has_pdf = checks_ && !block.pdfs.empty();
    for (std::size_t k = 0; k < block.directions.size(); ++k) {
      const Vec3<double>& w = block.directions[k];
      if (!block.valid.empty() && !block.valid[k]) {
        failed(counts, has_pdf, c);
      } else if (bin(w, counts) && has_pdf) {
        checks_->inside(block.first + k, w, block.pdfs[k], block.rounding.empty() ? PrintedRounding{} : block.rounding[k], c);
      }
    }
  }

  void chunk_done(std::size_t blocks) {
    if (!checks_) return;
    for (std::size_t b = 0; b < blocks; ++b) block_checks_.push_back(chunk_[b]);
  }

  Tally result(bool has_pdf) const {
    Tally t;
    t.has_pdf = has_pdf;
    t.checks = reduce_block_checks(block_checks_);
    t.block_checks = block_checks_;
    for (const std::size_t n : cells_) t.counts.emplace_back(n, 0.0);
    for (const ThreadCounts& c : counts_) {
      t.samples += c.samples;
      t.failed += c.failed;
      t.outside += c.outside;
      t.below_horizon += c.below_horizon;
      for (std::size_t k = 0; k < t.counts.size(); ++k)
        for (std::size_t i = 0; i < c.counts[k].size(); ++i) t.counts[k][i] += double(c.counts[k][i]);
    }
    return t;
  }

private:
  void failed(ThreadCounts& counts, bool has_pdf, PdfChecks& c) const {
    if (has_pdf) checks_->failed(c);
    ++counts.failed;
    for (std::vector<std::uint64_t>& h : counts.counts) ++h.back();
  }

  // Counts a sample in each binning (its remainder cell where it has no bin); false outside the domain.
  bool bin(const Vec3<double>& w, ThreadCounts& counts) const {
    if (!w.allFinite() || !(std::abs(w.norm() - 1) <= unit_tolerance_)) {
      ++counts.outside;
      return false;
    }
    counts.below_horizon += std::uint64_t(w.z() < 0);
    for (std::size_t k = 0; k < binners_.size(); ++k) {
      const int b = binners_[k](w);
      std::vector<std::uint64_t>& h = counts.counts[k];
      ++h[b >= 0 ? std::size_t(b) : h.size() - 1];
    }
    return true;
  }

  const double unit_tolerance_;
  const ClaimedPdfChecks* checks_;
  std::vector<FastDirectionBinner> binners_;
  std::vector<std::size_t> cells_;  // per binning: its bins and the remainder cell
  std::array<PdfChecks, kChunkBlocks> chunk_{};
  std::vector<PdfChecks> block_checks_;
  tbb::enumerable_thread_specific<ThreadCounts> counts_;
};

}  // namespace

Tally tally_samples(const SampleSource& source, const std::vector<const DirectionBinning*>& binnings,
                    const ValidationOptions& options, const ReferenceDistribution* claimed) {
  std::optional<ClaimedPdfChecks> checks;
  if (claimed && source.returns_pdf) checks.emplace(*claimed, options, source.precision, !source.seeded);
  Tallier tallier(binnings, options, checks ? &*checks : nullptr);
  source.stream([&](const SampleBlockView& b, std::size_t slot) { tallier.visit(b, slot); },
                [&](std::size_t blocks) { tallier.chunk_done(blocks); });
  return tallier.result(source.returns_pdf);
}

// ---- the expectations -----------------------------------------------------------------------------------

namespace {

ChiSquareOptions describing(ChiSquareOptions chi, const DirectionBinning& b, std::string remainder) {
  chi.describe_cell = [&b, remainder = std::move(remainder)](int bin) {
    return bin < b.size() ? b.describe_bin(bin) : remainder;
  };
  return chi;
}

double total(const std::vector<double>& counts) { return std::accumulate(counts.begin(), counts.end(), 0.0); }

// The bin probabilities of the claimed pdf: Pearson's goodness of fit.
class AnalyticBins final : public BinnedExpectation {
public:
  AnalyticBins(const DirectionBinning& binning, const BinIntegrals& probability)
      : binning_(binning), probability_(probability) {}
  const DirectionBinning& binning() const override { return binning_; }
  std::string label() const override { return "chi-square"; }

  ChiSquareResult test(const std::vector<double>& counts, const Tally& tally,
                       const ChiSquareOptions& options) const override {
    // Sphere bins cover every direction: only failed samples reach their remainder cell.
    const char* remainder = binning_.kind() == BinningKind::sphere ? "remainder (failed samples)"
                                                                  : "remainder (failed or outside the lobe space)";
    return goodness_of_fit(counts, with_remainder(probability_), double(tally.samples),
                           describing(options, binning_, remainder), double(tally.outside));
  }

  BinnedComparison figure(const std::vector<double>& counts, const Tally& tally) const override {
    BinnedComparison c{binning_, std::vector<double>(counts.begin(), counts.begin() + binning_.size()),
                       probability_.probability, "analytic pdf"};
    for (double& e : c.expected) e *= double(tally.samples);
    return c;
  }

private:
  const DirectionBinning& binning_;
  const BinIntegrals& probability_;
};

// A traced oracle's counts: the two-sample homogeneity test.
class OracleBins final : public BinnedExpectation {
public:
  OracleBins(const DirectionBinning& binning, std::vector<double> oracle) : binning_(binning), oracle_(std::move(oracle)) {}
  const DirectionBinning& binning() const override { return binning_; }
  std::string label() const override { return "two-sample chi-square against the traced oracle"; }

  ChiSquareResult test(const std::vector<double>& counts, const Tally& tally,
                       const ChiSquareOptions& options) const override {
    ChiSquareResult c;
    if (!(total(counts) > 0)) {
      c.test = "two_sample_homogeneity";
      c.p_value = 0;
      c.rejected = true;
      c.reason = "no sample inside the domain";
      return c;
    }
    c = two_sample_homogeneity(counts, oracle_, describing(options, binning_, "remainder (failed or outside the bins)"));
    // The samples' own counts decide the pooling here: near the bound of the sample requirement the
    // cells can still pool into one by chance. A test that cannot reject is no pass.
    if (c.dof < 1)
      throw InsufficientData(fmt::format("{} sample(s) pooled into a single cell of the {} bins: the two-sample test "
                                         "cannot reject; use more samples (or more oracle rays)",
                                         tally.samples, binning_.name()),
                             tally.samples, tally.samples + 1);
    return c;
  }

  // The oracle's counts rescaled to the samples' total (remainder cells included in both).
  BinnedComparison figure(const std::vector<double>& counts, const Tally&) const override {
    const double total_sampled = total(counts), total_oracle = total(oracle_);
    BinnedComparison c{binning_, std::vector<double>(counts.begin(), counts.begin() + binning_.size()),
                       std::vector<double>(oracle_.begin(), oracle_.begin() + binning_.size()),
                       "traced oracle (rescaled)"};
    for (double& e : c.expected) e *= total_oracle > 0 ? total_sampled / total_oracle : 0.0;
    return c;
  }

private:
  const DirectionBinning& binning_;
  const std::vector<double> oracle_;
};

}  // namespace

Expectations analytic_expectations(const ReferenceDistribution& reference) {
  for (const ReferenceBins& b : reference.binned())
    if (b.probability.probability.size() != std::size_t(b.binning.size()))
      throw std::logic_error("analytic_expectations: the reference has no bin probabilities (claimed_reference_bins)");
  Expectations e;
  for (const ReferenceBins& b : reference.binned()) e.push_back(std::make_unique<AnalyticBins>(b.binning, b.probability));
  return e;
}

std::unique_ptr<const BinnedExpectation> oracle_expectation(const DirectionBinning& binning,
                                                            std::vector<double> oracle_counts) {
  return std::make_unique<OracleBins>(binning, std::move(oracle_counts));
}

std::vector<const DirectionBinning*> binnings_of(const Expectations& expectations) {
  std::vector<const DirectionBinning*> b;
  for (const auto& e : expectations) b.push_back(&e->binning());
  return b;
}

// ---- the stages -----------------------------------------------------------------------------------------

ValidationReport report_header(const SampleSource& source, SampleDomain domain, const GGX<double>& ggx,
                               const Vec3<double>& wi, const Tally& tally, const ValidationOptions& options) {
  ValidationReport r;
  r.sampler = source.name;
  r.domain = domain;
  r.alpha_x = ggx.alpha_x();
  r.alpha_y = ggx.alpha_y();
  r.wi = wi;
  r.samples = tally.samples;
  r.seed = options.seed;
  r.precision = source.precision;
  r.significance = options.significance;
  r.failed_samples = tally.failed;
  r.outside_domain = tally.outside;
  r.seeded = source.seeded;
  r.storage = source.storage;
  if (source.invalid_rows) {
    const InvalidRows invalid = source.invalid_rows();
    r.invalid_rows = invalid.count;
    r.first_invalid_rows = invalid.first;
  }
  return r;
}

void add_binned_tests(ValidationReport& r, const Expectations& expectations, const Tally& tally,
                      const ValidationOptions& options) {
  ChiSquareOptions chi;
  chi.significance = options.significance;  // replaced by the Sidak level in decide()
  chi.worst_cells = options.worst_cells;
  for (std::size_t k = 0; k < expectations.size(); ++k) {
    const BinnedExpectation& e = *expectations[k];
    const std::string binning = e.binning().name();
    r.binned.push_back({"chi2_" + binning, binning, e.label(), e.test(tally.counts[k], tally, chi)});
    r.histograms.push_back(e.figure(tally.counts[k], tally));
  }
}

SubTest domain_check(const ValidationReport& report, const Tally& tally, const ValidationOptions& options) {
  SubTest t;
  t.name = "domain";
  t.value = double(tally.outside);
  t.tolerance = 0;
  t.passed = tally.outside == 0;
  t.detail = fmt::format("{} sample(s) non-finite or with | |w| - 1 | > {}", tally.outside, options.unit_tolerance);
  if (report.invalid_rows > 0)
    t.detail = fmt::format("{} row(s) of the file hold the sampler's failures (non-finite values or the zero "
                           "vector), the first at {}",
                           report.invalid_rows, fmt::join(report.first_invalid_rows, ", "));
  return t;
}

SubTest integral_check(const ReferenceDistribution& ref, const ValidationOptions& options) {
  const BinIntegrals& sphere = ref.sphere_probability;
  SubTest t;
  t.name = "pdf_integral";
  t.value = sphere.total;
  t.tolerance = options.integral_tolerance;
  t.passed = std::isfinite(sphere.total) && sphere.total <= 1 + options.integral_tolerance;
  t.detail = fmt::format("integral of the claimed pdf over the sphere = {:.9f} (cubature error estimate {:.1e}), "
                         "must not exceed 1 + {}",
                         sphere.total, sphere.error_estimate, options.integral_tolerance);
  return t;
}

SubTest returned_pdf_check(const Tally& tally, const ReferenceDistribution& ref, const ValidationOptions& options,
                           Precision precision) {
  SubTest t;
  t.name = "returned_pdf";
  t.label = "returned pdf differs from the claimed pdf";
  t.applicable = tally.has_pdf;
  if (!tally.has_pdf) {
    t.detail = "no returned pdf (samples from a file)";
    return t;
  }
  const PdfChecks& c = tally.checks;
  const double pdf_tol = returned_pdf_tolerance(options, precision);
  const auto allowed = std::uint64_t(std::floor(std::max(options.pdf_outlier_fraction, 0.0) * double(tally.samples)));
  t.value = c.pdf_worst;
  t.tolerance = pdf_tol;
  t.passed = c.pdf_outliers <= allowed;
  t.detail = c.pdf_worst > 0
                 ? fmt::format("max |returned - claimed| / max(returned, claimed) = {:.3e} at sample {} "
                               "({:.6f}, {:.6f}, {:.6f}): returned {:.9g}, claimed {:.9g}; {} sample(s) above {:.0e} "
                               "plus the change a rounding of the direction can cause ({} allowed)",
                               c.pdf_worst, c.pdf_worst_index, c.worst_direction.x(), c.worst_direction.y(),
                               c.worst_direction.z(), c.worst_returned, ref.returned_pdf(c.worst_direction), c.pdf_outliers,
                               pdf_tol, allowed) +
                       (c.printed ? "; text: plus the rounding of the printed digits (half a unit in the last digit "
                                    "of the pdf and of each direction component)"
                                  : "")
                 : std::string("returned pdf equals the claimed pdf on every sample");
  return t;
}

// E[weight] against the projected area |wi.z| / G1(wi).
SubTest weight_test(const Tally& tally, const ReferenceDistribution& ref, const ValidationOptions& options,
                    Precision precision) {
  const bool applicable = tally.has_pdf && ref.domain == SampleDomain::microfacet_normal;
  SubTest t;
  t.name = "weight_mean";
  t.label = "E[weight]";
  t.applicable = t.statistical = applicable;
  if (!applicable) {
    t.detail = tally.has_pdf ? "not applicable: samples are reflected directions"
                             : "not applicable: no returned pdf (a file without a pdf column: --columns x,y,z,pdf)";
    return t;
  }
  const Moments& all = tally.checks.weight;
  if (tally.checks.weight_unbounded > 0) {
    t.applicable = t.statistical = false;
    t.detail = fmt::format("not applicable: {} {} (no significant digit): their weights D <wi, m> / pdf are "
                           "unbounded; print the pdfs with more digits (%.9g)",
                           tally.checks.weight_unbounded, kPdfsPrintedAsZero);
    return t;
  }
  const double expected = ref.ggx.projected_area(ref.wi);
  // A text file's digits move the mean by at most this much: only the deviation beyond it is tested.
  const double printed = all.n > 0 ? tally.checks.weight_rounding / all.n : 0.0;
  // Float32 data (a float32 file, or float32 values widened to float64 or printed so: every returned pdf) rounds
  // its weights as float32 does.
  const bool float_data = precision == Precision::float32 ||
                          (tally.checks.pdfs_checked > 0 && tally.checks.pdfs_from_float == tally.checks.pdfs_checked);
  // D computed from cos theta_m in the renderer's pdf (pbrt-v4, Karis 2013) loses up to unit roundoff / alpha^2
  // near the peak, and not evenly: the mean weight may move by the mean of a unit roundoff's effect, allowed
  // where it exceeds the rounding floor (below it, at larger roughness, the floor covers it).
  const double rounding = options.weight_rounding > 0 ? options.weight_rounding : float_data ? 1e-5 : 1e-9;
  const double mean_cancellation = all.n > 0 ? tally.checks.weight_cancellation.value() / all.n : 0.0;
  const double cancellation = mean_cancellation > rounding * expected ? mean_cancellation : 0.0;
  const double se_stat = all.n > 1 ? std::sqrt(all.m2 / (all.n - 1) / all.n) : 0.0;
  const double se = std::sqrt(se_stat * se_stat + (rounding * expected) * (rounding * expected));
  const double deviation = all.mean - expected;
  const double z = std::copysign(std::max(0.0, std::abs(deviation) - printed - cancellation), deviation) / se;
  t.value = all.mean;
  t.tolerance = expected;
  t.p_value = std::isfinite(z) ? std::erfc(std::abs(z) / std::sqrt(2.0)) : 0.0;
  t.detail = fmt::format("mean weight {:.9g} vs |wi.z|/G1 = {:.9g}: z = {:.3f} (standard error {:.3e}, "
                         "rounding floor {:.0e} relative{})",
                         all.mean, expected, z, se_stat, rounding,
                         cancellation > 0 ? fmt::format("; the deviation beyond {:.2e}, what D's cancellation in the "
                                                        "pdfs can move the mean by",
                                                        cancellation)
                                          : "") +
             (tally.checks.printed ? fmt::format("; text: the deviation beyond {:.3e}, what the printed digits can move "
                                                 "the mean by",
                                                 printed)
                                   : "");
  return t;
}

SubTest dropped_fraction_test(const Tally& tally, const ReferenceDistribution& ref, const ValidationOptions& options) {
  if (!options.dropped_below_horizon)
    return not_applicable("dropped_fraction", "not applicable: the dump does not say how many it dropped (--dropped N)");
  const std::uint64_t dropped = *options.dropped_below_horizon, n = tally.samples + dropped;
  const double expected_fraction = std::clamp(1.0 - ref.kept_mass, 0.0, 1.0);
  SubTest t;
  t.name = "dropped_fraction";
  t.label = "dropped fraction";
  t.statistical = true;
  t.value = double(dropped) / double(n);
  t.tolerance = expected_fraction;
  const boost::math::binomial_distribution<double> binomial(double(n), expected_fraction);
  const double at_most = boost::math::cdf(binomial, double(dropped));
  const double at_least = dropped == 0 ? 1.0 : boost::math::cdf(boost::math::complement(binomial, double(dropped - 1)));
  t.p_value = std::min(1.0, 2.0 * std::min(at_most, at_least));
  t.detail = fmt::format("{} of {} samples dropped ({:.4f}%), the claimed pdf loses {:.4f}% (reflections below the "
                         "horizon, a dielectric's refractions above it)",
                         dropped, n, 100 * t.value, 100 * expected_fraction);
  return t;
}

std::string no_samples_below_horizon_note(const Tally& tally, const ReferenceDistribution& ref) {
  if (ref.domain != SampleDomain::reflected_direction || ref.kept_only || tally.below_horizon > 0) return "";
  // The mass of the sphere bins that lie wholly below the horizon.
  double below = 0;
  for (int b = 0; b < ref.sphere.size(); ++b)
    if (ref.sphere.bounds(b).theta_min_deg >= 90.0) below += ref.sphere_probability.probability[std::size_t(b)];
  const double expected = below * double(tally.samples - tally.outside);
  if (expected < 5) return "";
  return fmt::format("the file has no sample below the horizon, where the claimed pdf puts at least {:.3g}% of its mass "
                     "({:.0f} samples expected): a renderer's dump that drops the reflections below the horizon? Test "
                     "it with --above-horizon (and --dropped N, the count it dropped)",
                     100 * below, expected);
}

SubTest not_applicable(std::string name, std::string detail) {
  SubTest t;
  t.name = std::move(name);
  t.applicable = false;
  t.detail = std::move(detail);
  return t;
}

namespace {

// The Sidak level of each statistical test, and the family-wise p-value of the smallest p.
void combine_statistical_tests(ValidationReport& r) {
  std::vector<double> p_values;
  for (const BinnedTest& b : r.binned) p_values.push_back(b.chi2.p_value);
  for (const SubTest& c : r.checks)
    if (c.statistical) p_values.push_back(c.p_value);
  r.statistical_tests = int(p_values.size());
  r.per_test_significance = sidak_significance(r.significance, r.statistical_tests);
  r.p_value = sidak_adjusted_p(*std::min_element(p_values.begin(), p_values.end()), r.statistical_tests);
  for (BinnedTest& b : r.binned) {
    b.chi2.significance = r.per_test_significance;
    b.chi2.rejected = b.chi2.p_value < r.per_test_significance;
  }
  for (SubTest& c : r.checks)
    if (c.statistical) c.passed = c.p_value >= r.per_test_significance;
}

// The binned test with the smallest p; among equal p, the last.
void set_headline(ValidationReport& r) {
  const ChiSquareResult* headline = nullptr;
  for (const BinnedTest& b : r.binned)
    if (!headline || b.chi2.p_value <= headline->p_value) headline = &b.chi2;
  if (!headline) return;
  r.statistic = headline->statistic;
  r.dof = headline->dof;
}

std::string hard_failure(const SubTest& t) { return t.label.empty() ? t.detail : t.label + ": " + t.detail; }

std::string statistical_failure(const SubTest& t, double per_test) {
  return fmt::format("{} test rejects: p = {:.3g} < {:.3g}: {}", t.label, t.p_value, per_test, t.detail);
}

std::string binned_failure(const BinnedTest& b, double per_test) {
  return fmt::format("{} in {} bins rejects: p = {:.3g} < {:.3g}{}", b.label, b.binning, b.chi2.p_value, per_test,
                     b.chi2.reason.empty() ? "" : " (" + b.chi2.reason + ")");
}

void list_failures(ValidationReport& r) {
  for (const SubTest& c : r.checks)
    if (!c.statistical && !c.passed) r.failures.push_back(hard_failure(c));
  for (const BinnedTest& b : r.binned)
    if (b.chi2.rejected) r.failures.push_back(binned_failure(b, r.per_test_significance));
  for (const SubTest& c : r.checks)
    if (c.statistical && !c.passed) r.failures.push_back(statistical_failure(c, r.per_test_significance));
}

}  // namespace

void decide(ValidationReport& r) {
  if (r.binned.empty()) throw std::invalid_argument("a validation needs at least one binned test");
  combine_statistical_tests(r);
  set_headline(r);
  list_failures(r);
  r.passed = r.failures.empty();
}

namespace {
// The samples of `counts` (bins, then the remainder cell) in the bins of zero probability.
std::uint64_t samples_in_massless_bins(const std::vector<double>& counts, const BinIntegrals& probability) {
  double n = 0;
  for (std::size_t b = 0; b < probability.probability.size() && b < counts.size(); ++b)
    if (probability.probability[b] == 0.0) n += counts[b];
  return std::uint64_t(n);
}
}  // namespace

ValidationReport analytic_report(const SampleSource& source, const Tally& tally, const Expectations& expectations,
                                 const ReferenceDistribution& ref, const ValidationOptions& options,
                                 std::vector<SubTest> extra_checks) {
  ValidationReport r = report_header(source, ref.domain, ref.ggx, ref.wi, tally, options);
  add_binned_tests(r, expectations, tally, options);
  r.checks = {domain_check(r, tally, options), integral_check(ref, options),
              returned_pdf_check(tally, ref, options, source.precision),
              weight_test(tally, ref, options, source.precision)};
  if (ref.kept_only) r.checks.push_back(dropped_fraction_test(tally, ref, options));
  for (SubTest& t : extra_checks) r.checks.push_back(std::move(t));
  r.samples_where_pdf_is_zero = samples_in_massless_bins(tally.counts.front(), ref.sphere_probability);
  decide(r);
  if (!r.passed && !source.seeded)
    if (std::string note = no_samples_below_horizon_note(tally, ref); !note.empty()) r.hints.push_back(std::move(note));
  return r;
}

}  // namespace battery
}  // namespace microsim
