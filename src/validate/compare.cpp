#include "validate/compare.h"

#include "core/random.h"
#include "validate/sample_io.h"
#include "core/strict_parse.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
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

TraceAnalysis analyse_against_vndf(TracedHistogram& h, const GGX<double>& ggx, const Vec3<double>& wi,
                                   std::span<const std::uint64_t> unbinned, double significance) {
  if (h.binnings.empty()) throw std::invalid_argument("analyse_against_vndf: no binning");
  const int rows = h.binnings.front().rows();
  const auto ref = vndf_reference(SampleDomain::microfacet_normal, ggx, wi, rows);
  TraceAnalysis a;
  a.significance = significance;
  h.probability.assign(h.binnings.size(), {});
  const int n_tests = int(h.binnings.size());
  const double per_test = sidak_significance(significance, n_tests);
  double p_min = 1;
  for (std::size_t k = 0; k < h.binnings.size(); ++k) {
    const DirectionBinning& b = h.binnings[k];
    const BinIntegrals& bi = b.kind() == BinningKind::sphere ? ref->sphere_probability : ref->lobe_probability;
    const DirectionBinning& rb = b.kind() == BinningKind::sphere ? ref->sphere : ref->lobe;
    if (rb.size() != b.size()) throw std::invalid_argument("analyse_against_vndf: binning mismatch");
    h.probability[k] = bi.probability;
    TraceFit fit;
    fit.binning = b.name();
    fit.total_variation = total_variation(h.counts[k], h.hits, bi.probability);
    fit.noise_floor_tv = noise_floor_tv(bi.probability, h.hits);
    if (h.hits > 0) {
      std::vector<double> observed(h.counts[k].begin(), h.counts[k].end());
      std::vector<double> expected = bi.probability;
      const std::uint64_t binned = std::accumulate(h.counts[k].begin(), h.counts[k].end(), std::uint64_t(0));
      observed.push_back(double(k < unbinned.size() ? unbinned[k] : h.hits - binned));
      expected.push_back(std::max(0.0, 1.0 - bi.total));
      ChiSquareOptions chi;
      chi.significance = per_test;
      chi.describe_cell = [&b](int bin) { return bin < b.size() ? b.describe_bin(bin) : std::string("remainder (outside the bins)"); };
      fit.chi2 = goodness_of_fit(observed, expected, double(h.hits), chi);
    } else {
      fit.chi2.reason = "no hits";
      fit.chi2.significance = per_test;
    }
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
  t.blocks = options.blocks;
  t.run = options.run;
  TraceResult r = trace_vndf(target, wi, h.binnings, t);
  h.counts = r.counts;
  h.rays = r.rays;
  h.hits = r.hits;
  h.partial = r.partial;
  const auto g17 = [](double x) { return fmt::format("{:.17g}", x); };
  h.attributes["surface"] = "ellipsoid";
  h.attributes["target"] = target.describe();
  h.attributes["mesh_level"] = std::to_string(target.mesh_level());
  h.attributes["alpha"] = g17(ggx.alpha_x()) + "," + g17(ggx.alpha_y());
  h.attributes["wi"] = g17(wi.x()) + "," + g17(wi.y()) + "," + g17(wi.z());
  h.attributes["seed"] = std::to_string(options.seed);
  h.attributes["rays_per_second"] = g17(r.rays_per_second());
  if (raw) *raw = std::move(r);
  return h;
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

// The samples' histograms in the traced histogram's binnings, each with a remainder cell (failed samples or
// directions outside the binning's parameter space).
struct TraceBinCounts {
  std::vector<std::vector<double>> sampled;
  std::uint64_t samples = 0, failed = 0, outside = 0;
};

// Streams the samples (`drive(visit, chunk_done)`: a sampler's draw, a span or a file) through the traced
// histogram's binnings, into per-thread integer histograms (exact sums: independent of the thread count).
// FastDirectionBinner gives exactly DirectionBinning::bin_of, three times faster.
template <class Drive>
TraceBinCounts bin_for_trace(const TracedHistogram& traced, const ValidationOptions& options, Drive&& drive) {
  const std::size_t nk = traced.binnings.size();
  std::vector<FastDirectionBinner> binners;
  for (const DirectionBinning& b : traced.binnings) binners.emplace_back(b);
  struct Local {
    std::vector<std::vector<std::uint64_t>> counts;
    std::uint64_t samples = 0, failed = 0, outside = 0;
  };
  tbb::enumerable_thread_specific<Local> locals([&] {
    Local l;
    l.counts.resize(nk);
    for (std::size_t k = 0; k < nk; ++k) l.counts[k].assign(std::size_t(traced.binnings[k].size()) + 1, 0);
    return l;
  });
  drive([&](const SampleBlockView& block, std::size_t) {
    Local& l = locals.local();
    l.samples += block.directions.size();
    for (std::size_t i = 0; i < block.directions.size(); ++i) {
      if (!block.valid.empty() && !block.valid[i]) {
        ++l.failed;
        for (std::size_t k = 0; k < nk; ++k) ++l.counts[k].back();
        continue;
      }
      const Vec3<double>& w = block.directions[i];
      if (!w.allFinite() || !(std::abs(w.norm() - 1) <= options.unit_tolerance)) {
        ++l.outside;
        continue;
      }
      for (std::size_t k = 0; k < nk; ++k) {
        const int bin = binners[k](w);
        ++l.counts[k][bin >= 0 ? std::size_t(bin) : l.counts[k].size() - 1];
      }
    }
  });
  TraceBinCounts c;
  c.sampled.resize(nk);
  for (std::size_t k = 0; k < nk; ++k) c.sampled[k].assign(std::size_t(traced.binnings[k].size()) + 1, 0.0);
  for (const Local& l : locals) {
    c.samples += l.samples;
    c.failed += l.failed;
    c.outside += l.outside;
    for (std::size_t k = 0; k < nk; ++k)
      for (std::size_t b = 0; b < l.counts[k].size(); ++b) c.sampled[k][b] += double(l.counts[k][b]);
  }
  return c;
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

ValidationReport compare_counts(std::string name, const TraceBinCounts& counts, const GGX<double>& ggx,
                                const Vec3<double>& wi, const ValidationOptions& options, Precision precision,
                                const TracedHistogram& traced) {
  const auto start = std::chrono::steady_clock::now();
  ValidationReport r;
  r.sampler = std::move(name);
  r.domain = SampleDomain::microfacet_normal;
  r.alpha_x = ggx.alpha_x();
  r.alpha_y = ggx.alpha_y();
  r.wi = wi.normalized();
  r.samples = counts.samples;
  r.seed = options.seed;
  r.precision = precision;
  r.significance = options.significance;
  r.failed_samples = counts.failed;
  r.outside_domain = counts.outside;
  const std::size_t nk = traced.binnings.size();
  const std::vector<std::vector<double>>& sampled = counts.sampled;
  const std::vector<std::vector<double>> oracle = oracle_counts(traced);

  const int n_tests = int(nk);
  r.statistical_tests = n_tests;
  r.per_test_significance = sidak_significance(options.significance, n_tests);
  double p_min = 1;
  std::vector<ChiSquareResult> results;
  for (std::size_t k = 0; k < nk; ++k) {
    const DirectionBinning& b = traced.binnings[k];
    ChiSquareOptions chi;
    chi.significance = r.per_test_significance;
    chi.worst_cells = options.worst_cells;
    chi.describe_cell = [&b](int bin) { return bin < b.size() ? b.describe_bin(bin) : std::string("remainder (failed or outside the bins)"); };
    ChiSquareResult c;
    if (std::accumulate(sampled[k].begin(), sampled[k].end(), 0.0) > 0) {
      c = two_sample_homogeneity(sampled[k], oracle[k], chi);
      // The samples' own counts decide the pooling here: near the bound of require_trace_samples the
      // cells can still pool into one by chance. A test that cannot reject is no pass.
      if (!c.rejected && c.dof < 1)
        throw InsufficientData(fmt::format("{} sample(s) pooled into a single cell of the {} bins: the two-sample test "
                                           "cannot reject; use more samples (or more oracle rays)",
                                           r.samples, b.name()),
                               r.samples, r.samples + 1);
    } else {
      c.test = "two_sample_homogeneity";
      c.p_value = 0;
      c.rejected = true;
      c.reason = "no sample inside the domain";
    }
    c.significance = r.per_test_significance;
    c.rejected = c.rejected || c.p_value < r.per_test_significance;
    p_min = std::min(p_min, c.p_value);
    if (b.kind() == BinningKind::sphere) r.sphere = c;
    else r.lobe = c;
    results.push_back(std::move(c));
    // For figures: the oracle's counts rescaled to the samples' total (remainder cells included in both).
    const double total_sampled = std::accumulate(sampled[k].begin(), sampled[k].end(), 0.0);
    const double total_oracle = std::accumulate(oracle[k].begin(), oracle[k].end(), 0.0);
    BinnedComparison figure{b, std::vector<double>(sampled[k].begin(), sampled[k].begin() + b.size()),
                            std::vector<double>(oracle[k].begin(), oracle[k].begin() + b.size()),
                            "traced oracle (rescaled)"};
    for (double& e : figure.expected) e *= total_oracle > 0 ? total_sampled / total_oracle : 0.0;
    r.histograms.push_back(std::move(figure));
  }
  r.p_value = sidak_adjusted_p(p_min, n_tests);
  const ChiSquareResult& headline = *std::min_element(
      results.begin(), results.end(), [](const auto& a, const auto& b) { return a.p_value < b.p_value; });
  r.statistic = headline.statistic;
  r.dof = headline.dof;

  r.domain_check.name = "domain";
  r.domain_check.value = double(r.outside_domain);
  r.domain_check.passed = r.outside_domain == 0;
  r.domain_check.detail = fmt::format("{} sample(s) non-finite or with | |w| - 1 | > {}", r.outside_domain,
                                      options.unit_tolerance);
  const std::string not_here = "not applicable: comparison with the traced oracle (two-sample test only)";
  for (SubTest* t : {&r.weight, &r.pdf, &r.integral}) {
    t->applicable = false;
    t->statistical = false;
    t->passed = true;
    t->detail = not_here;
  }
  r.weight.name = "weight_mean";
  r.pdf.name = "returned_pdf";
  r.integral.name = "pdf_integral";

  if (!r.domain_check.passed) r.failures.push_back(r.domain_check.detail);
  for (std::size_t k = 0; k < nk; ++k) {
    const ChiSquareResult& c = results[k];
    if (c.rejected) {
      r.failures.push_back(fmt::format("two-sample chi-square against the traced oracle in {} bins rejects: p = {:.3g} < {:.3g}{}",
                                       traced.binnings[k].name(), c.p_value, r.per_test_significance,
                                       c.reason.empty() ? "" : " (" + c.reason + ")"));
    }
  }
  r.passed = r.failures.empty();
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

ValidationReport compare_sampler_to_trace(const SamplerInfo& sampler, const GGX<double>& ggx, const Vec3<double>& wi,
                                          const ValidationOptions& options, const TracedHistogram& traced) {
  if (sampler.domain != SampleDomain::microfacet_normal) {
    throw std::invalid_argument(fmt::format(
        "sampler '{}' samples reflected directions; the traced oracle measures microfacet normals", sampler.name));
  }
  const auto start = std::chrono::steady_clock::now();
  check_configuration(traced, ggx, wi);
  require_trace_samples(options.samples, traced);
  const TraceBinCounts counts = bin_for_trace(traced, options, [&](const auto& visit) {
    for_each_drawn_block(sampler, ggx, wi, options, visit);
  });
  ValidationReport r = compare_counts(std::string(sampler.name), counts, ggx, wi, options, options.precision, traced);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

namespace {
template <class Stream>
ValidationReport compare_stream(Stream& stream, std::string source, const GGX<double>& ggx, const Vec3<double>& wi,
                                const ValidationOptions& options, const TracedHistogram& traced) {
  check_configuration(traced, ggx, wi);
  require_oracle_hits(traced);  // before reading
  const TraceBinCounts counts =
      bin_for_trace(traced, options, [&](const auto& visit) { for_each_block(stream, visit); });
  require_trace_samples(counts.samples, traced);
  ValidationOptions o = options;
  o.samples = counts.samples;
  return compare_counts(std::move(source), counts, ggx, wi, o, Precision::float64, traced);
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
