// microsim: the sampler zoo. Every sampler is a pure function of (ggx, wi, u) that returns a direction
// and the pdf it claims for it, computed from its own intermediate quantities (so that the validator can
// compare the returned pdf with the analytic one); nullopt when there is nothing to sample.
//
// Conventions (shared by all samplers, documented in README and docs/reference/conventions.md):
// - wi is the unit view direction, pointing away from the surface, z-up.
// - Views below the horizon (wi.z < 0) see the microsurface from its back side: a sampler returns the
//   sample for -wi, negated (normals in the lower hemisphere), as a dielectric BSDF needs. The claimed
//   pdfs follow the same rule (GGX::visible_normal_pdf(w, m) = visible_normal_pdf(-w, -m)).
// - wi.z == 0 (exactly grazing) is allowed: the VNDF is well defined there.
// - alpha below 1e-4 is clamped to 1e-4 (GGX's constructor).
// - u is clamped to [0, 1 - eps/2] per component, so u == 1 behaves as the largest float below 1.
// - A non-finite wi returns nullopt.
#pragma once

#include "microfacet/ggx.h"

#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace microsim {

template <class T> struct DirectionSample {
  Vec3<T> direction;  // a microfacet normal, or a reflected direction (see SampleDomain)
  T pdf;              // the pdf the sampler claims for it, per unit solid angle of `direction`
};

template <class T> using SampleResult = std::optional<DirectionSample<T>>;

// Walter et al. 2007, "Microfacet Models for Refraction through Rough Surfaces", EGSR, eq. 35-36
// (anisotropic form via the stretched slope distribution): samples m with density D(m) m.z.
template <class T> SampleResult<T> sample_ndf(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u);

// Heitz & d'Eon 2014, "Importance Sampling Microfacet-Based BSDFs using the Distribution of Visible
// Normals", EGSR, sec. 4 and appendix: stretch, sample visible slopes of the alpha = 1 configuration
// (x by exact inversion of its marginal CDF, y by exact inversion of its conditional CDF), rotate,
// unstretch. Samples D_v(m).
template <class T> SampleResult<T> sample_heitz2014(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u);

// Heitz 2018, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4), sec. 3-4: transform the
// view to the hemisphere configuration, sample the projected hemisphere by a warped disk, transform
// the normal back. Samples D_v(m).
template <class T> SampleResult<T> sample_heitz2018(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u);

// NEGATIVE CONTROL. The Heitz 2018 listing as the 2018 talk's slide printed it: orthonormal-basis
// fallback (0, 0, 1), t1 = r sin(phi), t2 = r cos(phi), s = 0.5 + (1 + Vh.z), and N_hat read as the
// surface normal (0, 0, 1) instead of Vh. It is wrong; every validation must reject it.
template <class T> SampleResult<T> sample_heitz2018_talk(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u);

// Dupuy & Benyoub 2023, "Sampling Visible GGX Normals with Spherical Caps", CGF 42(8) (HPG), sec. 3:
// in the hemisphere configuration, the visible normal is the half vector between Vh and a direction
// uniform on the spherical cap z >= -Vh.z. Same pdf as Heitz 2018, different warp. Samples D_v(m).
template <class T> SampleResult<T> sample_dupuy2023(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u);

// Eto & Tokuyoshi 2023, "Bounded VNDF Sampling for Smith-GGX Reflections", SIGGRAPH Asia Technical
// Communications, sec. 3: the spherical cap of Dupuy & Benyoub shrunk to z >= -k Vh.z, which drops
// only half vectors whose reflection goes below the horizon. Samples the REFLECTED direction; its pdf
// is D(m) / (2 (k wi.z + t)) over the reflected direction (eq. 5), inside the cap.
template <class T> SampleResult<T> sample_bounded2023(const GGX<T>& ggx, const Vec3<T>& wi, Vec2<T> u);

// The pdf the bounded sampler claims for the reflected direction wo (0 outside its cap).
template <class T> T bounded2023_reflection_pdf(const GGX<T>& ggx, const Vec3<T>& wi, const Vec3<T>& wo);

// The k of Eto & Tokuyoshi 2023 eq. 4 (with a = min(ax, ay) clamped to 1 for anisotropy, sec. 3.3).
template <class T> T bounded2023_k(const GGX<T>& ggx, const Vec3<T>& wi);

// ---- the registry: samplers by name, for the validator and the command line ----------------------------

enum class SampleDomain {
  microfacet_normal,    // samples are microfacet normals m; analytic reference: D_v(wi, m)
  reflected_direction,  // samples are reflected directions wo; reference: the pdf over wo
};

// Which density a sampler claims (its claimed_pdf): samplers that claim the same one share a reference.
enum class ClaimedPdf {
  visible_normals,     // D_v(wi, m) (GGX::visible_normal_pdf): the traced oracle can validate it
  ndf_cosine,          // D(m) m.z (Walter et al. 2007)
  bounded_reflection,  // bounded2023_reflection_pdf over the reflected direction
};

// Where the pdf a sampler returns can be checked against its claimed pdf (stability.h).
enum class ReturnedPdfCheck {
  everywhere,
  // Not at reflected directions within 2^-20 of -wi outside the moderate regime: there the half vector
  // of two nearly opposite directions cancels and the claimed pdf cannot be evaluated reliably.
  except_near_back_reflection,
};

struct SamplerInfo {
  std::string_view name;
  std::string_view description;
  SampleDomain domain;
  bool negative_control;  // known to be wrong: validation must reject it
  ClaimedPdf claims;      // the density it claims to sample
  // The trusted sampler of the density it claims (one per ClaimedPdf, never a negative control): other
  // tests take their normals from it (reference_sampler).
  bool reference;
  ReturnedPdfCheck returned_pdf_check;
  SampleResult<float> (*sample_float)(const GGX<float>&, const Vec3<float>&, Vec2<float>);
  SampleResult<double> (*sample_double)(const GGX<double>&, const Vec3<double>&, Vec2<double>);
  // The density this sampler claims, analytic, per unit solid angle of the sample's direction.
  double (*claimed_pdf)(const GGX<double>&, const Vec3<double>& wi, const Vec3<double>& direction);
  // A function of the direction that is zero on a curve where the claimed pdf jumps, beyond the curves
  // where every pdf of the zoo jumps or kinks (validate.h, prepare_reference); nullptr: none.
  double (*claimed_pdf_jump)(const GGX<double>&, const Vec3<double>& wi, const Vec3<double>& direction);
};

std::span<const SamplerInfo> sampler_registry();
// nullptr when no sampler has that name.
const SamplerInfo* find_sampler(std::string_view name);
// The sampler of the registry whose `reference` trait is set for that density (std::logic_error if none).
const SamplerInfo& reference_sampler(ClaimedPdf claims);
std::vector<std::string> sampler_names();

}  // namespace microsim

#include "microfacet/samplers_impl.h"
