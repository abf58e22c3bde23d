// microfacet: the conventions a renderer's BSDF is written in, which a validation of its dumps must name.
//
// Transport mode (Veach 1997, thesis section 5.2; Walter et al. 2007 eq. 21 and its eta_o^2): a renderer
// samples an outgoing direction from a given one. Camera paths carry radiance: light flows from the sampled
// direction to the given one, and a refraction's weight holds (n_given / n_sampled)^2 (pbrt-v4
// DielectricBxDF in TransportMode::Radiance, Mitsuba 3 roughdielectric in TransportMode::Radiance). Light
// paths carry importance: light flows from the given direction to the sampled one, and the weight has no
// such factor. Reflection is the same in both.
//
// Masking-shadowing form: Smith's height-correlated G2 = 1 / (1 + Lambda_i + Lambda_o) (Heitz 2014 eq. 99;
// pbrt-v4's TrowbridgeReitzDistribution::G) or the separable G1(wi) G1(wo) (Heitz 2014 eq. 98; Mitsuba 3's
// MicrofacetDistribution::G), for both the reflection and the refraction lobe.
//
// Sampled normals: the microfacet normal a BSDF's sample() draws, from the visible normals D_v(wi, m) (Heitz 2018,
// JCGT 7(4); pbrt-v4, Mitsuba 3 by default) or from D(m) <m, n> (Walter et al. 2007 eq. 38: Mitsuba 3's
// sample_visible = false, older renderers). It sets the density of the sampled directions, not the BSDF.
#pragma once

#include <string>
#include <string_view>

namespace microsim {

enum class TransportMode { radiance, importance };
enum class MaskingForm { height_correlated, separable };
enum class SampledNormals { visible, ndf };

struct BsdfConvention {
  TransportMode transport = TransportMode::radiance;      // camera paths: what renderers mostly dump
  MaskingForm masking = MaskingForm::height_correlated;  // Smith's own form
  SampledNormals normals = SampledNormals::visible;       // what sample() draws m from
  bool operator==(const BsdfConvention&) const = default;
};

std::string to_string(TransportMode mode);   // "radiance", "importance"
std::string to_string(MaskingForm form);     // "height-correlated", "separable"
std::string to_string(SampledNormals normals);  // "vndf", "ndf"
// "radiance transport (camera paths), height-correlated G2": how a report names the convention.
std::string describe(const BsdfConvention& convention);
// Parse the names above; throw ParseError naming `what`, the bad token and the valid names.
TransportMode parse_transport_mode(std::string_view what, std::string_view text);
MaskingForm parse_masking_form(std::string_view what, std::string_view text);
SampledNormals parse_sampled_normals(std::string_view what, std::string_view text);

}  // namespace microsim
