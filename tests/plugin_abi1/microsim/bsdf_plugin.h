/* tests: include/microsim/bsdf_plugin.h as it was at ABI version 1 (no flags; pdf required), kept verbatim so
 * that a plugin built against it is a test that `check-bsdf` still loads what was built against the old header. */
/* microsim: the C interface a renderer implements around its own BSDF so that `microsim check-bsdf --plugin
 * LIB.so` can test it in process (sample, eval and pdf; no files).
 *
 * Build a shared library that defines microsim_bsdf_plugin_entry() returning a pointer to a static
 * microsim_bsdf_plugin. Directions are unit vectors in the BSDF's local frame (z-up unless `frame` says y-up),
 * pointing away from the surface; wi is the direction the renderer was given (the camera side on camera paths).
 * Values are per channel: `channels` of them, at most MICROSIM_BSDF_MAX_CHANNELS.
 *   create(params):   a BSDF for "key=value key=value" parameters (the --param options); NULL on a bad one.
 *   sample(self, wi, u, wo, pdf, weight): draws wo from the three uniforms u; writes the pdf of wo (per unit
 *                     solid angle) and weight = f(wi, wo) |cos wo| / pdf per channel; returns 0 for a lost
 *                     sample (nothing written), 1 otherwise.
 *   eval(self, wi, wo, value): value = f(wi, wo) |cos wo| per channel, 0 where the BSDF is 0.
 *   pdf(self, wi, wo): the density sample() draws wo with, given wi.
 *   destroy(self).
 * `transport`: 0 radiance (camera paths: a refraction's f holds (n_given / n_sampled)^2), 1 importance.
 * `masking`: 0 height-correlated G2 (pbrt-v4), 1 separable G1 G1 (Mitsuba 3). */
#ifndef MICROSIM_BSDF_PLUGIN_H
#define MICROSIM_BSDF_PLUGIN_H

#ifdef __cplusplus
extern "C" {
#endif

#define MICROSIM_BSDF_PLUGIN_ABI 1
#define MICROSIM_BSDF_MAX_CHANNELS 8

typedef struct microsim_bsdf_plugin {
  int abi_version; /* MICROSIM_BSDF_PLUGIN_ABI */
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
} microsim_bsdf_plugin;

typedef const microsim_bsdf_plugin* (*microsim_bsdf_plugin_entry_fn)(void);
const microsim_bsdf_plugin* microsim_bsdf_plugin_entry(void);

#ifdef __cplusplus
}
#endif

#endif
