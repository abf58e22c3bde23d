// scatter: the analytic single-scattering reference, binned like a measurement.
//
// Single scattering on the Smith microsurface (GGX or Beckmann) is the BSDF f of microfacet/bsdf.h (Walter,
// Marschner, Li, Torrance 2007, "Microfacet Models for Refraction through Rough Surfaces", EGSR, eq. 20-21,
// with the height-correlated masking-shadowing of Heitz 2014, JCGT 3(2), eq. 99): mirror (F = 1), conductor
// (exact Fresnel per channel, Born & Wolf 14.2) and dielectric (reflection and refraction, from either
// side; the refraction lobe with the Smith microsurface's own masking of a refracted pair, transmission_G2,
// dielectric_bsdf_smith: what order 1 of the Smith random walk of Heitz et al. 2016 is; Walter's reflection
// form of G2 in the BTDF differs from it at grazing angles). A path arriving along -wi leaves after one
// facet event into dwo with the flux f(wi, wo) |cos o|
// dwo (for the dielectric, Walter's eq. 21 with its eta_o^2 is the radiance BTDF whose f |cos o| is the
// transmitted flux; material.h), so the expected weight per launched path of order 1 in a bin is
//   E_bin = integral over the bin of f(wi, wo) |cos o| dwo,
// computed by adaptive cubature over the hemispheres binning (DirectionBinning::integrate), the equator a
// bin edge. Narrow lobes are found by focus points: the reflections (and refractions) of a lattice of
// visible normals (Heitz 2018's sampler for GGX, the exact Beckmann sampler) about wi.
// The sum over the bins is the single-scattering albedo E(wi); for a mirror GGX surface at alpha 1 it is
// 0.307 at normal incidence and 0.451 at mu = 0.5 (published values;
// tests/scatter/test_analytic_scatter.cpp checks them and an independent quadrature).
#pragma once

#include "core/math.h"
#include "core/run_control.h"
#include "microfacet/beckmann.h"
#include "microfacet/ggx.h"
#include "microfacet/material.h"
#include "stats/scatter_expectation.h"

#include <string>

namespace microsim {

// f(wi, wo) |cos o| of one channel: the single-scattering flux per unit solid angle of wo. 0 where the
// material does not send light (below the horizon of an opaque material, wi from below on one).
// Throws std::invalid_argument for a Lambertian facet material (its single scattering has no closed form).
double single_scattering_flux(const GGX<double>& ggx, const Material& material, int channel, const Vec3<double>& wi,
                              const Vec3<double>& wo);
double single_scattering_flux(const Beckmann<double>& beckmann, const Material& material, int channel,
                              const Vec3<double>& wi, const Vec3<double>& wo);

// The canonical measurement string of an analytic run ("analytic ggx alpha AX,AY wi X,Y,Z material M rows R").
std::string analytic_measurement(const GGX<double>& ggx, const Vec3<double>& wi, const Material& material,
                                 int rows_per_hemisphere);
std::string analytic_measurement(const Beckmann<double>& beckmann, const Vec3<double>& wi, const Material& material,
                                 int rows_per_hemisphere);

// The expected order-1 weight per launched path of every bin of the hemispheres binning of
// rows_per_hemisphere rows per hemisphere, per channel of the material, for light arriving along -wi
// (unit; wi.z < 0: from inside a dielectric). producer "scatter analytic". Throws std::invalid_argument
// naming the bad value (a Lambertian material, wi not a unit direction off the horizon, wi from below on
// an opaque material, rows outside [1, kMaxBinningRows / 2]); Cancelled when run.cancel is set (checked
// before and after each channel's cubature). run.threads bounds the cubature's threads.
ScatterExpectation analytic_single_scattering(const GGX<double>& ggx, const Vec3<double>& wi, const Material& material,
                                              int rows_per_hemisphere, const RunControl& run = {});
ScatterExpectation analytic_single_scattering(const Beckmann<double>& beckmann, const Vec3<double>& wi,
                                              const Material& material, int rows_per_hemisphere, const RunControl& run = {});

}  // namespace microsim
