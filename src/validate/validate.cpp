// microsim: the statistical validator of direction samplers (validate.h, docs/validation.md).
#include "validate/validate.h"

#include "core/block_runner.h"
#include "core/random.h"
#include "validate/sample_io.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>

namespace microsim {
namespace {

// ---- drawing in blocks --------------------------------------------------------------------------------

// One block's storage, reused by a thread from block to block.
struct BlockBuffer {
  std::vector<Vec3<double>> directions;
  std::vector<double> pdfs;
  std::vector<std::uint8_t> valid;
};

template <class T>
void draw_block(SampleResult<T> (*sample)(const GGX<T>&, const Vec3<T>&, Vec2<T>), const GGX<T>& g, const Vec3<T>& w,
                std::uint64_t seed, std::uint64_t first, std::uint64_t end, BlockBuffer& buf) {
  const std::size_t n = std::size_t(end - first);
  buf.directions.assign(n, Vec3<double>::Zero());
  buf.pdfs.assign(n, 0.0);
  buf.valid.assign(n, 0);
  for (std::uint64_t i = first; i < end; ++i) {
    CounterRng rng(seed, i);
    Vec2<T> u;
    if constexpr (std::is_same_v<T, float>) {
      u = Vec2<T>(rng.uniform_float(), rng.uniform_float());
    } else {
      u = Vec2<T>(rng.uniform(), rng.uniform());
    }
    const SampleResult<T> s = sample(g, w, u);
    if (!s) continue;
    const std::size_t k = std::size_t(i - first);
    buf.directions[k] = s->direction.template cast<double>();
    buf.pdfs[k] = double(s->pdf);
    buf.valid[k] = 1;
  }
}

template <class T>
void for_each_drawn_block_as(SampleResult<T> (*sample)(const GGX<T>&, const Vec3<T>&, Vec2<T>), const GGX<double>& ggx,
                             const Vec3<double>& wi, const ValidationOptions& options, const SampleBlockVisitor& visit,
                             const ChunkDone& chunk_done) {
  const std::uint64_t n = options.samples;
  const GGX<T> g(T(ggx.alpha_x()), T(ggx.alpha_y()));
  const Vec3<T> w = wi.template cast<T>();
  const BlockPlan plan{n, kSampleBlock};
  tbb::enumerable_thread_specific<BlockBuffer> buffers;
  // Chunks of kChunkBlocks: visit(block, slot) for each block of a chunk, then chunk_done, in order.
  const BlockSchedule schedule{"sampling", plan, kChunkBlocks};
  const BlockRunStatus status = for_each_block(
      BlockRange{0, plan.blocks()}, options.run, schedule,
      [&](std::uint64_t b) {
        BlockBuffer& buf = buffers.local();
        draw_block(sample, g, w, options.seed, plan.first_unit(b), plan.first_unit(b) + plan.units_in(b), buf);
        visit(SampleBlockView{plan.first_unit(b), buf.directions, buf.pdfs, buf.valid}, std::size_t(b % kChunkBlocks));
        return b;
      },
      [&](std::uint64_t, std::uint64_t b) {
        const bool chunk_end = (b + 1) % kChunkBlocks == 0 || b + 1 == plan.blocks();
        if (chunk_end && chunk_done) chunk_done(std::size_t(b % kChunkBlocks) + 1);
      });
  if (status.cancelled) throw Cancelled("while sampling");
}

// ---- per-sample checks and bin counts -------------------------------------------------------------------

// Mean and sum of squared deviations of a block (Welford), combined across blocks in order
// (Chan, Golub, LeVeque 1983).
struct Moments {
  double n = 0, mean = 0, m2 = 0;
  void add(double x) {
    n += 1;
    const double d = x - mean;
    mean += d / n;
    m2 += d * (x - mean);
  }
  void merge(const Moments& o) {
    if (o.n == 0) return;
    const double total = n + o.n, d = o.mean - mean;
    mean += d * o.n / total;
    m2 += o.m2 + d * d * n * o.n / total;
    n = total;
  }
};

double relative_difference(double a, double b) {
  if (a == b) return 0.0;  // both 0 included
  if (!std::isfinite(a) || !std::isfinite(b)) return std::numeric_limits<double>::infinity();
  return std::abs(a - b) / std::max(std::abs(a), std::abs(b));
}

// Largest relative change of the claimed pdf when the stored vector w moves by its rounding `step`:
// rotated by `step` radians along either tangent direction, or its length scaled by 1 +- step. How much
// of a pdf mismatch the rounding of w alone can explain.
// The length matters (issue 8, defect 9): the claimed pdf of a reflected direction recovers the half
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
    s = std::max(s, relative_difference(ref.pdf(Vec3<double>((w + step * t).normalized())), claimed));
  for (const double scale : {1 + step, 1 - step}) s = std::max(s, relative_difference(ref.pdf(Vec3<double>(w * scale)), claimed));
  return s;
}

// Expected probabilities with the remainder cell last: the mass the claimed pdf leaves outside the bins,
// where failed samples (and samples outside the lobe parameter space) are counted.
std::vector<double> with_remainder(const BinIntegrals& b) {
  std::vector<double> p = b.probability;
  p.push_back(std::max(0.0, 1.0 - b.total));
  return p;
}

std::string format_direction(const Vec3<double>& w) { return fmt::format("({:.6f}, {:.6f}, {:.6f})", w.x(), w.y(), w.z()); }

// The per-sample checks of one block (reduced in block order) ...
struct BlockChecks {
  std::uint64_t samples = 0;
  Moments weight;
  double pdf_worst = 0;
  std::uint64_t pdf_worst_index = 0, pdf_outliers = 0;
  Vec3<double> worst_direction = Vec3<double>::Zero();
  double worst_returned = 0;
  void merge(const BlockChecks& o) {
    samples += o.samples;
    weight.merge(o.weight);
    pdf_outliers += o.pdf_outliers;
    if (o.pdf_worst > pdf_worst) {
      pdf_worst = o.pdf_worst;
      pdf_worst_index = o.pdf_worst_index;
      worst_direction = o.worst_direction;
      worst_returned = o.worst_returned;
    }
  }
};

// ... and the bin counts (integers: summed per thread in any order). The last cell of each histogram is
// the remainder: failed samples, and for lobe bins samples outside the lobe parameter space.
struct BinCounts {
  std::vector<std::uint64_t> sphere, lobe;
  std::uint64_t failed = 0, outside = 0;
};

// Streams samples through the bins and the per-sample checks of one validation.
class SampleChecker {
public:
  SampleChecker(const ReferenceDistribution& ref, const ValidationOptions& options, Precision precision)
      : ref_(ref), options_(options),
        // The stored direction carries the rounding of its precision (a float sample has |dw| ~ 1e-7):
        // where the claimed pdf is ill-conditioned (a jump, or D at alpha = 1e-3 seen through a
        // cancelling half vector) that alone can change the analytic pdf by more than the tolerance.
        direction_rounding_(precision == Precision::float32 ? 2 * 0x1p-24 : 2 * 0x1p-53),
        pdf_tol_(options.pdf_tolerance > 0             ? options.pdf_tolerance
                 : precision == Precision::float32 ? kPdfToleranceFloat
                                                   : kPdfToleranceDouble),
        back_(ref.wi.z() < 0), wi_front_(back_ ? Vec3<double>(-ref.wi) : ref.wi),
        counts_([&] {
          BinCounts c;
          c.sphere.assign(std::size_t(ref.sphere.size()) + 1, 0);
          c.lobe.assign(std::size_t(ref.lobe.size()) + 1, 0);
          return c;
        }) {}

