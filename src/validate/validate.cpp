// microsim: the statistical validator of direction samplers (validate.h, docs/reference/validator.md).
#include "validate/validate.h"
#include "stats/json_values.h"

#include "validate/weight_test.h"

#include "validate/battery.h"
#include "validate/validation_part.h"

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
  const BlockSchedule schedule{"sampling", plan, kChunkBlocks, /*chunk_barrier=*/true};
  const BlockRange range = selected_blocks(plan, options.blocks);  // the runner's chunks start at its begin
  const BlockRunStatus status = for_each_block(
      range, options.run, schedule,
      [&](std::uint64_t b) {
        BlockBuffer& buf = buffers.local();
        draw_block(sample, g, w, options.seed, plan.first_unit(b), plan.first_unit(b) + plan.units_in(b), buf);
        visit(SampleBlockView{plan.first_unit(b), buf.directions, buf.pdfs, buf.valid, {}},
              std::size_t((b - range.begin) % kChunkBlocks));
        return b;
      },
      [&](std::uint64_t, std::uint64_t b) {
        const bool chunk_end = (b - range.begin + 1) % kChunkBlocks == 0 || b + 1 == range.end;
        if (chunk_end && chunk_done) chunk_done(std::size_t((b - range.begin) % kChunkBlocks) + 1);
      });
  if (status.cancelled) throw Cancelled("while sampling");
}

// ---- the battery's stages for the analytic pdf (battery.h) ----------------------------------------------

// Tallies the samples of `source` against `ref` (with the per-sample checks of its pdf) and reports.
// `require` runs on the number of samples seen, before any test.
template <class Require>
ValidationReport validate_source(const battery::SampleSource& source, const ReferenceDistribution& ref,
                                 const ValidationOptions& options, Require&& require,
                                 std::vector<SubTest> extra_checks = {}) {
  const battery::Expectations expectations = battery::analytic_expectations(ref);
  const battery::Tally tally = battery::tally_samples(source, battery::binnings_of(expectations), options, &ref);
  require(tally.samples);
  return battery::analytic_report(source, tally, expectations, ref, options, std::move(extra_checks));
}

