/* A multiple-scattering BSDF wrapped for `microsim check-bsdf --plugin` (include/microsim/bsdf_plugin.h, ABI 2):
 * the GGX conductor with every order of scattering on the Smith microsurface, by the stochastic evaluation of
 * Heitz et al. 2016 ("Multiple-Scattering Microfacet BSDFs with the Smith Model"), written from the math.
 * Parameters: alpha=A (or alpha_x=AX alpha_y=AY), eta=ETA k=K (the conductor's complex index; eta=0: a perfect
 * mirror, F = 1), paths=N (walks averaged per eval() call, default 4), seed=S (eval()'s random state);
 * eval_orders=K, a planted bug: eval() sums the first K orders only (an eval that is not the integral its sampler
 * implies, as Cycles' mf_eval was not mf_sample's).
 *
 * The microsurface: GGX slopes (Heitz 2014 eq. 85-86) on uncorrelated heights, uniform on [-1, 1] (Heitz 2016
 * sec. 3: the result does not depend on the height distribution), C1(h) = (h + 1) / 2 its CDF. A ray at height
 * h travelling along d:
 *   going up (d_z > 0): it leaves with probability C1(h)^Lambda(d) (Heitz 2016 eq. 8), else it meets the
 *     surface at the height where (C1(h) / C1(h'))^Lambda(d) = 1 - U;
 *   going down: it meets the surface at C1(h') = C1(h) (1 - U)^(1 / (1 + Lambda(-d))) (eq. 9 with the downward
 *     Lambda, -1 - Lambda(-d)).
 * At a meeting point the facet's normal is drawn from the visible normals of the view v = -d, D_v(m) =
 * <v, m>+ D(m) / sigma(v), sigma(v) = v_z (1 + Lambda(v)) above, |v_z| Lambda(-v) below the horizon (eq. 3-4),
 * by the spherical-cap construction in the configuration stretched to alpha 1 (Dupuy & Benyoub 2023), which holds
 * for a view below the horizon too; the ray reflects, its energy times the conductor's Fresnel (Born & Wolf 14.2).
 * sample(): one walk from wi (its random numbers seeded by the three uniforms); the weight is the energy it leaves
 *   with, the pdf unknown (written 0; pdf() is NULL).
 * eval(): the next-event estimator (Heitz 2016 sec. 6): along a walk from wi, every meeting point adds the energy
 *   so far times the phase function towards wo, F D_v(m) / (4 <v, m>) with m the half vector of v and wo, times
 *   the probability of leaving from there towards wo, C1(h)^Lambda(wo). Unbiased, noisy: the flag
 *   MICROSIM_BSDF_STOCHASTIC_EVAL. Its value is f |cos wo| in either transport mode (a reflection).
 * Walks end after 100 meeting points (the rest is far below the battery's resolution at alpha <= 1). */
#include "microsim/bsdf_plugin.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

enum { kMaxOrder = 100 };

typedef struct {
  double ax, ay, eta, k;
  int paths, eval_orders;
  uint64_t state; /* eval()'s generator */
} walk_bsdf;

/* splitmix64 (Steele et al. 2014): a small generator, uniforms in [0, 1). */
static uint64_t next_u64(uint64_t* s) {
  uint64_t z = (*s += 0x9e3779b97f4a7c15ull);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}
static double uniform(uint64_t* s) { return (double)(next_u64(s) >> 11) * 0x1.0p-53; }

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void normalize3(double v[3]) {
  const double n = sqrt(dot3(v, v));
  v[0] /= n, v[1] /= n, v[2] /= n;
}

static double ggx_d(const walk_bsdf* b, const double m[3]) {
  if (m[2] <= 0) return 0;
  const double x = m[0] / b->ax, y = m[1] / b->ay, e = x * x + y * y + m[2] * m[2];
  return 1 / (M_PI * b->ax * b->ay * e * e);
}

/* Lambda of a direction above the horizon (w_z > 0). */
static double lambda_up(const walk_bsdf* b, const double w[3]) {
  const double x = b->ax * w[0], y = b->ay * w[1];
  return (-1 + sqrt(1 + (x * x + y * y) / (w[2] * w[2]))) / 2;
}

static double c1(double h) { return h <= -1 ? 0 : h >= 1 ? 1 : (h + 1) / 2; }

/* The projected area of the microsurface seen from v (any side of the horizon). */
static double sigma(const walk_bsdf* b, const double v[3]) {
  const double up[3] = {-v[0], -v[1], -v[2]};
  return v[2] > 0 ? v[2] * (1 + lambda_up(b, v)) : -v[2] * lambda_up(b, up);
}

static double fresnel(const walk_bsdf* b, double c) {
  if (b->eta <= 0) return 1; /* a perfect mirror */
  const double c2 = c * c, s2 = 1 - c2, a = b->eta * b->eta - b->k * b->k - s2;
  const double t = sqrt(a * a + 4 * b->eta * b->eta * b->k * b->k), aa = sqrt(fmax(0, (t + a) / 2));
  const double rs = (t + c2 - 2 * aa * c) / (t + c2 + 2 * aa * c);
  const double rp = rs * (c2 * t + s2 * s2 - 2 * aa * c * s2) / (c2 * t + s2 * s2 + 2 * aa * c * s2);
  return (rs + rp) / 2;
}