  double pdf_tolerance() const { return pdf_tol_; }

  void visit(const SampleBlockView& block, std::size_t slot) {
    BlockChecks& c = chunk_[slot];
    c = BlockChecks{};
    c.samples = block.directions.size();
    const bool has_pdf = !block.pdfs.empty();
    has_pdf_ = has_pdf;  // the same for every block of a source
    BinCounts& counts = counts_.local();
    for (std::size_t k = 0; k < block.directions.size(); ++k)
      check_sample(block.first + k, block.directions[k], has_pdf ? block.pdfs[k] : 0.0,
                   block.valid.empty() || block.valid[k], has_pdf, c, counts);
  }

  void chunk_done(std::size_t blocks) {
    for (std::size_t b = 0; b < blocks; ++b) total_.merge(chunk_[b]);
  }

  const BlockChecks& checks() const { return total_; }
  bool has_pdf() const { return has_pdf_; }
  BinCounts counts() const {
    BinCounts all;
    all.sphere.assign(std::size_t(ref_.sphere.size()) + 1, 0);
    all.lobe.assign(std::size_t(ref_.lobe.size()) + 1, 0);
    for (const BinCounts& c : counts_) {
      for (std::size_t i = 0; i < all.sphere.size(); ++i) all.sphere[i] += c.sphere[i];
      for (std::size_t i = 0; i < all.lobe.size(); ++i) all.lobe[i] += c.lobe[i];
      all.failed += c.failed;
      all.outside += c.outside;
    }
    return all;
  }

private:
  void check_sample(std::uint64_t i, const Vec3<double>& w, double pdf, bool valid, bool has_pdf, BlockChecks& c,
                    BinCounts& counts) const {
    const bool weight_applicable = has_pdf && ref_.domain == SampleDomain::microfacet_normal;
    if (!valid) {
      if (weight_applicable) c.weight.add(0.0);  // a failed sample contributes weight 0
      ++counts.failed;
      ++counts.sphere.back();
      ++counts.lobe.back();
      return;
    }
    if (!w.allFinite() || !(std::abs(w.norm() - 1) <= options_.unit_tolerance)) {
      ++counts.outside;
      return;
    }
    // A finite unit vector always has a sphere bin.
    const auto s = ref_.sphere.bin_of(w);
    ++counts.sphere[s ? std::size_t(*s) : counts.sphere.size() - 1];
    const auto l = ref_.lobe.bin_of(w);
    ++counts.lobe[l ? std::size_t(*l) : counts.lobe.size() - 1];
    if (has_pdf) check_pdf(i, w, pdf, c);
    if (weight_applicable) {
      const Vec3<double> m = back_ ? Vec3<double>(-w) : w;
      const double numerator = ref_.ggx.D(m) * std::max(wi_front_.dot(m), 0.0);
      double weight = 0;
      if (numerator > 0) weight = pdf > 0 ? numerator / pdf : std::numeric_limits<double>::infinity();
      c.weight.add(weight);
    }
  }