double elapsed(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

// The sphere cubature's total error estimate above which unconverged bins get a second pass: the
// default pdf-integral tolerance (ValidationOptions::integral_tolerance), 10 samples in 1e6.
constexpr double kSecondPassTotalError = 1e-5;

namespace {

// The binnings and the pdf of a reference, without its bin probabilities.
ReferenceDistribution unintegrated_reference(DirectionFunction pdf, SampleDomain domain, const GGX<double>& ggx,
                                             const Vec3<double>& wi, int rows) {
  return ReferenceDistribution{domain,        ggx, wi, std::move(pdf), DirectionBinning::sphere(rows),
                               DirectionBinning::lobe(ggx, wi, domain, rows), {}, {}};
}

// The pdf a sampler claims, for view wi (normalised), and the jumps of it beyond the common ones.
DirectionFunction claimed_pdf_of(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi) {
  auto claimed = sampler.claimed_pdf;
  return [claimed, ggx, wi](const Vec3<double>& d) { return claimed(ggx, wi, d); };
}

std::vector<DirectionFunction> claimed_pdf_breaks(const SamplerInfo& sampler, const GGX<double>& ggx,
                                                  const Vec3<double>& wi) {
  std::vector<DirectionFunction> breaks;
  // A jump of the claimed pdf beyond the common ones (the bounded sampler's cap).
  if (const auto jump = sampler.claimed_pdf_jump)
    breaks.push_back([jump, ggx, wi](const Vec3<double>& d) { return jump(ggx, wi, d); });
  return breaks;
}

}  // namespace

std::shared_ptr<const ReferenceDistribution> prepare_reference(DirectionFunction pdf, SampleDomain domain,
                                                               const GGX<double>& ggx, const Vec3<double>& wi_in, int rows,
                                                               std::vector<DirectionFunction> breaks,
                                                               const std::vector<Vec3<double>>& focus, double rel_tolerance) {
  ReferenceDistribution ref = unintegrated_reference(std::move(pdf), domain, ggx, wi_in.normalized(), rows);
  // In lobe space the pdfs of the zoo are smooth and spread over the whole parameter space (the VNDF
  // is a clamped cosine there): plain adaptive cubature suffices.
  IntegrationOptions options;
  options.breaks = std::move(breaks);
  options.focus = focus;  // a second lobe (refraction) is narrow in lobe space too: resolve it there
  options.rel_tolerance = rel_tolerance;
  IntegrationOptions sphere_options = options;
  // In sphere space the lobe can be far narrower than a bin: focus on it with a lattice uniform in the
  // lobe parameter space, which covers every region with mass however narrow (alpha = 1e-3) or thin
  // (anisotropy, grazing reflections).
  sphere_options.focus = ref.lobe.lattice_directions(4096);
  sphere_options.focus.insert(sphere_options.focus.end(), focus.begin(), focus.end());
  // Where the pdfs of the zoo jump, in sphere coordinates: normals at m.z = 0; reflected directions
  // where the half vector reaches the horizon, wo.z = -wi.z.
  sphere_options.z_breaks = {0.0};
  if (domain == SampleDomain::reflected_direction) sphere_options.z_breaks.push_back(-ref.wi.z());
  // A lobe too narrow for the first pass (bounded2023 at alpha 1e-4, theta 89.99 deg
  // left 2e-5 of its mass, 20 of 1e6 samples, in the remainder cell, with an error estimate of 1.5e-3):
  // when the bins' error estimates add up to more than the pdf-integral check can tolerate, the bins
  // that missed their tolerance are integrated again with focus graded toward -wi and directed splits.
  // Below that the first pass stands, bit for bit.
  sphere_options.second_pass_total_error = kSecondPassTotalError;
  sphere_options.second_pass_focus = ref.lobe.visible_edge_directions(192, 64);
  ref.sphere_probability = ref.sphere.integrate(ref.pdf, sphere_options);
  ref.lobe_probability = ref.lobe.integrate(ref.pdf, options);
  return std::make_shared<const ReferenceDistribution>(std::move(ref));
}

std::shared_ptr<const ReferenceDistribution> claimed_reference(const SamplerInfo& sampler, const GGX<double>& ggx,
                                                               const Vec3<double>& wi_in, int rows) {
  const Vec3<double> wi = wi_in.normalized();
  return prepare_reference(claimed_pdf_of(sampler, ggx, wi), sampler.domain, ggx, wi, rows,
                           claimed_pdf_breaks(sampler, ggx, wi));
}

std::shared_ptr<const ReferenceDistribution> claimed_reference_bins(const SamplerInfo& sampler, const GGX<double>& ggx,
                                                                    const Vec3<double>& wi_in, int rows) {
  const Vec3<double> wi = wi_in.normalized();
  return std::make_shared<const ReferenceDistribution>(
      unintegrated_reference(claimed_pdf_of(sampler, ggx, wi), sampler.domain, ggx, wi, rows));
}

std::shared_ptr<const ReferenceDistribution> vndf_reference(SampleDomain domain, const GGX<double>& ggx,
                                                            const Vec3<double>& wi, int rows) {
  const Vec3<double> w = wi.normalized();
  if (domain == SampleDomain::microfacet_normal)
    return prepare_reference([ggx, w](const Vec3<double>& m) { return ggx.visible_normal_pdf(w, m); }, domain, ggx, w, rows);
  return density_reference(claimed_density(FilePdf::reflection, ggx, w), ggx, w, rows);
}

ClaimedDensity claimed_density(FilePdf pdf, const GGX<double>& ggx, const Vec3<double>& wi_in) {
  const Vec3<double> wi = wi_in.normalized();
  if (pdf == FilePdf::reflection)
    return {SampleDomain::reflected_direction,
            [ggx, wi](const Vec3<double>& o) { return ggx.visible_reflection_pdf(wi, o); }, {}, {}};
  if (pdf == FilePdf::bsdf) throw std::invalid_argument("the pdf 'bsdf' is the sampling density of a BSDF: give the BSDF");
  const ClaimedPdf claims = pdf == FilePdf::vndf  ? ClaimedPdf::visible_normals
                            : pdf == FilePdf::ndf ? ClaimedPdf::ndf_cosine
                                                  : ClaimedPdf::bounded_reflection;
  const SamplerInfo& sampler = reference_sampler(claims);
  return {sampler.domain, claimed_pdf_of(sampler, ggx, wi), claimed_pdf_breaks(sampler, ggx, wi), {}};
}

FilePdf parse_file_pdf(std::string_view name) {
  if (name == "vndf") return FilePdf::vndf;
  if (name == "ndf") return FilePdf::ndf;
  if (name == "bounded") return FilePdf::bounded;
  if (name == "reflection") return FilePdf::reflection;
  if (name == "bsdf") return FilePdf::bsdf;
  throw std::invalid_argument(fmt::format("unknown pdf '{}' (valid: vndf, ndf, bounded, reflection, bsdf)", name));
}

std::shared_ptr<const ReferenceDistribution> density_reference(const ClaimedDensity& density, const GGX<double>& ggx,
                                                               const Vec3<double>& wi, int rows) {
  return prepare_reference(density.pdf, density.domain, ggx, wi, rows, density.breaks, density.focus,
                           density.rel_tolerance);
}

namespace {
void scale_probabilities(BinIntegrals& b, double factor) {
  for (double& p : b.probability) p *= factor;
  b.total *= factor;
  b.error_estimate *= factor;
}
}  // namespace

std::shared_ptr<const ReferenceDistribution> kept_samples_reference(const ClaimedDensity& density, const GGX<double>& ggx,
                                                                    const Vec3<double>& wi, int rows) {
  const auto unconditioned = density_reference(density, ggx, wi, rows);
  const double kept = unconditioned->sphere_probability.total;
  if (!(kept > 0)) throw std::invalid_argument("the claimed pdf keeps no sample for this view (it has no mass)");
  ReferenceDistribution conditioned = *unconditioned;
  conditioned.kept_mass = std::min(kept, 1.0);
  conditioned.kept_only = true;
  conditioned.pdf = [full = density.pdf, kept](const Vec3<double>& o) { return full(o) / kept; };
  scale_probabilities(conditioned.sphere_probability, 1.0 / kept);
  scale_probabilities(conditioned.lobe_probability, 1.0 / kept);
  return std::make_shared<const ReferenceDistribution>(std::move(conditioned));
}

std::shared_ptr<const ReferenceDistribution> above_horizon_reference(const ClaimedDensity& density, const GGX<double>& ggx,
                                                                     const Vec3<double>& wi, int rows) {
  if (density.domain != SampleDomain::reflected_direction)
    throw std::invalid_argument("a density of microfacet normals has no horizon to condition on (reflected directions only)");
  ClaimedDensity above = density;
  above.pdf = [full = density.pdf](const Vec3<double>& o) { return o.z() > 0 ? full(o) : 0.0; };
  above.breaks.push_back([](const Vec3<double>& o) { return o.z(); });  // where `above` jumps
  try {
    return kept_samples_reference(above, ggx, wi, rows);
  } catch (const std::invalid_argument&) {
    throw std::invalid_argument("the claimed pdf puts no mass above the horizon for this view");
  }
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

void for_each_block(std::span<const Vec3<double>> samples, const SampleBlockVisitor& visit, const ChunkDone& chunk_done,
                    const RunControl* run) {
  const std::uint64_t n = samples.size(), blocks = (n + kSampleBlock - 1) / kSampleBlock;
  for (std::uint64_t c = 0; c < blocks; c += kChunkBlocks) {
    if (run && run->cancelled()) throw Cancelled("while tallying the samples");
    const std::uint64_t chunk_end = std::min(blocks, c + kChunkBlocks);
    tbb::parallel_for(c, chunk_end, [&](std::uint64_t b) {
      const std::uint64_t first = b * kSampleBlock, end = std::min(n, first + kSampleBlock);
      visit(SampleBlockView{first, samples.subspan(first, end - first), {}, {}, {}}, std::size_t(b - c));
    });
    if (chunk_done) chunk_done(std::size_t(chunk_end - c));
  }
}

void for_each_block(DirectionSampleReader& reader, const SampleBlockVisitor& visit, const ChunkDone& chunk_done,
                    const RunControl* run) {
  // One chunk of rows in memory at a time (kChunkBlocks x kSampleBlock x 24 bytes = 25 MB), its blocks
  // processed concurrently; the file is read on this thread.
  // With a pdf column, the returned pdfs come along (the returned-pdf and E[weight] checks), and from text
  // the digits they were printed with.
  std::vector<Vec3<double>> rows(kChunkBlocks * kSampleBlock);
  std::vector<double> pdfs(reader.columns().has_pdf() ? rows.size() : 0);
  std::vector<double> weights(rows.size() * std::size_t(reader.columns().channels()));
  std::vector<PrintedRounding> rounding(reader.storage() == "text" ? pdfs.size() : 0);
  const std::size_t channels = std::size_t(reader.columns().channels());
  std::vector<std::uint8_t> valid(reader.zero_weight_rows_lost() ? rows.size() : 0);
  std::uint64_t first = reader.rows_read();
  for (;;) {
    if (run && run->cancelled()) throw Cancelled("while reading the samples");
    const std::size_t n = reader.read(rows, pdfs, weights, rounding);
    if (n == 0) break;
    for (std::size_t i = 0; i < std::min(n, valid.size()); ++i)  // a lost sample kept as a row of weight 0
      valid[i] = std::any_of(&weights[i * channels], &weights[(i + 1) * channels], [](double w) { return w != 0; });
    const std::size_t blocks = std::size_t((n + kSampleBlock - 1) / kSampleBlock);
    tbb::parallel_for(std::size_t(0), blocks, [&](std::size_t b) {
      const std::size_t begin = b * kSampleBlock, end = std::min<std::size_t>(n, begin + kSampleBlock);
      const std::span<const double> block_pdfs =
          pdfs.empty() ? std::span<const double>() : std::span<const double>(pdfs).subspan(begin, end - begin);
      const std::span<const PrintedRounding> block_rounding =
          rounding.empty() ? std::span<const PrintedRounding>()
                           : std::span<const PrintedRounding>(rounding).subspan(begin, end - begin);
      const std::span<const std::uint8_t> block_valid =
          valid.empty() ? std::span<const std::uint8_t>() : std::span<const std::uint8_t>(valid).subspan(begin, end - begin);
      visit(SampleBlockView{first + begin, std::span<const Vec3<double>>(rows).subspan(begin, end - begin), block_pdfs,
                            block_valid, block_rounding},
            b);
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

namespace {
// The samples a goodness-of-fit test in these bins needs (chi2.h), their remainder cell included.
std::uint64_t samples_needed(const ReferenceBins& bins) {
  return goodness_of_fit_minimum_samples(battery::with_remainder(bins.probability), ChiSquareOptions{}.min_expected);
}
}  // namespace

std::uint64_t minimum_samples(const ReferenceDistribution& ref) {
  std::uint64_t needed = 0;
  for (const ReferenceBins& b : ref.binned()) needed = std::max(needed, samples_needed(b));
  return needed;
}

void require_samples(std::uint64_t given, const ReferenceDistribution& ref) {
  const std::vector<ReferenceBins> bins = ref.binned();
  std::size_t hardest = 0;  // the first binning that needs the most
  for (std::size_t k = 1; k < bins.size(); ++k)
    if (samples_needed(bins[k]) > samples_needed(bins[hardest])) hardest = k;
  const std::uint64_t needed = samples_needed(bins[hardest]);
  if (given >= needed) return;
  const ChiSquareOptions chi;
  const std::string binning = fmt::format("{} bins, {} rows", bins[hardest].binning.name(), bins[hardest].binning.rows());
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
  ValidationReport r = report_drawn_samples(sampler, *reference, tally_drawn_samples(sampler, *reference, options), options);
  r.seconds = elapsed(t0);
  return r;
}

namespace {
// Samples from elsewhere (a span or a file), checked against `ref`.
template <class Stream>
ValidationReport validate_stream(Stream& stream, const ReferenceDistribution& ref, const ValidationOptions& options,
                                 std::vector<SubTest> extra_checks = {}) {
  const auto t0 = std::chrono::steady_clock::now();
  ValidationReport r = validate_source(battery::given_samples(stream, "samples", &options.run), ref, options,
                                       [&ref](std::uint64_t seen) { require_samples(seen, ref); }, std::move(extra_checks));
  r.seconds = elapsed(t0);
  return r;
}
}  // namespace

ValidationReport validate_samples(std::span<const Vec3<double>> samples, SampleDomain domain, const GGX<double>& ggx,
                                  const Vec3<double>& wi, const ValidationOptions& options,
                                  std::shared_ptr<const ReferenceDistribution> reference) {
  if (!reference) reference = vndf_reference(domain, ggx, wi, options.rows);
  return validate_stream(samples, *reference, options);
}

ValidationReport validate_sample_file(DirectionSampleReader& reader, SampleDomain domain, const GGX<double>& ggx,
                                      const Vec3<double>& wi, const ValidationOptions& options,
                                      std::shared_ptr<const ReferenceDistribution> reference) {
  if (!reference) reference = vndf_reference(domain, ggx, wi, options.rows);
  std::vector<SubTest> weights;  // a pass of its own over the file, before the main one
  if (options.bsdf)
    weights = bsdf_weight_tests(reader, *reference, *options.bsdf, options);
  return validate_stream(reader, *reference, options, std::move(weights));
}

std::optional<FrameHint> diagnose_sample_frame(const DirectionSampleReader& samples,
                                               std::shared_ptr<const ReferenceDistribution> reference,
                                               const ValidationOptions& options) {
  std::optional<FrameHint> best;
  for (const SampleFrame frame : {SampleFrame::y_up, SampleFrame::z_down, SampleFrame::negated}) {
    DirectionSampleReader reader = samples.reopened();
    reader.set_frame(frame);
    ValidationReport r = validate_sample_file(reader, reference->domain, reference->ggx, reference->wi, options, reference);
    if (r.passed) return FrameHint{frame, std::move(r)};
    const bool fits = double(r.samples_where_pdf_is_zero) < 0.01 * double(r.samples);
    if (fits && (!best || r.samples_where_pdf_is_zero < best->report.samples_where_pdf_is_zero))
      best = FrameHint{frame, std::move(r)};
  }
  return best;
}

std::string to_string(Precision precision) { return precision == Precision::float32 ? "float" : "double"; }

nlohmann::json to_json(const SubTest& t) {
  nlohmann::json j;
  j["name"] = t.name;
  j["applicable"] = t.applicable;
  j["statistical"] = t.statistical;
  j["passed"] = t.passed;
  if (t.statistical) j["p_value"] = t.p_value;
  // A test that did not run has no value (null, not a 0 that reads as a measurement).
  j["value"] = t.applicable ? finite_or_null(t.value) : nlohmann::json(nullptr);
  j["tolerance"] = t.applicable ? finite_or_null(t.tolerance) : nlohmann::json(nullptr);
  j["detail"] = t.detail;
  return j;
}

nlohmann::json to_json(const ValidationReport& r) {
  nlohmann::json j;
  j["verdict"] = r.passed ? "pass" : "fail";
  j["p_value"] = r.p_value;
  j["statistic"] = finite_or_null(r.statistic);
  j["dof"] = r.dof;
  j["samples"] = r.samples;
  j["seed"] = r.seeded ? nlohmann::json(r.seed) : nlohmann::json(nullptr);  // null: nothing random was drawn
  j["sampler"] = r.sampler;
  j["domain"] = to_string(r.domain);
  j["alpha"] = {r.alpha_x, r.alpha_y};
  j["wi"] = {r.wi.x(), r.wi.y(), r.wi.z()};
  j["theta_deg"] = std::acos(std::clamp(r.wi.z(), -1.0, 1.0)) * 180 / kPi<double>;
  j["phi_deg"] = std::atan2(r.wi.y(), r.wi.x()) * 180 / kPi<double>;
  j["precision"] = to_string(r.precision);
  if (!r.storage.empty()) j["storage"] = r.storage;
  j["failed_samples"] = r.failed_samples;
  j["outside_domain"] = r.outside_domain;
  if (!r.storage.empty()) j["invalid_rows"] = {{"count", r.invalid_rows}, {"first", r.first_invalid_rows}};
  j["significance"] = r.significance;
  j["statistical_tests"] = r.statistical_tests;
  j["per_test_significance"] = r.per_test_significance;
  j["samples_where_pdf_is_zero"] = r.samples_where_pdf_is_zero;
  j["failures"] = r.failures;
  j["hints"] = r.hints;
  j["notes"] = r.notes;
  j["seconds"] = r.seconds;
  nlohmann::json tests = nlohmann::json::object();
  for (const BinnedTest& b : r.binned) tests[b.name] = to_json(b.chi2);
  for (const SubTest& c : r.checks) tests[c.name] = to_json(c);
  j["tests"] = tests;
  return j;
}

}  // namespace microsim
