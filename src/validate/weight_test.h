// validate: the weights of a BSDF sampler, tested against the BSDF.
//
// A renderer's sample() returns a direction wo with the weight w = f(wi, wo) cos(wo) / pdf(wo). Whatever
// pdf drew wo, E[w 1_B(wo)] = the integral over B of f(wi, wo) cos(wo) dwo (the estimator is unbiased), so
// the mean weight per sample in a bin B of the sphere binning must equal the BSDF's single-scattering flux
// into B, and the mean weight over all samples the directional albedo. Each is a z-score whose variance
// is the one w 1_B has under the reference (directions drawn from its pdf, weights f cos / returned pdf:
// E[w^2 1_B] - E[w 1_B]^2), not the samples' own: a few huge weights (fireflies) would inflate the
// samples' variance with the mean and pass at z ~ sqrt(their count), and bins that come out low would get
// too small a variance. Its p comes from the mean's skewness under the reference too (E[w^3 1_B]): a bin
// that few samples reach holds a skewed sum. The albedo test takes the channels' smallest p, the bin test
// the smallest p over the bins with at least kMinWeightBinSamples samples and the channels, each
// Sidak-corrected. They catch
// a weight without G1(wo), a wrong Fresnel, a wrong Jacobian, a roughness squared twice, even when the
// directions are right. Reflected directions of a mirror or conductor BSDF (microfacet/bsdf.h:
// mirror_brdf, conductor_brdf, Walter et al. 2007 eq. 20), and both lobes of the rough dielectric
// (dielectric_bsdf_as), in the renderer's convention (ValidationOptions::convention: transport mode and
// masking form); the flux integrals by the binning's adaptive cubature.
#pragma once

#include "microfacet/material.h"
#include "validate/sample_io.h"
#include "validate/validate.h"
#include "stats/direction_binner.h"

#include <filesystem>
#include <span>
#include <vector>

namespace microsim {

inline constexpr std::uint64_t kMinWeightBinSamples = 30;

// Per sphere bin and channel: the sums of the weights and of their squares, and the samples per bin.
// Blocks of samples are summed into their own WeightSums and merged in block order (thread-count
// independent).
struct WeightSums {
  std::vector<std::vector<double>> sum, sum_sq;  // [channel][bin]
  std::vector<std::uint64_t> samples;            // per bin
  std::uint64_t rows = 0;                        // every sample given, lost ones included
  std::uint64_t negative = 0;                    // samples with a negative weight in some channel
  std::uint64_t first_negative_row = 0;          // the first one's 1-based index among the rows
  double first_negative = 0;                     // and its weight
  WeightSums(int channels, int bins);
  // n directions with their weights (channels per row, row-major); a non-finite direction or one outside
  // the binning weighs nothing but counts in rows.
  void add(const FastDirectionBinner& binner, std::span<const Vec3<double>> directions, std::span<const double> weights,
           std::size_t n);
  void merge(const WeightSums& other);
};

// Where a dielectric's refracted lobe has mass: the lobe binning's lattice of visible normals refracted
// (the refraction of wi about each normal into eta). Empty for eta == 1.
std::vector<Vec3<double>> refracted_lobe_focus(const DirectionBinning& lobe, const Vec3<double>& wi, double eta);

// Where a dielectric's sampling density jumps or has kinks, as functions whose zero sets are those curves
// (IntegrationOptions::breaks): the horizon, the ends of the refraction lobe (its half vector
// -(wi + eta wo) leaving the horizon or either direction's side) and, for eta < 1, total internal
// reflection (<wi, m> = sqrt(1 - eta^2), where F has a kink and 1 - F ends).
std::vector<DirectionFunction> dielectric_breaks(const Vec3<double>& wi, double eta);

// What one sample contributes on average to a sphere bin B under the reference, per channel: E[w 1_B], the
// integral of f(wi, wo) |wo.z| over B (the BSDF's flux), E[w^2 1_B] and E[w^3 1_B], the integrals of
// (f |wo.z|)^j / pdf^(j-1) (w = f |wo.z| / pdf, the returned pdf).
struct ExpectedWeights {
  std::vector<std::vector<double>> mean, square, cube;  // [channel][bin]
  void divide(double s);  // all three, by s (a reference conditioned on its kept mass)
};

// The expected weights in every sphere bin of `ref`, per channel of `bsdf`, f in the renderer's `convention`
// (transport mode, masking form: bsdf_convention.h) (mirror, conductor: reflected directions; dielectric:
// reflection and refraction over the whole sphere, the cubature focused on the refracted lobe too).
ExpectedWeights expected_bin_weights(const ReferenceDistribution& ref, const Material& bsdf,
                                     const BsdfConvention& convention);

// The checks "bsdf_weight_sign" (no weight is negative: f >= 0, pdf > 0), "bsdf_albedo" and "bsdf_bins" of
// sums over n samples (lost ones weigh 0) against `expected`.
std::vector<SubTest> weight_checks(const WeightSums& sums, const ExpectedWeights& expected, double n,
                                   const DirectionBinning& sphere, const Material& bsdf, const ValidationOptions& options);

// The samples of a file, read again with its columns and frame, and their weights (one column per channel
// of `bsdf`) against the BSDF: the statistical checks "bsdf_albedo" and "bsdf_bins". The mean is over the
// file's rows plus options.dropped_below_horizon (dropped samples weigh 0); a reference conditioned on the
// upper hemisphere without that count divides the expectations by its kept mass. Throws
// std::invalid_argument for normals, a Lambertian BSDF, or weight columns that do not match the BSDF's
// channels.
std::vector<SubTest> bsdf_weight_tests(const std::filesystem::path& file, const SampleColumns& columns, SampleFrame frame,
                                       const ReferenceDistribution& reference, const Material& bsdf,
                                       const ValidationOptions& options);
// The same for the samples of `samples` (a file or an array), read again from their start (reopened()).
std::vector<SubTest> bsdf_weight_tests(const DirectionSampleReader& samples, const ReferenceDistribution& reference,
                                       const Material& bsdf, const ValidationOptions& options);

}  // namespace microsim