  void check_pdf(std::uint64_t i, const Vec3<double>& w, double pdf, BlockChecks& c) const {
    const double claimed = ref_.pdf(w);
    const double e = relative_difference(pdf, claimed);
    if (e > pdf_tol_ && e > pdf_tol_ + 2 * rounding_sensitivity(ref_, w, claimed, direction_rounding_)) ++c.pdf_outliers;
    if (e > c.pdf_worst) {
      c.pdf_worst = e;
      c.pdf_worst_index = i;
      c.worst_direction = w;
      c.worst_returned = pdf;
    }
  }

  const ReferenceDistribution& ref_;
  const ValidationOptions& options_;
  const double direction_rounding_, pdf_tol_;
  const bool back_;
  const Vec3<double> wi_front_;
  bool has_pdf_ = false;
  std::array<BlockChecks, kChunkBlocks> chunk_{};
  BlockChecks total_;
  tbb::enumerable_thread_specific<BinCounts> counts_;
};

ValidationReport report_header(std::string name, const ReferenceDistribution& ref, const ValidationOptions& options,
                               Precision precision, std::uint64_t samples) {
  ValidationReport r;
  r.sampler = std::move(name);
  r.domain = ref.domain;
  r.alpha_x = ref.ggx.alpha_x();
  r.alpha_y = ref.ggx.alpha_y();
  r.wi = ref.wi;
  r.samples = samples;
  r.seed = options.seed;
  r.precision = precision;
  r.significance = options.significance;
  return r;
}

// The two chi-square tests and the histograms for figures.
void fill_chi_square(ValidationReport& r, const BinCounts& counts, const ReferenceDistribution& ref,
                     const ValidationOptions& options) {
  const double n = double(r.samples);
  const int ns = ref.sphere.size(), nl = ref.lobe.size();
  const std::vector<double> sphere_obs(counts.sphere.begin(), counts.sphere.end());
  const std::vector<double> lobe_obs(counts.lobe.begin(), counts.lobe.end());
  ChiSquareOptions chi;
  chi.significance = options.significance;  // replaced by the Sidak level below for the verdict
  chi.worst_cells = options.worst_cells;
  chi.describe_cell = [&](int bin) {
    return bin < ns ? ref.sphere.describe_bin(bin) : std::string("remainder (failed samples)");
  };
  r.sphere = goodness_of_fit(sphere_obs, with_remainder(ref.sphere_probability), n, chi, double(r.outside_domain));
  chi.describe_cell = [&](int bin) {
    return bin < nl ? ref.lobe.describe_bin(bin) : std::string("remainder (failed or outside the lobe space)");
  };
  r.lobe = goodness_of_fit(lobe_obs, with_remainder(ref.lobe_probability), n, chi, double(r.outside_domain));
  auto comparison = [&](const DirectionBinning& b, const std::vector<double>& obs, const BinIntegrals& p) {
    BinnedComparison c{b, std::vector<double>(obs.begin(), obs.begin() + b.size()), p.probability, "analytic pdf"};
    for (double& e : c.expected) e *= n;
    return c;
  };
  r.histograms = {comparison(ref.sphere, sphere_obs, ref.sphere_probability),
                  comparison(ref.lobe, lobe_obs, ref.lobe_probability)};
}

void fill_hard_checks(ValidationReport& r, const ReferenceDistribution& ref, const ValidationOptions& options) {
  r.domain_check.name = "domain";
  r.domain_check.value = double(r.outside_domain);
  r.domain_check.tolerance = 0;
  r.domain_check.passed = r.outside_domain == 0;
  r.domain_check.detail = fmt::format("{} sample(s) non-finite or with | |w| - 1 | > {}", r.outside_domain,
                                      options.unit_tolerance);

  r.integral.name = "pdf_integral";
  r.integral.value = ref.sphere_probability.total;
  r.integral.tolerance = options.integral_tolerance;
  r.integral.passed = std::isfinite(ref.sphere_probability.total) &&
                      ref.sphere_probability.total <= 1 + options.integral_tolerance;
  r.integral.detail = fmt::format("integral of the claimed pdf over the sphere = {:.9f} (cubature error estimate {:.1e}), "
                                  "must not exceed 1 + {}",
                                  ref.sphere_probability.total, ref.sphere_probability.error_estimate,
                                  options.integral_tolerance);
}

void fill_pdf_check(ValidationReport& r, const BlockChecks& c, bool has_pdf, double pdf_tol,
                    const ReferenceDistribution& ref, const ValidationOptions& options) {
  r.pdf.name = "returned_pdf";
  r.pdf.applicable = has_pdf;
  if (!has_pdf) {
    r.pdf.detail = "no returned pdf (samples from a file)";
    return;
  }
  const double fraction = std::max(options.pdf_outlier_fraction, 0.0);
  const auto allowed = std::uint64_t(std::floor(fraction * double(r.samples)));
  r.pdf.value = c.pdf_worst;
  r.pdf.tolerance = pdf_tol;
  r.pdf.passed = c.pdf_outliers <= allowed;
  r.pdf.detail = c.pdf_worst > 0
                     ? fmt::format("max |returned - claimed| / max(returned, claimed) = {:.3e} at sample {} "
                                   "{}: returned {:.9g}, claimed {:.9g}; {} sample(s) above {:.0e} plus the "
                                   "change a rounding of the direction can cause ({} allowed)",
                                   c.pdf_worst, c.pdf_worst_index, format_direction(c.worst_direction),
                                   c.worst_returned, ref.pdf(c.worst_direction), c.pdf_outliers, pdf_tol, allowed)
                     : std::string("returned pdf equals the claimed pdf on every sample");
}

// E[weight] against the projected area |wi.z| / G1(wi).
void fill_weight_test(ValidationReport& r, const Moments& all, bool has_pdf, const ReferenceDistribution& ref,
                      const ValidationOptions& options) {
  const bool weight_applicable = has_pdf && ref.domain == SampleDomain::microfacet_normal;
  r.weight.name = "weight_mean";
  r.weight.applicable = weight_applicable;
  r.weight.statistical = weight_applicable;
  if (!weight_applicable) {
    r.weight.detail = has_pdf ? "not applicable: samples are reflected directions"
                              : "not applicable: no returned pdf (samples from a file)";
    return;
  }
  const double expected = ref.ggx.projected_area(ref.wi);
  const double rounding = options.weight_rounding > 0 ? options.weight_rounding
                          : r.precision == Precision::float32 ? 1e-5
                                                              : 1e-9;
  const double se_stat = all.n > 1 ? std::sqrt(all.m2 / (all.n - 1) / all.n) : 0.0;
  const double se = std::sqrt(se_stat * se_stat + (rounding * expected) * (rounding * expected));
  const double z = (all.mean - expected) / se;
  r.weight.value = all.mean;
  r.weight.tolerance = expected;
  r.weight.p_value = std::isfinite(z) ? std::erfc(std::abs(z) / std::sqrt(2.0)) : 0.0;
  r.weight.detail = fmt::format("mean weight {:.9g} vs |wi.z|/G1 = {:.9g}: z = {:.3f} (standard error {:.3e}, "
                                "rounding floor {:.0e} relative)",
                                all.mean, expected, z, se_stat, rounding);
}

// The Sidak combination of the statistical tests and the list of failures.
void fill_verdict(ValidationReport& r, bool has_pdf, const ValidationOptions& options) {
  std::vector<double> p_values = {r.sphere.p_value, r.lobe.p_value};
  if (r.weight.statistical) p_values.push_back(r.weight.p_value);
  r.statistical_tests = int(p_values.size());
  r.per_test_significance = sidak_significance(options.significance, r.statistical_tests);
  const double p_min = *std::min_element(p_values.begin(), p_values.end());
  r.p_value = sidak_adjusted_p(p_min, r.statistical_tests);
  for (ChiSquareResult* c : {&r.sphere, &r.lobe}) {
    c->significance = r.per_test_significance;
    c->rejected = c->p_value < r.per_test_significance;
  }
  r.weight.passed = !r.weight.statistical || r.weight.p_value >= r.per_test_significance;
  const ChiSquareResult& headline = r.sphere.p_value < r.lobe.p_value ? r.sphere : r.lobe;
  r.statistic = headline.statistic;
  r.dof = headline.dof;

  if (!r.domain_check.passed) r.failures.push_back(r.domain_check.detail);
  if (!r.integral.passed) r.failures.push_back(r.integral.detail);
  if (has_pdf && !r.pdf.passed) r.failures.push_back("returned pdf differs from the claimed pdf: " + r.pdf.detail);
  if (r.sphere.rejected)
    r.failures.push_back(fmt::format("chi-square in sphere bins rejects: p = {:.3g} < {:.3g}{}", r.sphere.p_value,
                                     r.per_test_significance, r.sphere.reason.empty() ? "" : " (" + r.sphere.reason + ")"));
  if (r.lobe.rejected)
    r.failures.push_back(fmt::format("chi-square in lobe bins rejects: p = {:.3g} < {:.3g}{}", r.lobe.p_value,
                                     r.per_test_significance, r.lobe.reason.empty() ? "" : " (" + r.lobe.reason + ")"));
  if (!r.weight.passed)
    r.failures.push_back(fmt::format("E[weight] test rejects: p = {:.3g} < {:.3g}: {}", r.weight.p_value,
                                     r.per_test_significance, r.weight.detail));
  r.passed = r.failures.empty();
}

// The report of the samples a checker has seen.
ValidationReport finish_validation(std::string name, const SampleChecker& checker, const ReferenceDistribution& ref,
                                   const ValidationOptions& options, Precision precision) {
  const BlockChecks& c = checker.checks();
  ValidationReport r = report_header(std::move(name), ref, options, precision, c.samples);
  const BinCounts counts = checker.counts();
  r.failed_samples = counts.failed;
  r.outside_domain = counts.outside;
  fill_chi_square(r, counts, ref, options);
  fill_hard_checks(r, ref, options);
  fill_pdf_check(r, c, checker.has_pdf(), checker.pdf_tolerance(), ref, options);
  fill_weight_test(r, c.weight, checker.has_pdf(), ref, options);
  fill_verdict(r, checker.has_pdf(), options);
  return r;
}

double elapsed(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

// The sphere cubature's total error estimate above which unconverged bins get a second pass: the
// default pdf-integral tolerance (ValidationOptions::integral_tolerance), 10 samples in 1e6.
constexpr double kSecondPassTotalError = 1e-5;

std::shared_ptr<const ReferenceDistribution> prepare_reference(DirectionFunction pdf, SampleDomain domain,
                                                               const GGX<double>& ggx, const Vec3<double>& wi_in, int rows,
                                                               std::vector<DirectionFunction> breaks) {
  const Vec3<double> wi = wi_in.normalized();
  auto sphere = DirectionBinning::sphere(rows);
  auto lobe = DirectionBinning::lobe(ggx, wi, domain, rows);
  // In lobe space the pdfs of the zoo are smooth and spread over the whole parameter space (the VNDF
  // is a clamped cosine there): plain adaptive cubature suffices.
  IntegrationOptions options;
  options.breaks = std::move(breaks);
  IntegrationOptions sphere_options = options;
  // In sphere space the lobe can be far narrower than a bin: focus on it with a lattice uniform in the
  // lobe parameter space, which covers every region with mass however narrow (alpha = 1e-3) or thin
  // (anisotropy, grazing reflections).
  sphere_options.focus = lobe.lattice_directions(4096);
  // Where the pdfs of the zoo jump, in sphere coordinates: normals at m.z = 0; reflected directions
  // where the half vector reaches the horizon, wo.z = -wi.z.
  sphere_options.z_breaks = {0.0};
  if (domain == SampleDomain::reflected_direction) sphere_options.z_breaks.push_back(-wi.z());
  // A lobe too narrow for the first pass (issue 8, defect 9: bounded2023 at alpha 1e-4, theta 89.99 deg
  // left 2e-5 of its mass, 20 of 1e6 samples, in the remainder cell, with an error estimate of 1.5e-3):
  // when the bins' error estimates add up to more than the pdf-integral check can tolerate, the bins
  // that missed their tolerance are integrated again with focus graded toward -wi and directed splits.
  // Below that the first pass stands, bit for bit.
  sphere_options.second_pass_total_error = kSecondPassTotalError;
  sphere_options.second_pass_focus = lobe.visible_edge_directions(192, 64);
  auto sphere_p = sphere.integrate(pdf, sphere_options);
  auto lobe_p = lobe.integrate(pdf, options);
  return std::make_shared<const ReferenceDistribution>(ReferenceDistribution{
      domain, ggx, wi, std::move(pdf), std::move(sphere), std::move(lobe), std::move(sphere_p), std::move(lobe_p)});
}

namespace {
// The boundary of the support of the bounded VNDF sampler (Eto & Tokuyoshi 2023, sec. 3): the cap
// direction c = reflect(Vh, Nh) of the half vector must satisfy c.z >= -k Vh.z. Zero on the boundary
// (same back-side and half-vector conventions as bounded2023_reflection_pdf).
DirectionFunction bounded2023_cap_boundary(const GGX<double>& ggx, const Vec3<double>& wi_in) {
  return [ggx, wi_in](const Vec3<double>& wo_in) {
    const bool flip = wi_in.z() < 0;
    const Vec3<double> wi = flip ? Vec3<double>(-wi_in) : wi_in;
    const Vec3<double> wo = flip ? Vec3<double>(-wo_in) : wo_in;
    Vec3<double> m = normalized_or_zero(Vec3<double>(wi + wo));
    if (m.isZero()) return 1.0;
    if (m.z() < 0) m = -m;
    const Vec3<double> vh = normalized_or_zero(Vec3<double>(ggx.alpha_x() * wi.x(), ggx.alpha_y() * wi.y(), wi.z()));
    const Vec3<double> nh = normalized_or_zero(Vec3<double>(m.x() / ggx.alpha_x(), m.y() / ggx.alpha_y(), m.z()));
    const Vec3<double> c = reflect(vh, nh);
    const double k = wi.z() > 0 ? bounded2023_k(ggx, wi) : 1.0;
    return c.z() + k * vh.z();
  };
}
}  // namespace

std::shared_ptr<const ReferenceDistribution> claimed_reference(const SamplerInfo& sampler, const GGX<double>& ggx,
                                                               const Vec3<double>& wi_in, int rows) {
  const Vec3<double> wi = wi_in.normalized();
  std::vector<DirectionFunction> breaks;
  // Known jumps of the zoo's claimed pdfs beyond the common ones: the bounded sampler's cap.
  if (sampler.name == "bounded2023") breaks.push_back(bounded2023_cap_boundary(ggx, wi));
  auto claimed = sampler.claimed_pdf;
  return prepare_reference([claimed, ggx, wi](const Vec3<double>& d) { return claimed(ggx, wi, d); }, sampler.domain,
                           ggx, wi, rows, std::move(breaks));
}

std::shared_ptr<const ReferenceDistribution> vndf_reference(SampleDomain domain, const GGX<double>& ggx,
                                                            const Vec3<double>& wi, int rows) {
  const Vec3<double> w = wi.normalized();
  if (domain == SampleDomain::microfacet_normal)
    return prepare_reference([ggx, w](const Vec3<double>& m) { return ggx.visible_normal_pdf(w, m); }, domain, ggx, w, rows);
  return prepare_reference([ggx, w](const Vec3<double>& o) { return ggx.visible_reflection_pdf(w, o); }, domain, ggx, w,
                           rows);
}

SampleSet SampleSet::from_directions(std::span<const Vec3<double>> directions) {
  SampleSet set;
  set.directions.assign(directions.begin(), directions.end());
  set.valid.assign(directions.size(), 1);
  return set;
}

void for_each_drawn_block(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                          const ValidationOptions& options, const SampleBlockVisitor& visit, const ChunkDone& chunk_done) {
  if (options.precision == Precision::float32)
    for_each_drawn_block_as<float>(sampler.sample_float, ggx, wi, options, visit, chunk_done);
  else
    for_each_drawn_block_as<double>(sampler.sample_double, ggx, wi, options, visit, chunk_done);
}

void for_each_block(std::span<const Vec3<double>> samples, const SampleBlockVisitor& visit, const ChunkDone& chunk_done) {
  const std::uint64_t n = samples.size(), blocks = (n + kSampleBlock - 1) / kSampleBlock;
  for (std::uint64_t c = 0; c < blocks; c += kChunkBlocks) {
    const std::uint64_t chunk_end = std::min(blocks, c + kChunkBlocks);
    tbb::parallel_for(c, chunk_end, [&](std::uint64_t b) {
      const std::uint64_t first = b * kSampleBlock, end = std::min(n, first + kSampleBlock);
      visit(SampleBlockView{first, samples.subspan(first, end - first), {}, {}}, std::size_t(b - c));
    });
    if (chunk_done) chunk_done(std::size_t(chunk_end - c));
  }
}

void for_each_block(DirectionSampleReader& reader, const SampleBlockVisitor& visit, const ChunkDone& chunk_done) {
  // One chunk of rows in memory at a time (kChunkBlocks x kSampleBlock x 24 bytes = 25 MB), its blocks
  // processed concurrently; the file is read on this thread.
  std::vector<Vec3<double>> rows(kChunkBlocks * kSampleBlock);
  std::uint64_t first = reader.rows_read();
  for (;;) {
    const std::size_t n = reader.read(rows);
    if (n == 0) break;
    const std::size_t blocks = std::size_t((n + kSampleBlock - 1) / kSampleBlock);
    tbb::parallel_for(std::size_t(0), blocks, [&](std::size_t b) {
      const std::size_t begin = b * kSampleBlock, end = std::min<std::size_t>(n, begin + kSampleBlock);
      visit(SampleBlockView{first + begin, std::span<const Vec3<double>>(rows).subspan(begin, end - begin), {}, {}}, b);
    });
    if (chunk_done) chunk_done(blocks);
    first += n;
    if (n < rows.size()) break;
  }
}

SampleSet draw_samples(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                       const ValidationOptions& options) {
  SampleSet set;
  set.directions.assign(options.samples, Vec3<double>::Zero());
  set.pdfs.assign(options.samples, 0.0);
  set.valid.assign(options.samples, 0);
  for_each_drawn_block(sampler, ggx, wi, options, [&](const SampleBlockView& b, std::size_t) {
    std::copy(b.directions.begin(), b.directions.end(), set.directions.begin() + std::ptrdiff_t(b.first));
    std::copy(b.pdfs.begin(), b.pdfs.end(), set.pdfs.begin() + std::ptrdiff_t(b.first));
    std::copy(b.valid.begin(), b.valid.end(), set.valid.begin() + std::ptrdiff_t(b.first));
  });
  return set;
}

void require_samples_for_any_test(std::uint64_t given) {
  const ChiSquareOptions chi;
  const std::uint64_t needed = minimum_samples_for_any_test(chi.min_expected);
  if (given < needed)
    throw InsufficientData(fmt::format("{} sample(s) are too few: a chi-square test needs at least {} samples (two cells "
                                       "that expect at least {:g} each, or it cannot reject)",
                                       given, needed, chi.min_expected),
                           given, needed);
}

std::uint64_t minimum_samples(const ReferenceDistribution& ref) {
  const ChiSquareOptions chi;
  return std::max(goodness_of_fit_minimum_samples(with_remainder(ref.sphere_probability), chi.min_expected),
                  goodness_of_fit_minimum_samples(with_remainder(ref.lobe_probability), chi.min_expected));
}

void require_samples(std::uint64_t given, const ReferenceDistribution& ref) {
  const ChiSquareOptions chi;
  const std::uint64_t sphere = goodness_of_fit_minimum_samples(with_remainder(ref.sphere_probability), chi.min_expected);
  const std::uint64_t lobe = goodness_of_fit_minimum_samples(with_remainder(ref.lobe_probability), chi.min_expected);
  const std::uint64_t needed = std::max(sphere, lobe);
  if (given >= needed) return;
  const std::string binning = sphere >= lobe ? fmt::format("sphere bins, {} rows", ref.sphere.rows())
                                             : fmt::format("lobe bins, {} rows", ref.lobe.rows());
  // The rule (chi2.h, goodness_of_fit_minimum_samples): with fewer, the cells pool into one and the test
  // has no degree of freedom: it cannot reject, and a test that cannot fail is no pass.
  if (needed == kNoSampleCountSuffices)
    throw InsufficientData(fmt::format("{} sample(s) given, but no number of samples is enough: the claimed pdf puts all "
                                       "its mass in one cell of the {}, so no chi-square test is possible",
                                       given, binning),
                           given, needed);
  throw InsufficientData(
      fmt::format("{} sample(s) are too few: the chi-square tests need at least {} samples ({}: the largest cell must "
                  "expect at least {:g} samples and the other cells together at least {:g}, or the cells pool into one "
                  "and the test cannot reject)",
                  given, needed, binning, chi.min_expected, chi.min_expected),
      given, needed);
}

ValidationReport validate_sampler(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                                  const ValidationOptions& options, std::shared_ptr<const ReferenceDistribution> reference) {
  const auto t0 = std::chrono::steady_clock::now();
  require_samples_for_any_test(options.samples);  // before the cubature of the reference
  if (!reference) reference = claimed_reference(sampler, ggx, wi, options.rows);
  require_samples(options.samples, *reference);
  SampleChecker checker(*reference, options, options.precision);
  for_each_drawn_block(
      sampler, ggx, reference->wi, options,
      [&](const SampleBlockView& b, std::size_t slot) { checker.visit(b, slot); },
      [&](std::size_t blocks) { checker.chunk_done(blocks); });
  ValidationReport r = finish_validation(std::string(sampler.name), checker, *reference, options, options.precision);
  r.seconds = elapsed(t0);
  return r;
}

namespace {
// Samples from elsewhere, streamed by `stream` (a span or a file), checked against `ref`.
template <class Stream>
ValidationReport validate_stream(Stream& stream, const ReferenceDistribution& ref, const ValidationOptions& options) {
  SampleChecker checker(ref, options, Precision::float64);
  for_each_block(
      stream, [&](const SampleBlockView& b, std::size_t slot) { checker.visit(b, slot); },
      [&](std::size_t blocks) { checker.chunk_done(blocks); });
  require_samples(checker.checks().samples, ref);
  ValidationOptions o = options;
  o.samples = checker.checks().samples;
  return finish_validation("samples", checker, ref, o, Precision::float64);
}
}  // namespace

ValidationReport validate_samples(std::span<const Vec3<double>> samples, SampleDomain domain, const GGX<double>& ggx,
                                  const Vec3<double>& wi, const ValidationOptions& options,
                                  std::shared_ptr<const ReferenceDistribution> reference) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!reference) reference = vndf_reference(domain, ggx, wi, options.rows);
  ValidationReport r = validate_stream(samples, *reference, options);
  r.seconds = elapsed(t0);
  return r;
}

