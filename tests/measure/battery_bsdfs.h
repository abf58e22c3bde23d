// tests: BSDFs written in the repository from the math, as BsdfUnderTest for the battery (measure/bsdf_battery.h),
// each with the bugs renderers planted in theirs:
//   - the exact single-scattering conductor and dielectric (microfacet/bsdf.h: Walter et al. 2007 eq. 20-21, the
//     zoo's VNDF samplers of microfacet/bsdf_samplers.h) in either transport mode, a view from inside mirrored
//     to the zoo's view from above with 1 / eta; the conductor anisotropic too, with the bugs of a renderer that
//     swaps the roughnesses, or that turns the view to phi 0 (the isotropic shortcut) and not the roughness;
//   - the Smith multiple-scattering dielectric by the stochastic evaluation of Heitz et al. 2016: sample() the
//     random walk (scatter/smith_walk.h smith_walk_samples), eval() its next-event estimator (smith_walk_eval,
//     a few paths per call: unbiased and noisy), no pdf();
//   - a Kulla-Conty compensated GGX mirror (Kulla & Conty 2017): the single scattering plus the lobe
//     (1 - E(mu_i)) (1 - E(mu_o)) / (pi (1 - E_avg)), E tabulated here on 64 mu by VNDF quadrature (E(mu) =
//     the mean of G2 / G1(wi) over the visible normals), sampled by choosing the lobe with probability
//     1 - E(mu_i) (cosine-weighted) or else a VNDF reflection; pdf the mixture, weight eval / pdf.
#pragma once

#include "measure/bsdf_battery.h"

#include <string>

namespace microsim::test {

enum class PlantedBug {
  none,
  eta2_in_transmission,     // eval()'s refraction f times (n_o / n_i)^2: the transport mode's factor inverted
  no_same_hemisphere_check, // eval() adds the refraction formula on a reflected pair (wo mirrored)
  weight_not_eval_over_pdf, // sample()'s weight: the conductor without G1(wo) (the zoo's cond_no_g1_wo)
  one_lobe_weight,          // Kulla-Conty: the chosen lobe's f cos / pdf as the weight (unbiased, not eval / pdf)
  non_reciprocal_lobe,      // Kulla-Conty: (1 - E(mu_i))^2 for (1 - E(mu_i)) (1 - E(mu_o))
  stale_height,             // the walk keeps its height after a refraction (sample and eval)
  eval_not_sampler_integral,// the walk's eval() of orders 1 and 2 only
  eval_scale,               // eval() times (1 + scale) (the power sweep)
  weight_scale,             // sample()'s weight times (1 + scale) (the power sweep)
  swapped_alphas,           // anisotropic: alpha_x and alpha_y swapped
  unrotated_anisotropy,     // anisotropic: wi turned to phi 0 (wo with it) and the roughness not turned
};
std::string to_string(PlantedBug bug);

struct WorkedBsdf {
  BsdfUnderTest bsdf;
  Material claimed;
  GGX<double> ggx;
  BatteryReference reference;
};

WorkedBsdf exact_conductor(double alpha, PlantedBug bug = PlantedBug::none, double scale = 0);
// An anisotropic GGX conductor (alpha_x, alpha_y).
WorkedBsdf anisotropic_conductor(double alpha_x, double alpha_y, PlantedBug bug = PlantedBug::none);
WorkedBsdf exact_dielectric(double alpha, TransportMode mode, PlantedBug bug = PlantedBug::none, double scale = 0);
// paths_per_eval: the walks of each eval() call; scale: of eval_scale and weight_scale.
WorkedBsdf walk_dielectric(double alpha, PlantedBug bug = PlantedBug::none, int paths_per_eval = 4, double scale = 0);
WorkedBsdf kulla_conty_mirror(double alpha, PlantedBug bug = PlantedBug::none);

}  // namespace microsim::test
