#include "microfacet/bsdf_convention.h"

#include "core/parse.h"

#include <fmt/core.h>

namespace microsim {

std::string to_string(TransportMode mode) { return mode == TransportMode::radiance ? "radiance" : "importance"; }

std::string to_string(MaskingForm form) {
  return form == MaskingForm::height_correlated ? "height-correlated" : "separable";
}

std::string to_string(SampledNormals normals) { return normals == SampledNormals::visible ? "vndf" : "ndf"; }

std::string describe(const BsdfConvention& c) {
  const char* paths = c.transport == TransportMode::radiance ? "camera paths" : "light paths";
  const char* masking = c.masking == MaskingForm::height_correlated ? "height-correlated G2" : "separable G1(wi) G1(wo)";
  return fmt::format("{} transport ({}), {}{}", to_string(c.transport), paths, masking,
                     c.normals == SampledNormals::ndf ? ", normals sampled from D(m) cos (Walter et al. 2007)" : "");
}

TransportMode parse_transport_mode(std::string_view what, std::string_view text) {
  if (text == "radiance") return TransportMode::radiance;
  if (text == "importance") return TransportMode::importance;
  throw ParseError(fmt::format("{} {}: unknown transport mode (valid: radiance for camera paths, importance for "
                               "light paths)",
                               what, quote_excerpt(text)));
}

MaskingForm parse_masking_form(std::string_view what, std::string_view text) {
  if (text == "height-correlated") return MaskingForm::height_correlated;
  if (text == "separable") return MaskingForm::separable;
  throw ParseError(fmt::format("{} {}: unknown masking-shadowing form (valid: height-correlated, separable)", what,
                               quote_excerpt(text)));
}

SampledNormals parse_sampled_normals(std::string_view what, std::string_view text) {
  if (text == "vndf") return SampledNormals::visible;
  if (text == "ndf") return SampledNormals::ndf;
  throw ParseError(fmt::format("{} {}: unknown normal sampling (valid: vndf, the visible normals; ndf, D(m) cos as "
                               "Walter et al. 2007)",
                               what, quote_excerpt(text)));
}

}  // namespace microsim
