/* microsim: the C interface a renderer implements around its own BSDF so that `microsim check-bsdf --plugin
 * LIB.so` can test it in process (sample, eval and pdf; no files).
 *
 * Build a shared library that defines microsim_bsdf_plugin_entry() returning a pointer to a static
 * microsim_bsdf_plugin. Directions are unit vectors in the BSDF's local frame (z-up unless `frame` says y-up),
 * pointing away from the surface; wi is the direction the renderer was given (the camera side on camera paths).
 * Values are per channel: `channels` of them, at most MICROSIM_BSDF_MAX_CHANNELS.
 *   create(params):   a BSDF for "key=value key=value" parameters (the --param options); NULL on a bad one.
 *   sample(self, wi, u, wo, pdf, weight): draws wo from the three uniforms u; writes the pdf of wo (per unit
 *                     solid angle; 0 when it is not known, pdf NULL) and weight = f(wi, wo) |cos wo| / pdf per
 *                     channel (the path throughput the sample carries); returns 0 for a lost sample (nothing
 *                     written), 1 otherwise.
 *   eval(self, wi, wo, value): value = f(wi, wo) |cos wo| per channel, 0 where the BSDF is 0.
 *   pdf(self, wi, wo): the density sample() draws wo with, given wi; NULL (ABI 2) when it is not known in
 *                     closed form (a multiple-scattering sampler): the tests that need it are not run.
 *   destroy(self).
 * `transport`: 0 radiance (camera paths: a refraction's f holds (n_given / n_sampled)^2), 1 importance.
 * `masking`: 0 height-correlated G2 (pbrt-v4), 1 separable G1 G1 (Mitsuba 3).
 * `flags` (ABI 2; read only when abi_version >= 2):
 *   MICROSIM_BSDF_STOCHASTIC_EVAL: eval() returns an unbiased random estimate of f |cos wo|, independent from call
 *     to call (the stochastic evaluation of a multiple-scattering BSDF, Heitz et al. 2016 sec. 6). The battery
 *     then averages repeated calls at each query pair (the eval and reciprocity tests, by a chi-square with the
 *     calls' standard error), keeps the noise in the cell integrals' variance (the integral and furnace tests),
 *     does not hold the samples' weights to eval / pdf pointwise, and does not compare eval() with an exact
 *     single-scattering BSDF (use `--reference smith-walk` or `none`). A test of such an eval() that rejects
 *     (integral, eval, reciprocity) runs again on fresh calls, 64 times as many per pair (4 times the points per
 *     cell) with standard errors pooled over the pairs, and rejects only if that second stage rejects too (a
 *     heavy-tailed estimate's error from its own few hundred calls is too small): every call must be a fresh
 *     estimate. eval() is called from one thread; its
 *     random state is the plugin's (seed it in create() for a run that repeats).
 *   MICROSIM_BSDF_NDF_SAMPLING: sample() draws the microfacet normal m from D(m) cos (Walter et al. 2007 eq. 35;
 *     Mitsuba 3's sample_visible = false), not from the visible normals of wi (Heitz 2018); a normal facing away
 *     from wi loses the sample. The samples are then tested against that density. A dielectric's weights under
 *     it are heavy-tailed (~ 1 / m.z near the horizon) and the battery refuses it (test its directions and pdfs
 *     with `microsim validate --from DUMP --sampling ndf`).
 * Versions: ABI 1 is this struct without `flags` (and pdf required); a plugin built against the version-1 header
 * sets abi_version 1 and still loads: the fields after `pdf` are read only from a plugin of version 2 or more. */
#ifndef MICROSIM_BSDF_PLUGIN_H
#define MICROSIM_BSDF_PLUGIN_H

#ifdef __cplusplus
extern "C" {
#endif

#define MICROSIM_BSDF_PLUGIN_ABI 2
#define MICROSIM_BSDF_MAX_CHANNELS 8
#define MICROSIM_BSDF_STOCHASTIC_EVAL 1 /* a bit of `flags` */
#define MICROSIM_BSDF_NDF_SAMPLING 2    /* a bit of `flags` */

typedef struct microsim_bsdf_plugin {
  int abi_version; /* MICROSIM_BSDF_PLUGIN_ABI (1 or 2) */
  const char* name;
  int channels;
  int transport; /* 0 radiance, 1 importance */
  int masking;   /* 0 height-correlated, 1 separable */
  int frame;     /* 0 z-up, 1 y-up */
  void* (*create)(const char* params);
  void (*destroy)(void* self);
  int (*sample)(void* self, const double wi[3], const double u[3], double wo[3], double* pdf, double* weight);
  void (*eval)(void* self, const double wi[3], const double wo[3], double* value);
  double (*pdf)(void* self, const double wi[3], const double wo[3]);
  int flags; /* ABI 2: MICROSIM_BSDF_STOCHASTIC_EVAL, MICROSIM_BSDF_NDF_SAMPLING (or'ed), or 0 */
} microsim_bsdf_plugin;

typedef const microsim_bsdf_plugin* (*microsim_bsdf_plugin_entry_fn)(void);
const microsim_bsdf_plugin* microsim_bsdf_plugin_entry(void);

#ifdef __cplusplus
}
#endif

#endif
