// validate: a BSDF sampler of the zoo (microfacet/bsdf_samplers.h) validated as a renderer's sample()
// would be: its outgoing directions against the pdf it claims (chi-square in sphere and
// lobe bins, the returned pdf at each sample, the pdf's integral), and its weights against the analytic
// single-scattering BSDF (weight_test.h: the albedo and the flux per sphere bin), in one report.
// Sample i draws three uniforms from CounterRng(seed, i): the same samples whatever the thread count.
#pragma once

#include "microfacet/bsdf_samplers.h"
#include "validate/validate.h"
#include "validate/weight_test.h"

#include <memory>
#include <optional>
#include <vector>

namespace microsim {

// The material a sampler of the zoo is validated with (bsdf_samplers.h): the zoo's conductor, or its
// glass seen from outside (eta 1.5) or, mirrored, from inside (eta 1 / 1.5).
Material zoo_bsdf_material(const BsdfSamplerInfo& sampler, bool from_inside);

// The cubature's tolerance per bin of a dielectric's sampling density (the kinks of F at total internal
// reflection and the ends of the refraction lobe make it costly): a relative error d per bin moves the
// chi-square statistic of N samples by at most its noncentrality N d^2 = 1e-8 N, 0.01 at 1e6 samples,
// against a statistic of the order of its dof (hundreds). (The BSDF's flux, which the albedo test compares
// with means known to 1e-6, keeps the default 1e-7.) Measured on the --all grid: the total mass moves by
// at most 1e-7 from 1e-5 to 1e-4, the cubature's time 52 -> 24 s summed over the 27 references.
inline constexpr double kDielectricDensityRelTolerance = 1e-4;

// The claimed density of sampling `bsdf` as the zoo's correct sampler of its kind does (conductor and mirror:
// conductor_vndf_pdf; dielectric: dielectric_vndf_pdf with its eta), with the refracted lobe as focus; with
// `normals` ndf, the same with the normals drawn from D(m) cos (conductor_ / dielectric_sampling_pdf).
ClaimedDensity bsdf_sampling_density(const Material& bsdf, const GGX<double>& ggx, const Vec3<double>& wi,
                                     SampledNormals normals = SampledNormals::visible);

// The density a file of samples claims (`validate --from --pdf`): claimed_density(pdf), or for FilePdf::bsdf
// the sampling density of `bsdf` (bsdf_sampling_density, its normals drawn as `normals` says).
// std::invalid_argument for FilePdf::bsdf without a BSDF.
ClaimedDensity file_claimed_density(FilePdf pdf, const std::optional<Material>& bsdf, const GGX<double>& ggx,
                                    const Vec3<double>& wi, SampledNormals normals = SampledNormals::visible);

// What the validations of one configuration and material share (expensive: cubature of the claimed pdf
// over two binnings and of the BSDF's flux over the sphere bins).
struct BsdfReference {
  std::shared_ptr<const ReferenceDistribution> directions;
  ExpectedWeights flux;  // a sample's expected w, w^2, w^3 per channel and sphere bin, in `convention`
  BsdfConvention convention;
};
BsdfReference bsdf_reference(const Material& bsdf, const BsdfConvention& convention, const GGX<double>& ggx,
                             const Vec3<double>& wi, int rows);
// The flux in `convention` over the binnings of sampling directions already computed (shared by conventions).
BsdfReference bsdf_reference(std::shared_ptr<const ReferenceDistribution> directions, const Material& bsdf,
                             const BsdfConvention& convention);

// Draws options.samples samples of `sampler` for `bsdf` (float64; options.precision is ignored) and
// validates them, the weights in options.convention (the zoo's: the sampler's own, sampler.convention); the
// report's checks hold "bsdf_albedo" and "bsdf_bins". A reference must be in that convention
// (std::invalid_argument otherwise). Throws InsufficientData before
// drawing when options.samples is too few, std::invalid_argument for a material of another kind.
ValidationReport validate_bsdf_sampler(const BsdfSamplerInfo& sampler, const Material& bsdf, const GGX<double>& ggx,
                                       const Vec3<double>& wi, const ValidationOptions& options,
                                       const BsdfReference* reference = nullptr);

}  // namespace microsim