/* The next height along d from h; INFINITY when the ray leaves. */
static double next_height(const walk_bsdf* b, const double d[3], double h, uint64_t* s) {
  const double u = uniform(s);
  if (d[2] > 0) {
    const double lambda = lambda_up(b, d), leave = pow(c1(h), lambda);
    if (1 - u <= leave) return INFINITY;
    return 2 * c1(h) / pow(1 - u, 1 / lambda) - 1;
  }
  const double down[3] = {-d[0], -d[1], -d[2]};
  const double c = (h == INFINITY ? 1 : c1(h)) * pow(1 - u, 1 / (1 + lambda_up(b, down)));
  return 2 * c - 1;
}

/* A visible normal of the view v (either side of the horizon): the spherical cap of Dupuy & Benyoub 2023 in the
 * stretched configuration, the normal unstretched. */
static void visible_normal(const walk_bsdf* b, const double v[3], uint64_t* s, double m[3]) {
  double w[3] = {b->ax * v[0], b->ay * v[1], v[2]};
  normalize3(w);
  const double z = -w[2] + uniform(s) * (1 + w[2]), phi = 2 * M_PI * uniform(s), r = sqrt(fmax(0, 1 - z * z));
  m[0] = b->ax * (r * cos(phi) + w[0]), m[1] = b->ay * (r * sin(phi) + w[1]), m[2] = z + w[2];
  normalize3(m);
}

/* F D_v(m) / (4 <v, m>) at the half vector of v and wo, times the probability of leaving from h towards wo. */
static double phase_and_leave(const walk_bsdf* b, const double v[3], const double wo[3], double h) {
  double m[3] = {v[0] + wo[0], v[1] + wo[1], v[2] + wo[2]};
  if (wo[2] <= 0 || dot3(m, m) == 0) return 0;
  normalize3(m);
  const double vm = dot3(v, m);
  if (m[2] <= 0 || vm <= 0) return 0;
  return fresnel(b, vm) * ggx_d(b, m) / (4 * sigma(b, v)) * pow(c1(h), lambda_up(b, wo));
}

/* One walk from wi: its energy when it leaves (0 after kMaxOrder), its direction then in out; with wo, the
 * next-event estimate of f |cos wo| added to *estimate at each meeting point. */
static double walk(const walk_bsdf* b, const double wi[3], const double* wo, double* estimate, double out[3], uint64_t* s) {
  double d[3] = {-wi[0], -wi[1], -wi[2]}, h = INFINITY, energy = 1;
  for (int order = 0; order < kMaxOrder; ++order) {
    h = next_height(b, d, h, s);
    if (h == INFINITY) {
      memcpy(out, d, sizeof d);
      return energy;
    }
    const double v[3] = {-d[0], -d[1], -d[2]};
    if (wo && order < b->eval_orders) *estimate += energy * phase_and_leave(b, v, wo, h);
    double m[3];
    visible_normal(b, v, s, m);
    const double vm = dot3(v, m);
    energy *= fresnel(b, vm);
    for (int i = 0; i < 3; ++i) d[i] = 2 * vm * m[i] - v[i];
  }
  return 0;
}

static void* create(const char* params) {
  walk_bsdf* b = calloc(1, sizeof *b);
  b->ax = b->ay = 0.5, b->paths = 4, b->eval_orders = kMaxOrder, b->state = 1;
  char buffer[512];
  strncpy(buffer, params ? params : "", sizeof buffer - 1);
  for (char* item = strtok(buffer, " "); item; item = strtok(NULL, " ")) {
    char* value = strchr(item, '=');
    if (!value) goto bad;
    *value++ = '\0';
    if (!strcmp(item, "alpha")) b->ax = b->ay = atof(value);
    else if (!strcmp(item, "alpha_x")) b->ax = atof(value);
    else if (!strcmp(item, "alpha_y")) b->ay = atof(value);
    else if (!strcmp(item, "eta")) b->eta = atof(value);
    else if (!strcmp(item, "k")) b->k = atof(value);
    else if (!strcmp(item, "paths")) b->paths = atoi(value);
    else if (!strcmp(item, "seed")) b->state = strtoull(value, NULL, 10);
    else if (!strcmp(item, "eval_orders")) b->eval_orders = atoi(value);
    else goto bad;
  }
  if (b->ax > 0 && b->ay > 0 && b->eta >= 0 && b->paths > 0 && b->eval_orders > 0) return b;
bad:
  free(b);
  return NULL;
}

static void destroy(void* self) { free(self); }

static int sample(void* self, const double wi[3], const double u[3], double wo[3], double* pdf, double* weight) {
  if (wi[2] <= 0) return 0;
  uint64_t s = 0, bits;
  for (int i = 0; i < 3; ++i) memcpy(&bits, &u[i], sizeof bits), s = next_u64(&s) ^ bits;
  double out[3];
  const double energy = walk(self, wi, NULL, NULL, out, &s);
  if (!(energy > 0)) return 0;
  memcpy(wo, out, sizeof out);
  *pdf = 0, weight[0] = energy;
  return 1;
}

static void eval(void* self, const double wi[3], const double wo[3], double* value) {
  walk_bsdf* b = self;
  double sum = 0, out[3];
  if (wi[2] > 0 && wo[2] > 0)
    for (int p = 0; p < b->paths; ++p) walk(b, wi, wo, &sum, out, &b->state);
  value[0] = sum / b->paths;
}

static const microsim_bsdf_plugin plugin = {MICROSIM_BSDF_PLUGIN_ABI, "Smith multiple-scattering GGX conductor (Heitz 2016)",
                                            1, 0, 0, 0, create, destroy, sample, eval, NULL,
                                            MICROSIM_BSDF_STOCHASTIC_EVAL};

const microsim_bsdf_plugin* microsim_bsdf_plugin_entry(void) { return &plugin; }
