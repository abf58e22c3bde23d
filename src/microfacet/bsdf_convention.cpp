#include "microfacet/bsdf_convention.h"

#include "core/parse.h"

#include <fmt/core.h>

#include <utility>

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

namespace {
// A convention's two names, the first for `first` and the second for `second`; else a ParseError naming `what`, the
// bad token, the kind of convention and the valid names (`valid`).
template <class E>
E parse_either(std::string_view what, std::string_view text, std::string_view kind, std::string_view valid,
               std::pair<std::string_view, E> first, std::pair<std::string_view, E> second) {
  if (text == first.first) return first.second;
  if (text == second.first) return second.second;
  throw ParseError(fmt::format("{} {}: unknown {} (valid: {})", what, quote_excerpt(text), kind, valid));
}
}  // namespace

TransportMode parse_transport_mode(std::string_view what, std::string_view text) {
  return parse_either(what, text, "transport mode", "radiance for camera paths, importance for light paths",
                      std::pair{std::string_view("radiance"), TransportMode::radiance},
                      std::pair{std::string_view("importance"), TransportMode::importance});
}

MaskingForm parse_masking_form(std::string_view what, std::string_view text) {
  return parse_either(what, text, "masking-shadowing form", "height-correlated, separable",
                      std::pair{std::string_view("height-correlated"), MaskingForm::height_correlated},
                      std::pair{std::string_view("separable"), MaskingForm::separable});
}

SampledNormals parse_sampled_normals(std::string_view what, std::string_view text) {
  return parse_either(what, text, "normal sampling", "vndf, the visible normals; ndf, D(m) cos as Walter et al. 2007",
                      std::pair{std::string_view("vndf"), SampledNormals::visible},
                      std::pair{std::string_view("ndf"), SampledNormals::ndf});
}

}  // namespace microsim
