// validate: the weights of a BSDF sampler, tested against the BSDF (issue 11, point 4).
//
// A renderer's sample() returns a direction wo with the weight w = f(wi, wo) cos(wo) / pdf(wo). Whatever
// pdf drew wo, E[w 1_B(wo)] = the integral over B of f(wi, wo) cos(wo) dwo (the estimator is unbiased), so
// the mean weight per sample in a bin B of the sphere binning must equal the BSDF's single-scattering flux
// into B, and the mean weight over all samples the directional albedo: tests of the weights alone,
// independent of how the directions were drawn. Each is a z-score with the samples' own variance of
// w 1_B (per channel); the albedo test takes the channels' smallest p, the bin test the smallest p over
// the bins with at least kMinWeightBinSamples samples and the channels, each Sidak-corrected. They catch
// a weight without G1(wo), a wrong Fresnel, a wrong Jacobian, a roughness squared twice, even when the
// directions are right. Reflected directions of a mirror or conductor BSDF (microfacet/bsdf.h:
// mirror_brdf, conductor_brdf, Walter et al. 2007 eq. 20 with the height-correlated G2 of Heitz 2014
// eq. 99); the flux integrals by the binning's adaptive cubature.
#pragma once

#include "microfacet/material.h"
#include "validate/sample_io.h"
#include "validate/validate.h"

#include <filesystem>
#include <vector>

namespace microsim {

inline constexpr std::uint64_t kMinWeightBinSamples = 30;

// The samples of a file, read again with its columns and frame, and their weights (one column per channel
// of `bsdf`) against the BSDF: the statistical checks "bsdf_albedo" and "bsdf_bins". The mean is over the
// file's rows plus options.dropped_below_horizon (dropped samples weigh 0); a reference conditioned on the
// upper hemisphere without that count divides the expectations by its kept mass. Throws
// std::invalid_argument for normals, a Lambertian or dielectric BSDF (not yet), or weight columns that do
// not match the BSDF's channels.
std::vector<SubTest> bsdf_weight_tests(const std::filesystem::path& file, const SampleColumns& columns, SampleFrame frame,
                                       const ReferenceDistribution& reference, const Material& bsdf,
                                       const ValidationOptions& options);

}  // namespace microsim
