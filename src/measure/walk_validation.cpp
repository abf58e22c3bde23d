// A renderer's multiple-scattering BSDF against the Smith random walk (walk_validation.h).
#include "measure/walk_validation.h"
#include "stats/json_values.h"

#include "scatter/scatter_setup.h"
#include "stats/scatter_compare.h"

#include <fmt/core.h>

#include <cmath>
#include <stdexcept>

namespace microsim {

namespace {

ScatterOptions walk_options(const Material& material, const Vec3<double>& wi, const WalkValidationOptions& o) {
  ScatterOptions s;
  s.wi = wi;
  s.material = material;
  s.paths = o.paths;
  s.seed = o.seed;
  s.rows = o.rows;
  s.max_order = o.max_order;
  s.run = o.run;
  return s;
}

// The dump's rows as a histogram of one order over the walk's binning: each row a launched path leaving with its
// weights; the dropped samples launched paths that left nothing. `spread` gets each channel's weights.
ScatterHistogram dump_histogram(DirectionSampleReader& dump, const ScatterOptions& s, std::uint64_t dropped,
                                std::vector<DominanceTally>& spread) {
  const int channels = s.material.channels();
  if (dump.columns().channels() != channels)
    throw std::invalid_argument(fmt::format("the dump has {} weight column(s); the material has {} channel(s)",
                                            dump.columns().channels(), channels));
  ScatterHistogram h = empty_scatter_histogram(s, "dump", "a renderer's samples");
  const DirectionBinning binning = DirectionBinning::hemispheres(s.rows);
  std::vector<Vec3<double>> rows(kSampleFileBlock);
  std::vector<double> pdfs(dump.columns().has_pdf() ? rows.size() : 0), weights(rows.size() * std::size_t(channels));
  spread.assign(std::size_t(channels), DominanceTally{});
  for (std::size_t n; (n = dump.read(rows, pdfs, weights)) > 0;) {
    if (s.run.cancelled()) throw Cancelled("reading the dump");
    for (std::size_t i = 0; i < n; ++i) {
      const std::span<const double> w(&weights[i * std::size_t(channels)], std::size_t(channels));
      for (std::size_t c = 0; c < w.size(); ++c) spread[c].add(w[c]);
      if (const auto bin = binning.bin_of(rows[i])) h.add_escaped(1, std::size_t(*bin), w);
      else h.add_escaped_unbinned(1, w);
    }
    h.add_launched(n);
  }
  h.add_launched(dropped);
  for (DominanceTally& t : spread) t.add_zeros(dropped);
  return h;
}

// The albedo tests compare means with their own standard errors: void when one row holds much of the spread.
void firefly_check(WalkValidationReport& r, const DominanceTally& spread) {
  r.dominant = spread.result();
  if (!r.dominant.dominates()) return;
  r.failures.push_back("the dump's albedo cannot be tested: " + r.dominant.firefly());
  r.passed = false;
}

// One channel's three tests; the report keeps the channel whose smallest p is the smallest.
WalkValidationReport channel_report(const ScatterHistogram& dump, const ScatterHistogram& walk, int c, bool from_inside) {
  WalkValidationReport r;
  r.channel = c;
  const ScatterSide same = from_inside ? ScatterSide::transmitted : ScatterSide::reflected;
  const ScatterSide other = from_inside ? ScatterSide::reflected : ScatterSide::transmitted;
  r.albedo_reflected_dump = dump.albedo(c, kTotalOrder, same);
  r.albedo_reflected_walk = walk.albedo(c, kTotalOrder, same);
  r.albedo_transmitted_dump = dump.albedo(c, kTotalOrder, other);
  r.albedo_transmitted_walk = walk.albedo(c, kTotalOrder, other);
  r.walk_unfinished = walk.unfinished(c);
  r.p_reflected = difference_p(r.albedo_reflected_dump, r.albedo_reflected_walk);
  r.p_transmitted = difference_p(r.albedo_transmitted_dump, r.albedo_transmitted_walk);
  ScatterFile a, b;
  a.histogram = dump;
  b.histogram = walk;
  const LobeComparison l = compare_lobes(*scatter_lobe(a, c, kTotalOrder), *scatter_lobe(b, c, kTotalOrder),
                                         effective_entry_options());
  r.tv = l.tv;
  r.tv_noise_floor = l.tv_noise_floor;
  r.chi2 = l.chi2;
  r.insufficient = l.insufficient;
  return r;
}

void walk_verdict(WalkValidationReport& r, int channels, double significance, bool transmits) {
  r.tests = channels * (transmits ? 3 : 2);
  r.per_test_significance = sidak_significance(significance, r.tests);
  const double p_min = std::min({r.chi2->p_value, r.p_reflected, transmits ? r.p_transmitted : 1.0});
  r.p_value = sidak_adjusted_p(p_min, r.tests);
  if (r.chi2->p_value < r.per_test_significance)
    r.failures.push_back(fmt::format("the lobe's shape differs from the walk's (chi-square p = {:.3g}, TV {:.4f} against "
                                     "a noise floor of {:.4f})", r.chi2->p_value, r.tv, r.tv_noise_floor));
  if (r.p_reflected < r.per_test_significance)
    r.failures.push_back(fmt::format("the reflected albedo {:.5f} +- {:.5f} differs from the walk's {:.5f} +- {:.5f} (p = "
                                     "{:.3g})", r.albedo_reflected_dump.value, r.albedo_reflected_dump.standard_error,
                                     r.albedo_reflected_walk.value, r.albedo_reflected_walk.standard_error, r.p_reflected));
  if (transmits && r.p_transmitted < r.per_test_significance)
    r.failures.push_back(fmt::format("the transmitted albedo {:.5f} +- {:.5f} differs from the walk's {:.5f} +- {:.5f} (p "
                                     "= {:.3g})", r.albedo_transmitted_dump.value, r.albedo_transmitted_dump.standard_error,
                                     r.albedo_transmitted_walk.value, r.albedo_transmitted_walk.standard_error,
                                     r.p_transmitted));
  r.passed = r.failures.empty();
}

}  // namespace

WalkValidationReport validate_dump_against_walk(DirectionSampleReader& dump, const SmithMicrosurface& surface,
                                                const Material& material, const Vec3<double>& wi,
                                                const WalkValidationOptions& options) {
  const ScatterOptions s = walk_options(material, wi, options);
  check_scatter_options(s);
  std::vector<DominanceTally> spread;
  const ScatterHistogram d = dump_histogram(dump, s, options.dropped, spread);
  const ScatterHistogram walk = smith_walk_scatter(surface, s);
  if (walk.partial) throw Cancelled("the walk");
  WalkValidationReport best;
  for (int c = 0; c < material.channels(); ++c) {
    WalkValidationReport r = channel_report(d, walk, c, wi.z() < 0);
    if (!r.chi2)
      throw InsufficientData(fmt::format("too little data for the lobe's shape test: {}", r.insufficient), d.paths(), 0);
    walk_verdict(r, material.channels(), options.significance, material.transmits());
    firefly_check(r, spread[std::size_t(c)]);
    // A failed channel is reported before a passing one with a smaller p (a firefly fails at any p).
    if (c == 0 || (r.passed != best.passed ? !r.passed : r.p_value < best.p_value)) best = std::move(r);
  }
  best.rows = d.paths();
  best.paths = walk.paths();
  return best;
}

nlohmann::json to_json(const WalkValidationReport& r) {
  nlohmann::json j{{"verdict", r.passed ? "pass" : "fail"},
                   {"model", "smith-walk"},
                   {"rows", r.rows},
                   {"walk_paths", r.paths},
                   {"channel", r.channel},
                   {"tv", r.tv},
                   {"tv_noise_floor", r.tv_noise_floor},
                   {"albedo_reflected", {{"dump", estimate_json(r.albedo_reflected_dump)}, {"walk", estimate_json(r.albedo_reflected_walk)}, {"p", r.p_reflected}}},
                   {"albedo_transmitted",
                    {{"dump", estimate_json(r.albedo_transmitted_dump)}, {"walk", estimate_json(r.albedo_transmitted_walk)}, {"p", r.p_transmitted}}},
                   {"walk_unfinished", estimate_json(r.walk_unfinished)},
                   {"dominant_weight", {{"row", r.dominant.index}, {"weight", r.dominant.value}, {"share", r.dominant.share}}},
                   {"tests", r.tests},
                   {"per_test_significance", r.per_test_significance},
                   {"p_value", r.p_value},
                   {"failures", r.failures}};
  if (r.chi2) j["chi2"] = to_json(*r.chi2);
  return j;
}

}  // namespace microsim
