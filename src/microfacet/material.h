// microfacet: what a single microfacet does to the light that reaches it, for the scattering
// measurements (explicit heightfields, src/scatter, and the Smith random walk of Heitz, Hanika, d'Eon,
// Dachsbacher 2016, "Multiple-Scattering Microfacet BSDFs with the Smith Model", SIGGRAPH, section 5).
//
// Conventions (bsdf.h): directions point away from the surface point; the facet normal m points to the
// side the light arrives from (wi . m > 0). The medium above the macrosurface has index 1; a
// dielectric's solid below has the relative index eta. Weights are flux weights: a dielectric's choice
// between reflection and refraction is made with probability F, so R + T = 1 path by path in expectation
// and the histogram of outgoing flux is Walter et al. 2007's BSDF (eq. 21 with its eta_o^2) times cos.
//
// Materials:
//   mirror                         F = 1 (every path keeps weight 1)
//   conductor:ETA,K[;ETA,K...]     exact Fresnel of eta + i k (Born & Wolf 14.2), one weight channel each
//   dielectric:ETA                 reflection or refraction chosen by Fresnel (Walter 2007 eq. 22)
//   lambertian[:ALBEDO]            a two-sided Lambertian facet: cosine-distributed about m on wi's side,
//                                  weight ALBEDO (Heitz et al. 2016, section 5.3, "diffuse" microsurface)
#pragma once

#include "core/math.h"

#include <complex>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace microsim {

enum class MaterialKind { mirror, conductor, dielectric, lambertian };

// A facet material (value type). Build with the named constructors or parse_material(); every
// constructor checks its values (std::invalid_argument naming the bad one).
class Material {
public:
  static constexpr int kMaxChannels = 64;

  static Material mirror();
  // One channel per complex index eta + i k (eta > 0, k >= 0, finite); names default to "c0", "c1", ...
  static Material conductor(std::vector<std::complex<double>> ior, std::vector<std::string> channel_names = {});
  static Material dielectric(double eta);   // eta > 0, finite, != 1
  static Material lambertian(double albedo = 1.0);  // albedo in [0, 1]

  MaterialKind kind() const { return kind_; }
  bool transmits() const { return kind_ == MaterialKind::dielectric; }
  // Weight channels: a conductor's indices; one for every other material.
  int channels() const { return int(names_.size()); }
  const std::string& channel_name(int c) const { return names_[std::size_t(c)]; }
  double eta() const { return eta_; }  // dielectric: n_inside / n_outside; 1 otherwise
  std::complex<double> ior(int c) const { return ior_[std::size_t(c)]; }
  double albedo() const { return albedo_; }
  // The canonical spec ("mirror", "conductor:0.2,3.9;0.5,2.4", "dielectric:1.5", "lambertian:0.8"),
  // parsed back by parse_material to an equal material (names aside).
  std::string describe() const;
  bool operator==(const Material&) const = default;

private:
  MaterialKind kind_ = MaterialKind::mirror;
  std::vector<std::complex<double>> ior_;
  std::vector<std::string> names_{"c0"};
  double eta_ = 1.0, albedo_ = 1.0;
};

// Parses a material spec (see above) with core/parse.h's number rules; throws ParseError naming `what`
// and quoting the bad part (an unknown material, eta <= 0 or not finite, k < 0, more than kMaxChannels).
Material parse_material(std::string_view what, std::string_view text);

// One facet event: the outgoing direction (unit, pointing away from the facet point) and whether it
// crossed the interface (a dielectric's refraction: the path changes side).
struct FacetEvent {
  Vec3<double> wo = Vec3<double>::Zero();
  bool refracted = false;
};

// The event at a facet of normal m (unit, wi . m > 0) for light arriving from wi (unit); `inside` says
// wi is in the dielectric's solid (the relative index is then 1 / eta). u: two uniforms in [0, 1)
// (u.x() chooses reflection or refraction; Lambertian: both draw the cosine direction). factors
// (channels() values) receives each channel's weight factor: conductor F_c(wi . m), Lambertian albedo,
// mirror and dielectric 1.
FacetEvent scatter_on_facet(const Material& material, const Vec3<double>& wi, const Vec3<double>& m, bool inside,
                            const Vec2<double>& u, std::span<double> factors);

}  // namespace microsim
