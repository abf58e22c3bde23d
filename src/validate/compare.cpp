#include "validate/compare.h"

#include "validate/battery.h"
#include "validate/validation_part.h"

#include "core/random.h"
#include "validate/sample_io.h"
#include "core/strict_parse.h"

#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/non_central_chi_squared.hpp>
#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <limits>
#include <cmath>
#include <numeric>
#include <optional>
#include <stdexcept>

namespace microsim {

// ---- traced histogram vs analytic D_v ------------------------------------------------------------------

double total_variation(std::span<const std::uint64_t> counts, std::uint64_t hits, std::span<const double> probability) {
  if (counts.size() != probability.size()) throw std::invalid_argument("total_variation: size mismatch");
  if (hits == 0) return 0.0;
  double sum = 0, mass = 0;
  for (std::size_t i = 0; i < counts.size(); ++i) {
    sum += std::abs(double(counts[i]) / double(hits) - probability[i]);
    mass += probability[i];
  }
  // Hits outside the bins and probability outside them form one more cell.
  const double outside_observed = 1.0 - double(std::accumulate(counts.begin(), counts.end(), std::uint64_t(0))) / double(hits);
  sum += std::abs(outside_observed - std::max(0.0, 1.0 - mass));
  return 0.5 * sum;
}

double noise_floor_tv(std::span<const double> probability, std::uint64_t hits) {
  if (hits == 0) return 0.0;
  double sum = 0;
  for (double p : probability) sum += std::sqrt(std::max(0.0, p * (1 - p)) / (2 * kPi<double> * double(hits)));
  return sum;
}

namespace {
// Goodness of fit of one binning's traced counts against the bin probabilities of D_v (remainder cell:
// the hits outside the bins), and its total-variation distance.
TraceFit fit_binning(const DirectionBinning& b, std::span<const std::uint64_t> counts, std::uint64_t hits,
                     std::optional<std::uint64_t> unbinned, const BinIntegrals& bins, double per_test) {
  TraceFit fit;
  fit.binning = b.name();
  fit.total_variation = total_variation(counts, hits, bins.probability);
  fit.noise_floor_tv = noise_floor_tv(bins.probability, hits);
  fit.chi2.significance = per_test;
  if (hits == 0) {
    fit.chi2.reason = "no hits";
    return fit;
  }
  std::vector<double> observed(counts.begin(), counts.end());
  const std::uint64_t binned = std::accumulate(counts.begin(), counts.end(), std::uint64_t(0));
  observed.push_back(double(unbinned.value_or(hits - binned)));
  ChiSquareOptions chi;
  chi.significance = per_test;
  chi.describe_cell = [&b](int bin) { return bin < b.size() ? b.describe_bin(bin) : std::string("remainder (outside the bins)"); };
  fit.chi2 = goodness_of_fit(observed, battery::with_remainder(bins), double(hits), chi);
  return fit;
}
}  // namespace

TraceAnalysis analyse_against_vndf(TracedHistogram& h, const GGX<double>& ggx, const Vec3<double>& wi,
                                   std::span<const std::uint64_t> unbinned, double significance) {
  if (h.binnings.empty()) throw std::invalid_argument("analyse_against_vndf: no binning");
  const auto ref = vndf_reference(SampleDomain::microfacet_normal, ggx, wi, h.binnings.front().rows());
  const std::vector<ReferenceBins> reference = ref->binned();
  TraceAnalysis a;
  a.significance = significance;
  h.probability.assign(h.binnings.size(), {});
  const int n_tests = int(h.binnings.size());
  const double per_test = sidak_significance(significance, n_tests);
  double p_min = 1;
  for (std::size_t k = 0; k < h.binnings.size(); ++k) {
    const DirectionBinning& b = h.binnings[k];
    const auto same_kind = [&b](const ReferenceBins& r) { return r.binning.kind() == b.kind(); };
    const auto r = std::find_if(reference.begin(), reference.end(), same_kind);
    if (r == reference.end() || r->binning.size() != b.size())
      throw std::invalid_argument("analyse_against_vndf: binning mismatch");
    h.probability[k] = r->probability.probability;
    std::optional<std::uint64_t> outside;
    if (k < unbinned.size()) outside.emplace(unbinned[k]);
    TraceFit fit = fit_binning(b, h.counts[k], h.hits, outside, r->probability, per_test);
    p_min = std::min(p_min, fit.chi2.p_value);
    a.rejected = a.rejected || fit.chi2.rejected;
    a.fits.push_back(std::move(fit));
  }
  a.p_value = sidak_adjusted_p(p_min, n_tests);
  return a;
}

nlohmann::json to_json(const TraceAnalysis& a) {
  nlohmann::json j;
  j["significance"] = a.significance;
  j["p_value"] = a.p_value;
  j["verdict"] = a.rejected ? "fail" : "pass";
  j["binnings"] = nlohmann::json::array();
  for (const TraceFit& f : a.fits) {
    j["binnings"].push_back({{"binning", f.binning},
                             {"total_variation", f.total_variation},
                             {"noise_floor_tv", f.noise_floor_tv},
                             {"chi2", to_json(f.chi2)}});
  }
  return j;
}

void record_ellipsoid_target(TracedHistogram& h, const EllipsoidTarget& target) {
  const auto g17 = [](double x) { return fmt::format("{:.17g}", x); };
  h.attributes["surface"] = "ellipsoid";
  h.attributes["target"] = target.describe();
  h.attributes["mesh_level"] = std::to_string(target.mesh_level());
  h.attributes["alpha"] = g17(target.ellipsoid().ax) + "," + g17(target.ellipsoid().ay);
}

TracedHistogram trace_vndf_histogram(const GGX<double>& ggx, const Vec3<double>& wi_in, const OracleTraceOptions& options,
                                     TraceResult* raw) {
  const Vec3<double> wi = wi_in.normalized();
  const EllipsoidTarget target(ggx.alpha_x(), ggx.alpha_y(), options.mesh_level);
  TracedHistogram h;
  h.binnings = {DirectionBinning::sphere(options.rows),
                DirectionBinning::lobe(ggx, wi, SampleDomain::microfacet_normal, options.rows)};
  TraceOptions t;
  t.rays = options.rays;
  t.seed = options.seed;
  t.run = options.run;
  TraceResult r = trace_vndf(target, wi, h.binnings, t);
  h.counts = r.counts;
  h.rays = r.rays;
  h.hits = r.hits;
  h.partial = r.partial;
  record_ellipsoid_target(h, target);
  const auto g17 = [](double x) { return fmt::format("{:.17g}", x); };
  h.attributes["wi"] = g17(wi.x()) + "," + g17(wi.y()) + "," + g17(wi.z());
  h.attributes["seed"] = std::to_string(options.seed);
  h.attributes["rays_per_second"] = g17(r.rays_per_second());
  if (raw) *raw = std::move(r);
  return h;
}

// ---- a traced reference's own departure from D_v ---------------------------------------------------------

namespace {

constexpr double kExcessMargin = 3.09;  // null standard deviations of X^2 taken off its excess (one-sided 0.1%)

// The probability that the binnings' Sidak-combined two-sample tests reject an exact sampler of `samples`.
double false_rejection(const ReferenceBias& b, std::uint64_t hits, double samples, double per_test) {
  double keep = 1;
  for (std::size_t k = 0; k < b.excess.size(); ++k) {
    if (b.excess[k] <= 0 || b.dof[k] < 1) continue;
    const double lambda = b.excess[k] * samples / (samples + double(hits));
    if (!(lambda < 1e7)) return 1;  // an impossible trace (X^2 infinite) or far beyond any critical value
    const double critical =
        boost::math::quantile(boost::math::complement(boost::math::chi_squared(b.dof[k]), per_test));
    keep *= boost::math::cdf(boost::math::non_central_chi_squared(b.dof[k], lambda), critical);
  }
  return 1 - keep;
}

// The largest sample count whose false rejection stays within the bound (bisection in log S).
std::uint64_t max_samples_within(const ReferenceBias& b, std::uint64_t hits, double per_test) {
  constexpr double kAny = 1e15;
  if (false_rejection(b, hits, kAny, per_test) <= b.bound) return std::numeric_limits<std::uint64_t>::max();
  double lo = 1, hi = kAny;
  for (int i = 0; i < 200 && hi / lo > 1.0001; ++i) {
    const double mid = std::sqrt(lo * hi);
    (false_rejection(b, hits, mid, per_test) <= b.bound ? lo : hi) = mid;
  }
  return std::uint64_t(lo);
}

}  // namespace

std::string ReferenceBias::describe() const {
  const std::string most = max_samples == std::numeric_limits<std::uint64_t>::max()
                               ? std::string("any number of samples")
                               : fmt::format("at most {} samples", max_samples);
  std::string excess_text;
  for (std::size_t k = 0; k < binnings.size(); ++k)
    excess_text += fmt::format("{}{} {:.1f} (dof {})", k ? ", " : "", binnings[k], excess[k], dof[k]);
  const bool nil = std::all_of(excess.begin(), excess.end(), [](double e) { return e <= 0; });
  if (nil)
    return fmt::format("the traced reference is D_v within its noise (its chi-square excess beyond the noise: {}): "
                       "it serves {}", excess_text, most);
  return fmt::format("the traced reference departs from D_v (its chi-square excess beyond the noise: {}): an exact "
                     "sampler of {} samples would be rejected with probability {:.3g} (bound {:.3g}, twice the "
                     "level); it serves {}",
                     excess_text, samples, false_rejection, bound, most);
}

BiasedReference::BiasedReference(ReferenceBias b)
    : std::invalid_argument(b.describe() + ": compare fewer samples, or trace a larger tile or more exact surface"),
      bias(std::move(b)) {}

ReferenceBias reference_bias(const TracedHistogram& traced, std::uint64_t samples, double significance) {
  TracedHistogram h = traced;
  const TraceAnalysis fit = analyse_against_vndf(h, histogram_ggx(traced), histogram_wi(traced), {}, significance);
  ReferenceBias b;
  b.samples = samples;
  b.bound = 2 * significance;
  for (const TraceFit& f : fit.fits) {
    const double d = f.chi2.dof;
    b.binnings.push_back(f.binning);
    b.dof.push_back(f.chi2.dof);
    b.excess.push_back(std::max(0.0, f.chi2.statistic - d - kExcessMargin * std::sqrt(2 * d)));
  }
  const double per_test = sidak_significance(significance, int(b.excess.size()));
  b.false_rejection = false_rejection(b, traced.hits, double(samples), per_test);
  b.max_samples = max_samples_within(b, traced.hits, per_test);
  return b;
}

// ---- sampler vs traced histogram -------------------------------------------------------------------------

namespace {

// The n finite numbers of the ','-separated attribute `key` (each a whole decimal token).
std::vector<double> parse_numbers(const TracedHistogram& h, const std::string& key, std::size_t n) {
  const auto it = h.attributes.find(key);
  if (it == h.attributes.end()) throw HistogramIoError(fmt::format("traced histogram: attribute '{}' is missing", key));
  const std::vector<std::string_view> fields = reader::split_commas(it->second);
  std::vector<double> values;
  for (const std::string_view field : fields) {
    const std::optional<double> v = reader::parse_finite_double(field);
    if (!v || fields.size() != n) {
      throw HistogramIoError(fmt::format("traced histogram: attribute {} = {} is not {} finite numbers separated by ','",
                                         key, reader::quote_excerpt(it->second), n));
    }
    values.push_back(*v);
  }
  return values;
}

void check_configuration(const TracedHistogram& traced, const GGX<double>& ggx, const Vec3<double>& wi) {
  const GGX<double> tg = histogram_ggx(traced);
  const Vec3<double> twi = histogram_wi(traced);
  const double tol = 1e-9;
  if (std::abs(tg.alpha_x() - ggx.alpha_x()) > tol * ggx.alpha_x() ||
      std::abs(tg.alpha_y() - ggx.alpha_y()) > tol * ggx.alpha_y() || (twi - wi.normalized()).norm() > tol) {
    throw std::invalid_argument(fmt::format(
        "the traced histogram was made for alpha ({}, {}) and wi ({:.9f}, {:.9f}, {:.9f}), not for alpha ({}, {}) "
        "and wi ({:.9f}, {:.9f}, {:.9f})",
        tg.alpha_x(), tg.alpha_y(), twi.x(), twi.y(), twi.z(), ggx.alpha_x(), ggx.alpha_y(), wi.x(), wi.y(), wi.z()));
  }
  if (traced.hits == 0) throw std::invalid_argument("the traced histogram has no hits");
}

// The oracle's counts per binning, with its remainder cell (hits outside the bins).
std::vector<std::vector<double>> oracle_counts(const TracedHistogram& traced) {
  std::vector<std::vector<double>> oracle(traced.binnings.size());
  for (std::size_t k = 0; k < oracle.size(); ++k) {
    oracle[k].assign(traced.counts[k].begin(), traced.counts[k].end());
    const std::uint64_t binned = std::accumulate(traced.counts[k].begin(), traced.counts[k].end(), std::uint64_t(0));
    oracle[k].push_back(double(traced.hits - binned));
  }
  return oracle;
}

}  // namespace

// How many samples the two-sample tests need, from the oracle's histogram: under homogeneity cell i
// expects min(Na, Nb) q_i (q: the oracle's proportions) on the smaller side, and pooling (chi2.h) must
// leave two cells, so both the samples and the oracle's hits need goodness_of_fit_minimum_samples(q).
std::uint64_t trace_minimum_samples(const TracedHistogram& traced) {
  std::uint64_t needed = minimum_samples_for_any_test();
  for (std::vector<double> q : oracle_counts(traced)) {
    for (double& x : q) x /= double(traced.hits);
    needed = std::max(needed, goodness_of_fit_minimum_samples(q));
  }
  return needed;
}

namespace {

constexpr const char* kTwoSampleRule =
    "so that the cells of the two-sample test do not pool into one: its largest cell must expect at least 5 samples "
    "of each side, and the other cells together at least 5";

void require_oracle_hits(const TracedHistogram& traced) {
  const std::uint64_t needed = trace_minimum_samples(traced);
  if (traced.hits < needed)
    throw InsufficientData(fmt::format("the traced histogram has {} hits, too few: the comparison needs at least {} ({})",
                                       traced.hits, needed, kTwoSampleRule),
                           traced.hits, needed);
}

void require_trace_samples(std::uint64_t samples, const TracedHistogram& traced) {
  require_oracle_hits(traced);
  const std::uint64_t needed = trace_minimum_samples(traced);
  if (samples < needed)
    throw InsufficientData(fmt::format("{} sample(s) are too few: the comparison with the traced histogram needs at "
                                       "least {} samples ({})",
                                       samples, needed, kTwoSampleRule),
                           samples, needed);
}

// The two-sample test against the oracle in each binning of the traced histogram.
battery::Expectations oracle_expectations(const TracedHistogram& traced) {
  std::vector<std::vector<double>> oracle = oracle_counts(traced);
  battery::Expectations e;
  for (std::size_t k = 0; k < oracle.size(); ++k)
    e.push_back(battery::oracle_expectation(traced.binnings[k], std::move(oracle[k])));
  return e;
}

// The reference's bias at `samples` (reference_bias), or BiasedReference when it is not usable.
ReferenceBias require_usable_reference(const TracedHistogram& traced, std::uint64_t samples, double significance) {
  ReferenceBias bias = reference_bias(traced, samples, significance);
  if (!bias.usable()) throw BiasedReference(std::move(bias));
  return bias;
}

// The report's statement of a usable reference's bias (a hard check: an unusable one never reaches a report).
SubTest reference_bias_check(const ReferenceBias& bias) {
  SubTest t;
  t.name = "reference_bias";
  t.label = "reference bias";
  t.value = bias.false_rejection;
  t.tolerance = bias.bound;
  t.passed = bias.usable();
  t.detail = bias.describe();
  return t;
}

// The report of the samples' counts against the oracle's: the two-sample tests and the domain check
// (the checks against a claimed pdf do not apply).
ValidationReport oracle_report(const battery::SampleSource& source, const battery::Tally& tally,
                               const battery::Expectations& expectations, const GGX<double>& ggx,
                               const Vec3<double>& wi, const ValidationOptions& options, const ReferenceBias& bias) {
  using namespace battery;
  ValidationReport r = report_header(source, SampleDomain::microfacet_normal, ggx, wi.normalized(), tally, options);
  add_binned_tests(r, expectations, tally, options);
  const std::string not_here = "not applicable: comparison with the traced oracle (two-sample test only)";
  r.checks = {domain_check(r, tally, options), not_applicable("pdf_integral", not_here),
              not_applicable("returned_pdf", not_here), not_applicable("weight_mean", not_here),
              reference_bias_check(bias)};
  decide(r);
  return r;
}

// Tallies the samples of `source` in the traced histogram's binnings and compares them with the oracle.
// `require` runs on the number of samples seen, before any test.
template <class Require>
ValidationReport compare_source(const battery::SampleSource& source, const GGX<double>& ggx, const Vec3<double>& wi,
                                const ValidationOptions& options, const TracedHistogram& traced, Require&& require) {
  const auto start = std::chrono::steady_clock::now();
  const battery::Expectations expectations = oracle_expectations(traced);
  const battery::Tally tally = battery::tally_samples(source, battery::binnings_of(expectations), options);
  require(tally.samples);
  const ReferenceBias bias = require_usable_reference(traced, tally.samples, options.significance);
  ValidationReport r = oracle_report(source, tally, expectations, ggx, wi, options, bias);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

}  // namespace

GGX<double> histogram_ggx(const TracedHistogram& h) {
  const auto a = parse_numbers(h, "alpha", 2);
  if (!(a[0] > 0) || !(a[1] > 0)) throw HistogramIoError("traced histogram: alpha must be positive");
  return GGX<double>(a[0], a[1]);
}

Vec3<double> histogram_wi(const TracedHistogram& h) {
  const auto w = parse_numbers(h, "wi", 3);
  const Vec3<double> wi(w[0], w[1], w[2]);
  if (!(wi.norm() > 0)) throw HistogramIoError("traced histogram: wi must be a non-zero direction");
  return wi.normalized();
}

namespace {
void check_sampler_for_trace(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                             const TracedHistogram& traced) {
  if (sampler.domain != SampleDomain::microfacet_normal) {
    throw std::invalid_argument(fmt::format(
        "sampler '{}' samples reflected directions; the traced oracle measures microfacet normals", sampler.name));
  }
  check_configuration(traced, ggx, wi);
}
}  // namespace

namespace {
// The sampler's options.samples tallied in the traced histogram's binnings (no check).
battery::Tally tally_drawn(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                           const ValidationOptions& options, const TracedHistogram& traced) {
  std::vector<const DirectionBinning*> binnings;
  for (const DirectionBinning& b : traced.binnings) binnings.push_back(&b);
  return battery::tally_samples(battery::drawn_samples(sampler, ggx, wi, options), binnings, options);
}
}  // namespace

// The reference's bias computed once (its fit to D_v is a cubature), before any sample is drawn.
ValidationReport compare_sampler_to_trace(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                                          const ValidationOptions& options, const TracedHistogram& traced) {
  const auto start = std::chrono::steady_clock::now();
  check_sampler_for_trace(sampler, ggx, wi, traced);
  require_trace_samples(options.samples, traced);
  const ReferenceBias bias = require_usable_reference(traced, options.samples, options.significance);
  const battery::Tally tally = tally_drawn(sampler, ggx, wi, options, traced);
  ValidationReport r = oracle_report(battery::drawn_samples(sampler, ggx, wi, options), tally,
                                     oracle_expectations(traced), ggx, wi, options, bias);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

battery::Tally tally_drawn_samples_for_trace(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                                             const ValidationOptions& options, const TracedHistogram& traced) {
  check_sampler_for_trace(sampler, ggx, wi, traced);
  require_trace_samples(options.samples, traced);
  require_usable_reference(traced, options.samples, options.significance);  // before any sample is drawn
  return tally_drawn(sampler, ggx, wi, options, traced);
}

ValidationReport report_drawn_samples_against_trace(const SamplerInfo& sampler, const GGX<double>& ggx,
                                                    const Vec3<double>& wi, const battery::Tally& tally,
                                                    const ValidationOptions& options, const TracedHistogram& traced) {
  return oracle_report(battery::drawn_samples(sampler, ggx, wi, options), tally, oracle_expectations(traced), ggx, wi,
                       options, require_usable_reference(traced, tally.samples, options.significance));
}

namespace {
template <class Stream>
ValidationReport compare_stream(Stream& stream, std::string source, const GGX<double>& ggx, const Vec3<double>& wi,
                                const ValidationOptions& options, const TracedHistogram& traced) {
  check_configuration(traced, ggx, wi);
  require_oracle_hits(traced);  // before reading
  return compare_source(battery::given_samples(stream, std::move(source)), ggx, wi, options, traced,
                        [&traced](std::uint64_t seen) { require_trace_samples(seen, traced); });
}
}  // namespace

ValidationReport compare_samples_to_trace(std::span<const Vec3<double>> samples, std::string source,
                                          const GGX<double>& ggx, const Vec3<double>& wi,
                                          const ValidationOptions& options, const TracedHistogram& traced) {
  return compare_stream(samples, std::move(source), ggx, wi, options, traced);
}

ValidationReport compare_sample_file_to_trace(DirectionSampleReader& reader, std::string source, const GGX<double>& ggx,
                                              const Vec3<double>& wi, const ValidationOptions& options,
                                              const TracedHistogram& traced) {
  return compare_stream(reader, std::move(source), ggx, wi, options, traced);
}

}  // namespace microsim
