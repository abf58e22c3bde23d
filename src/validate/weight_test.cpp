#include "validate/weight_test.h"

#include "microfacet/bsdf.h"
#include "stats/chi2.h"
#include "stats/direction_binner.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <tuple>
#include <utility>

namespace microsim {

namespace {

// f(wi, wo) |cos(wo)| of channel c in the renderer's convention: the expected weight per unit solid angle of
// the sampled wo (wi: the direction the sampler was given).
double bsdf_flux(const GGX<double>& ggx, const Material& bsdf, const BsdfConvention& convention, int c,
                 const Vec3<double>& wi, const Vec3<double>& wo) {
  switch (bsdf.kind()) {
    case MaterialKind::mirror: return mirror_brdf(ggx, wi, wo, convention.masking) * std::max(wo.z(), 0.0);
    case MaterialKind::conductor:
      return conductor_brdf(ggx, bsdf.ior(c), wi, wo, convention.masking) * std::max(wo.z(), 0.0);
    case MaterialKind::dielectric: return dielectric_bsdf_as(ggx, bsdf.eta(), wi, wo, convention) * std::abs(wo.z());
    case MaterialKind::lambertian: break;
  }
  return 0.0;
}

// A mean weight over n samples against its moments under the reference (one sample's E[w^j 1_B], j = 1..3):
// z = (sum / n - m1) / se, se = sqrt((m2 - m1^2) / n) (with a floor of 1e-12 relative for rounding), and the
// two-sided p from the translated gamma of the mean's skewness (stats/chi2.h skewed_mean_p; Chebyshev's bound
// where the gamma would put the mean below 0: a bin that few nonzero weights reach).
struct MeanTest {
  double z = 0, p = 1;
};

MeanTest mean_test(double sum, double n, double m1, double m2, double m3) {
  const double var = std::max(m2 - m1 * m1, 0.0), se = std::sqrt(var / n + 1e-24 * m1 * m1);
  const double deviation = sum / n - m1;
  const double mu3 = m3 - 3 * m1 * m2 + 2 * m1 * m1 * m1;  // one sample's third central moment
  const double skew = var > 0 ? mu3 / (var * std::sqrt(var) * std::sqrt(n)) : 0.0;
  const double z = se > 0 ? deviation / se : (deviation == 0 ? 0.0 : INFINITY);
  return {z, skewed_mean_p(deviation, se, skew, -m1)};  // weights are >= 0: the mean is at least 0
}

// No negative weight: a BSDF and a pdf are never negative, and a few negative weights hide in a mean.
SubTest sign_check(const WeightSums& s) {
  SubTest t;
  t.name = "bsdf_weight_sign";
  t.label = "negative weights";
  t.passed = s.negative == 0;
  t.value = double(s.negative);
  t.detail = t.passed ? "none"
                      : fmt::format("{} of {} samples have a negative weight (the first: sample {}, weight {:.6g})",
                                    s.negative, s.rows, s.first_negative_row, s.first_negative);
  return t;
}

// One channel's mean weight over all bins against its albedo.
struct ChannelAlbedo {
  double p = 2, mean = 0, sd = 0, albedo = 0, albedo_sd = 0;
  int channel = 0;
};

ChannelAlbedo channel_albedo(const WeightSums& s, const ExpectedWeights& e, double n, std::size_t c) {
  double sum = 0, sum_sq = 0, albedo = 0, square = 0, cube = 0;
  for (std::size_t b = 0; b < e.mean[c].size(); ++b) {
    sum += s.sum[c][b];
    sum_sq += s.sum_sq[c][b];
    albedo += e.mean[c][b];
    square += e.square[c][b];
    cube += e.cube[c][b];
  }
  return {mean_test(sum, n, albedo, square, cube).p, sum / n, std::sqrt(std::max(sum_sq / n - sqr(sum / n), 0.0)),
          albedo, std::sqrt(std::max(square - sqr(albedo), 0.0)), int(c)};
}

// The mean weight per channel against the albedo (the sums over the bins of the expected weights `e`, already
// scaled); the figures shown are those of the channel of the smallest p.
SubTest albedo_test(const WeightSums& s, const ExpectedWeights& e, double n, const Material& bsdf,
                    const ValidationOptions& options) {
  ChannelAlbedo worst;
  for (std::size_t c = 0; c < e.mean.size(); ++c)
    if (const ChannelAlbedo a = channel_albedo(s, e, n, c); a.p < worst.p) worst = a;
  SubTest t;
  t.name = "bsdf_albedo";
  t.label = "BSDF albedo (mean weight)";
  t.statistical = true;
  t.p_value = sidak_adjusted_p(std::min(worst.p, 1.0), int(e.mean.size()));
  t.value = worst.mean;
  t.tolerance = worst.albedo;
  const std::string dropped =
      options.dropped_below_horizon ? fmt::format(" + {} dropped", *options.dropped_below_horizon) : "";
  const std::string channel = e.mean.size() > 1 ? fmt::format(", channel {}", bsdf.channel_name(worst.channel)) : "";
  t.detail = fmt::format("mean weight {:.6g} vs the BSDF's directional albedo {:.6g} ({}{}, {}; {} samples{}); the "
                         "weights' standard deviation {:.4g} vs the BSDF's {:.4g}",
                         worst.mean, worst.albedo, bsdf.describe(), channel, describe(options.convention), s.rows,
                         dropped, worst.sd, worst.albedo_sd);
  return t;
}

// The mean weight per bin (with at least kMinWeightBinSamples samples) and channel against the flux.
SubTest bins_test(const WeightSums& s, const ExpectedWeights& e, double n, const DirectionBinning& sphere,
                  const Material& bsdf) {
  MeanTest worst_test;
  int tested = 0;
  std::string worst;
  for (std::size_t c = 0; c < e.mean.size(); ++c)
    for (std::size_t b = 0; b < e.mean[c].size(); ++b) {
      if (s.samples[b] < kMinWeightBinSamples) continue;
      ++tested;
      const MeanTest test = mean_test(s.sum[c][b], n, e.mean[c][b], e.square[c][b], e.cube[c][b]);
      if (std::isnan(worst_test.z) || !(test.p < worst_test.p || std::isnan(test.z))) continue;  // NaN stays the worst
      worst_test = test;
      worst = fmt::format("{} ({}): mean weight {:.4g} vs flux {:.4g}", sphere.describe_bin(int(b)),
                          bsdf.channel_name(int(c)), s.sum[c][b] / n, e.mean[c][b]);
    }
  SubTest t;
  t.name = "bsdf_bins";
  t.label = "BSDF flux per bin (mean weight)";
  t.applicable = t.statistical = tested > 0;
  t.p_value = tested > 0 ? sidak_adjusted_p(worst_test.p, tested) : 1.0;
  t.value = worst_test.z;
  t.detail = tested > 0 ? fmt::format("{} bin-channels with >= {} samples; worst z = {:.2f} at {}", tested,
                                      kMinWeightBinSamples, worst_test.z, worst)
                        : "not applicable: no bin holds enough samples";
  return t;
}

void check_weight_inputs(const SampleColumns& columns, const ReferenceDistribution& ref, const Material& bsdf) {
  if (ref.domain != SampleDomain::reflected_direction)
    throw std::invalid_argument("--bsdf: the weight test needs outgoing directions (--reflected or --pdf "
                                "reflection|bounded|bsdf)");
  if (bsdf.kind() == MaterialKind::lambertian)
    throw std::invalid_argument(fmt::format("--bsdf {}: the weight test has mirror, conductor and dielectric BSDFs",
                                            bsdf.describe()));
  if (columns.channels() != bsdf.channels())
    throw std::invalid_argument(fmt::format("--bsdf {} has {} channel(s) but the file {} weight column(s) (--columns)",
                                            bsdf.describe(), bsdf.channels(), columns.channels()));
}

// The sums of the weights of the samples `reader` reads, block by block; a cancelled run stops between blocks.
WeightSums sum_weights(DirectionSampleReader& reader, const DirectionBinning& sphere, int channels, const RunControl& run) {
  const FastDirectionBinner binner(sphere);
  WeightSums s(channels, sphere.size());
  std::vector<Vec3<double>> rows(kSampleFileBlock);
  std::vector<double> pdfs(reader.columns().has_pdf() ? rows.size() : 0), weights(rows.size() * std::size_t(channels));
  while (const std::size_t n = reader.read(rows, pdfs, weights)) {
    s.add(binner, rows, weights, n);
    if (run.cancelled()) throw Cancelled("while summing the weights");
  }
  return s;
}

// The weight tests of the samples `open()` reads (opened once the inputs are checked).
std::vector<SubTest> weight_tests_of(const std::function<DirectionSampleReader()>& open, const SampleColumns& columns,
                                     const ReferenceDistribution& ref, const Material& bsdf,
                                     const ValidationOptions& options) {
  check_weight_inputs(columns, ref, bsdf);
  ExpectedWeights expected = expected_bin_weights(ref, bsdf, options.convention);
  // Conditioned on the kept samples without the dropped count: the kept samples' mean weight.
  if (ref.kept_only && !options.dropped_below_horizon) expected.divide(ref.kept_mass);
  DirectionSampleReader reader = open();
  const WeightSums s = sum_weights(reader, ref.sphere, bsdf.channels(), options.run);
  const double n = double(s.rows + options.dropped_below_horizon.value_or(0));
  return weight_checks(s, expected, n, ref.sphere, bsdf, options);
}

}  // namespace

WeightSums::WeightSums(int channels, int bins)
    : sum(std::size_t(channels), std::vector<double>(std::size_t(bins), 0.0)),
      sum_sq(std::size_t(channels), std::vector<double>(std::size_t(bins), 0.0)),
      samples(std::size_t(bins), 0) {}

void WeightSums::add(const FastDirectionBinner& binner, std::span<const Vec3<double>> directions,
                     std::span<const double> weights, std::size_t n) {
  const std::size_t channels = sum.size();
  rows += n;
  for (std::size_t i = 0; i < n; ++i) {
    if (!directions[i].allFinite()) continue;  // the sampler's failure: weighs nothing, counted in rows
    const auto row = weights.subspan(i * channels, channels);
    if (const auto w = std::find_if(row.begin(), row.end(), [](double x) { return x < 0; }); w != row.end())
      if (negative++ == 0) std::tie(first_negative_row, first_negative) = std::pair(rows - n + i + 1, *w);
    const int b = binner(directions[i]);
    if (b < 0) continue;
    ++samples[std::size_t(b)];
    for (std::size_t c = 0; c < channels; ++c) {
      const double w = row[c];
      sum[c][std::size_t(b)] += w;
      sum_sq[c][std::size_t(b)] += w * w;
    }
  }
}

void WeightSums::merge(const WeightSums& other) {
  if (negative == 0 && other.negative > 0)
    std::tie(first_negative_row, first_negative) = std::pair(rows + other.first_negative_row, other.first_negative);
  negative += other.negative;
  rows += other.rows;
  for (std::size_t b = 0; b < samples.size(); ++b) samples[b] += other.samples[b];
  for (std::size_t c = 0; c < sum.size(); ++c)
    for (std::size_t b = 0; b < samples.size(); ++b) {
      sum[c][b] += other.sum[c][b];
      sum_sq[c][b] += other.sum_sq[c][b];
    }
}

std::vector<Vec3<double>> refracted_lobe_focus(const DirectionBinning& lobe, const Vec3<double>& wi, double eta) {
  std::vector<Vec3<double>> focus;
  if (eta == 1.0) return focus;
  for (const Vec3<double>& wo : lobe.lattice_directions(4096)) {
    const Vec3<double> m = normalized_or_zero(Vec3<double>(wi + wo));  // the lattice's visible normal
    Vec3<double> t;
    if (refract(wi, m, eta, t)) focus.push_back(t);
  }
  return focus;
}

std::vector<DirectionFunction> dielectric_breaks(const Vec3<double>& wi, double eta) {
  // The refraction lobe ends where its half vector -(wi + eta wo) leaves the horizon or wi's or wo's side.
  const auto raw_half = [wi, eta](const Vec3<double>& o) { return Vec3<double>(-(wi + eta * o)); };
  std::vector<DirectionFunction> breaks = {
      [](const Vec3<double>& o) { return o.z(); },  // reflection above, refraction below
      [raw_half](const Vec3<double>& o) { return o.z() < 0 ? raw_half(o).z() : 1.0; },
      [raw_half, wi](const Vec3<double>& o) { return o.z() < 0 ? wi.dot(raw_half(o)) : 1.0; },
      [raw_half](const Vec3<double>& o) { return o.z() < 0 ? o.dot(raw_half(o)) : -1.0; }};
  if (eta < 1) {  // total internal reflection beyond <wi, m> = cos_c: F has a kink there, 1 - F ends
    const double cos_c = std::sqrt(1 - sqr(eta));
    breaks.push_back([wi, cos_c](const Vec3<double>& o) {
      return o.z() > 0 ? wi.dot(normalized_or_zero(Vec3<double>(wi + o))) - cos_c : 1.0;
    });
    breaks.push_back([wi, cos_c, raw_half](const Vec3<double>& o) {
      return o.z() < 0 ? std::abs(wi.dot(normalized_or_zero(raw_half(o)))) - cos_c : 1.0;
    });
  }
  return breaks;
}

void ExpectedWeights::divide(double s) {
  for (auto* moments : {&mean, &square, &cube})
    for (auto& channel : *moments)
      for (double& e : channel) e /= s;
}

ExpectedWeights expected_bin_weights(const ReferenceDistribution& ref, const Material& bsdf,
                                     const BsdfConvention& convention) {
  IntegrationOptions o;
  o.focus = ref.lobe.lattice_directions(4096);
  if (bsdf.transmits()) {
    const std::vector<Vec3<double>> refracted = refracted_lobe_focus(ref.lobe, ref.wi, bsdf.eta());
    o.focus.insert(o.focus.end(), refracted.begin(), refracted.end());
  }
  o.z_breaks = {0.0, -ref.wi.z()};
  // A dielectric's flux jumps and has kinks where its sampling density does: on those curves the cubature
  // integrates piecewise instead of refining into them: a smaller error in less time (docs/records/validate-all.md).
  if (bsdf.transmits()) o.breaks = dielectric_breaks(ref.wi, bsdf.eta());
  // The second and third moments set a variance and a skewness: 1e-3 relative is plenty (se to 5e-4), and cheaper.
  IntegrationOptions coarse = o;
  coarse.rel_tolerance = 1e-3;
  ExpectedWeights e;
  for (int c = 0; c < bsdf.channels(); ++c) {
    const auto flux = [&](const Vec3<double>& wo) { return bsdf_flux(ref.ggx, bsdf, convention, c, ref.wi, wo); };
    e.mean.push_back(ref.sphere.integrate(flux, o).probability);
    // (f cos)^2 / pdf: the weight times the flux; 0 where the pdf is (no sample lands there).
    const auto square = [&](const Vec3<double>& wo) {
      const double p = ref.returned_pdf(wo), f = flux(wo);
      return p > 0 ? f * f / p : 0.0;
    };
    e.square.push_back(ref.sphere.integrate(square, coarse).probability);
    const auto cube = [&](const Vec3<double>& wo) {  // (f cos)^3 / pdf^2: E[w^3 1_B]'s integrand
      const double p = ref.returned_pdf(wo), f = flux(wo);
      return p > 0 ? f * sqr(f / p) : 0.0;
    };
    e.cube.push_back(ref.sphere.integrate(cube, coarse).probability);
  }
  return e;
}

std::vector<SubTest> weight_checks(const WeightSums& sums, const ExpectedWeights& expected, double n,
                                   const DirectionBinning& sphere, const Material& bsdf, const ValidationOptions& options) {
  return {sign_check(sums), albedo_test(sums, expected, n, bsdf, options), bins_test(sums, expected, n, sphere, bsdf)};
}

std::vector<SubTest> bsdf_weight_tests(const std::filesystem::path& file, const SampleColumns& columns, SampleFrame frame,
                                       const ReferenceDistribution& ref, const Material& bsdf,
                                       const ValidationOptions& options) {
  const auto open = [&] {
    DirectionSampleReader reader(file, columns);
    reader.set_frame(frame);
    return reader;
  };
  return weight_tests_of(open, columns, ref, bsdf, options);
}

std::vector<SubTest> bsdf_weight_tests(const DirectionSampleReader& samples, const ReferenceDistribution& ref,
                                       const Material& bsdf, const ValidationOptions& options) {
  return weight_tests_of([&] { return samples.reopened(); }, samples.columns(), ref, bsdf, options);
}

}  // namespace microsim
