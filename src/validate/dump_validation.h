// validate: a renderer's dump of samples validated against what it claims, with what a user must know to
// act on the verdict. One function for the command line (`validate --from`), Python (`microsim.validate`)
// and experiments: the reference of the claimed density, the weights against the BSDF in the dump's
// convention (transport mode, masking form), and the report's hints (a frame mistake, samples the renderer
// dropped) and notes (what was not checked: the returned pdfs of a dump without a pdf column).
#pragma once

#include "validate/bsdf_validation.h"
#include "validate/validate.h"

#include <memory>
#include <optional>

namespace microsim {

// What a dump claims: the density of its directions, the BSDF whose samples (FilePdf::bsdf) or weights they
// are, and how it holds the samples its sampler lost (a reflection below the horizon, a refraction back up):
// dropped (pbrt-v4: `--above-horizon`), or kept as rows of weight 0 (Mitsuba 3: `--lost-as-zero-weight`,
// counted as failed samples; DirectionSampleReader::set_zero_weight_rows_lost).
struct DumpClaims {
  FilePdf pdf = FilePdf::vndf;
  std::optional<Material> bsdf;
  bool kept_only = false;
  bool zero_weight_lost = false;
};

// Light from inside a dielectric (a view below the surface, wi.z < 0) is validated as its mirror image in z:
// the same BSDF with index 1 / eta seen from outside (Walter et al. 2007 eq. 21 is invariant under a common
// scale of both indices; the transport factor (n_given / n_sampled)^2 too), its rows mirrored
// (DirectionSampleReader::set_mirrored). A view above the surface is kept as it is.
struct ViewFromOutside {
  Vec3<double> wi;
  std::optional<Material> bsdf;
  bool mirrored = false;
};
// std::invalid_argument for a view below the surface without a dielectric BSDF.
ViewFromOutside seen_from_outside(const Vec3<double>& wi, const std::optional<Material>& bsdf);

// The reference of the claimed density: the density itself, or conditioned on the kept samples (a BSDF's
// density: on its own support; a reflection density: on wo.z > 0). std::invalid_argument for FilePdf::bsdf
// without a BSDF, or kept_only with a density of normals or no kept mass.
// Why the weights of `bsdf` in `convention` are not tested ("" when they are): a dielectric drawing D(m) cos
// refracts through normals near the horizon with weights ~ 1 / m.z, a heavy tail whose third moment the weight
// tests' skewed-mean p cannot represent (docs/records/validation.md). Callers name their own option before it.
std::string untested_weights_reason(const Material& bsdf, const BsdfConvention& convention);

// `normals`: how the BSDF of FilePdf::bsdf draws its normals (BsdfConvention::normals).
std::shared_ptr<const ReferenceDistribution> dump_reference(const DumpClaims& claims, const GGX<double>& ggx,
                                                            const Vec3<double>& wi, int rows,
                                                            SampledNormals normals = SampledNormals::visible);

// Validates the samples `samples` reads (from their start) against `reference` (dump_reference of the claims),
// the weights against options.bsdf in options.convention, and adds the report's hints and notes. A frame
// mistake is diagnosed (each common mistake a full validation, ValidationReport::hints) when `diagnose_frame`
// and the samples look like one (looks_like_a_frame_mistake).
ValidationReport validate_dump(const DirectionSampleReader& samples, std::shared_ptr<const ReferenceDistribution> reference,
                               const GGX<double>& ggx, const Vec3<double>& wi, const ValidationOptions& options,
                               bool diagnose_frame);

// A dump's whole validation from the view as the user gave it: a view below the surface (light from inside a
// dielectric) is mirrored (seen_from_outside, the samples' reader set_mirrored), options.bsdf (the weight test,
// when set) is the BSDF so seen, the reference is dump_reference of the claims, and the report keeps the view
// as given. std::invalid_argument for claims that do not fit (a view below the surface without a dielectric,
// kept_only with a density of normals, zero_weight_lost with kept_only or without weight columns).
ValidationReport validate_dump_as_given(DirectionSampleReader& samples, const DumpClaims& claims, const GGX<double>& ggx,
                                        const Vec3<double>& view, ValidationOptions options, bool diagnose_frame);

}  // namespace microsim
