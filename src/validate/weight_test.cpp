#include "validate/weight_test.h"

#include "microfacet/bsdf.h"
#include "stats/chi2.h"
#include "stats/direction_binner.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>

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

// Two-sided p of z (0 for a non-finite z: NaN weights reject).
double two_sided_p(double z) { return std::isfinite(z) ? std::erfc(std::abs(z) / std::sqrt(2.0)) : 0.0; }

// z of a mean weight: (sum / n - expected) / its standard error from the sums (with a floor of 1e-12
// relative for rounding).
double mean_z(double sum, double sum_sq, double n, double expected) {
  const double mean = sum / n, var = std::max(sum_sq / n - mean * mean, 0.0);
  const double se = std::sqrt(var / n + 1e-24 * expected * expected);
  return se > 0 ? (mean - expected) / se : (mean == expected ? 0.0 : INFINITY);
}

// The mean weight per channel against the albedo (the sum of the expected bin weights `e`, already scaled).
SubTest albedo_test(const WeightSums& s, const std::vector<std::vector<double>>& e, double n, const Material& bsdf,
                    const ValidationOptions& options) {
  double p_min = 1;
  std::vector<double> albedo, measured;
  for (std::size_t c = 0; c < e.size(); ++c) {
    double sum = 0, sum_sq = 0, total = 0;
    for (std::size_t b = 0; b < e[c].size(); ++b) {
      sum += s.sum[c][b];
      sum_sq += s.sum_sq[c][b];
      total += e[c][b];
    }
    albedo.push_back(total);
    measured.push_back(sum / n);
    p_min = std::min(p_min, two_sided_p(mean_z(sum, sum_sq, n, total)));
  }
  SubTest t;
  t.name = "bsdf_albedo";
  t.label = "BSDF albedo (mean weight)";
  t.statistical = true;
  t.p_value = sidak_adjusted_p(p_min, int(e.size()));
  t.value = measured.front();
  t.tolerance = albedo.front();
  const std::string dropped =
      options.dropped_below_horizon ? fmt::format(" + {} dropped", *options.dropped_below_horizon) : "";
  t.detail = fmt::format("mean weight {:.6g} vs the BSDF's directional albedo {:.6g} ({}, {}; {} samples{})",
                         measured.front(), albedo.front(), bsdf.describe(), describe(options.convention), s.rows, dropped);
  return t;
}

// The mean weight per bin (with at least kMinWeightBinSamples samples) and channel against the flux.
SubTest bins_test(const WeightSums& s, const std::vector<std::vector<double>>& e, double n, const DirectionBinning& sphere,
                  const Material& bsdf) {
  double worst_z = 0;
  int tested = 0;
  std::string worst;
  for (std::size_t c = 0; c < e.size(); ++c)
    for (std::size_t b = 0; b < e[c].size(); ++b) {
      if (s.samples[b] < kMinWeightBinSamples) continue;
      ++tested;
      const double z = mean_z(s.sum[c][b], s.sum_sq[c][b], n, e[c][b]);
      if (std::isnan(worst_z) || std::abs(z) <= std::abs(worst_z)) continue;  // a NaN weight stays the worst
      worst_z = z;
      worst = fmt::format("{} ({}): mean weight {:.4g} vs flux {:.4g}", sphere.describe_bin(int(b)),
                          bsdf.channel_name(int(c)), s.sum[c][b] / n, e[c][b]);
    }
  SubTest t;
  t.name = "bsdf_bins";
  t.label = "BSDF flux per bin (mean weight)";
  t.applicable = t.statistical = tested > 0;
  t.p_value = tested > 0 ? sidak_adjusted_p(two_sided_p(worst_z), tested) : 1.0;
  t.value = worst_z;
  t.detail = tested > 0 ? fmt::format("{} bin-channels with >= {} samples; worst z = {:.2f} at {}", tested,
                                      kMinWeightBinSamples, worst_z, worst)
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

// The sums of the weights of the samples `reader` reads, block by block.
WeightSums sum_weights(DirectionSampleReader& reader, const DirectionBinning& sphere, int channels) {
  const FastDirectionBinner binner(sphere);
  WeightSums s(channels, sphere.size());
  std::vector<Vec3<double>> rows(kSampleFileBlock);
  std::vector<double> pdfs(reader.columns().has_pdf() ? rows.size() : 0), weights(rows.size() * std::size_t(channels));
  while (const std::size_t n = reader.read(rows, pdfs, weights)) s.add(binner, rows, weights, n);
  return s;
}

// The weight tests of the samples `open()` reads (opened once the inputs are checked).
std::vector<SubTest> weight_tests_of(const std::function<DirectionSampleReader()>& open, const SampleColumns& columns,
                                     const ReferenceDistribution& ref, const Material& bsdf,
                                     const ValidationOptions& options) {
  check_weight_inputs(columns, ref, bsdf);
  std::vector<std::vector<double>> expected = expected_bin_weights(ref, bsdf, options.convention);
  // Conditioned on the kept samples without the dropped count: the kept samples' mean weight.
  if (ref.kept_only && !options.dropped_below_horizon)
    for (auto& channel : expected)
      for (double& e : channel) e /= ref.kept_mass;
  DirectionSampleReader reader = open();
  const WeightSums s = sum_weights(reader, ref.sphere, bsdf.channels());
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
    const int b = binner(directions[i]);
    if (b < 0) continue;
    ++samples[std::size_t(b)];
    for (std::size_t c = 0; c < channels; ++c) {
      const double w = weights[i * channels + c];
      sum[c][std::size_t(b)] += w;
      sum_sq[c][std::size_t(b)] += w * w;
    }
  }
}

void WeightSums::merge(const WeightSums& other) {
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

std::vector<std::vector<double>> expected_bin_weights(const ReferenceDistribution& ref, const Material& bsdf,
                                                      const BsdfConvention& convention) {
  IntegrationOptions o;
  o.focus = ref.lobe.lattice_directions(4096);
  if (bsdf.transmits()) {
    const std::vector<Vec3<double>> refracted = refracted_lobe_focus(ref.lobe, ref.wi, bsdf.eta());
    o.focus.insert(o.focus.end(), refracted.begin(), refracted.end());
  }
  o.z_breaks = {0.0, -ref.wi.z()};
  std::vector<std::vector<double>> e;
  for (int c = 0; c < bsdf.channels(); ++c)
    e.push_back(
        ref.sphere.integrate([&](const Vec3<double>& wo) { return bsdf_flux(ref.ggx, bsdf, convention, c, ref.wi, wo); }, o)
            .probability);
  return e;
}

std::vector<SubTest> weight_checks(const WeightSums& sums, const std::vector<std::vector<double>>& expected, double n,
                                   const DirectionBinning& sphere, const Material& bsdf, const ValidationOptions& options) {
  return {albedo_test(sums, expected, n, bsdf, options), bins_test(sums, expected, n, sphere, bsdf)};
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