ValidationReport validate_sample_file(DirectionSampleReader& reader, SampleDomain domain, const GGX<double>& ggx,
                                      const Vec3<double>& wi, const ValidationOptions& options,
                                      std::shared_ptr<const ReferenceDistribution> reference) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!reference) reference = vndf_reference(domain, ggx, wi, options.rows);
  ValidationReport r = validate_stream(reader, *reference, options);
  r.seconds = elapsed(t0);
  return r;
}

std::string to_string(Precision precision) { return precision == Precision::float32 ? "float" : "double"; }

nlohmann::json to_json(const SubTest& t) {
  auto num = [](double v) -> nlohmann::json { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  nlohmann::json j;
  j["name"] = t.name;
  j["applicable"] = t.applicable;
  j["statistical"] = t.statistical;
  j["passed"] = t.passed;
  if (t.statistical) j["p_value"] = t.p_value;
  j["value"] = num(t.value);
  j["tolerance"] = num(t.tolerance);
  j["detail"] = t.detail;
  return j;
}

nlohmann::json to_json(const ValidationReport& r) {
  auto num = [](double v) -> nlohmann::json { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  nlohmann::json j;
  j["verdict"] = r.passed ? "pass" : "fail";
  j["p_value"] = r.p_value;
  j["statistic"] = num(r.statistic);
  j["dof"] = r.dof;
  j["samples"] = r.samples;
  j["seed"] = r.seed;
  j["sampler"] = r.sampler;
  j["domain"] = to_string(r.domain);
  j["alpha"] = {r.alpha_x, r.alpha_y};
  j["wi"] = {r.wi.x(), r.wi.y(), r.wi.z()};
  j["theta_deg"] = std::acos(std::clamp(r.wi.z(), -1.0, 1.0)) * 180 / kPi<double>;
  j["phi_deg"] = std::atan2(r.wi.y(), r.wi.x()) * 180 / kPi<double>;
  j["precision"] = to_string(r.precision);
  j["failed_samples"] = r.failed_samples;
  j["outside_domain"] = r.outside_domain;
  j["significance"] = r.significance;
  j["statistical_tests"] = r.statistical_tests;
  j["per_test_significance"] = r.per_test_significance;
  j["failures"] = r.failures;
  j["seconds"] = r.seconds;
  nlohmann::json tests;
  tests["chi2_sphere"] = to_json(r.sphere);
  tests["chi2_lobe"] = to_json(r.lobe);
  tests["weight_mean"] = to_json(r.weight);
  tests["returned_pdf"] = to_json(r.pdf);
  tests["pdf_integral"] = to_json(r.integral);
  tests["domain"] = to_json(r.domain_check);
  j["tests"] = tests;
  return j;
}

}  // namespace microsim
