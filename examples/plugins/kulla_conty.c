/* An energy-compensated BSDF wrapped for `microsim check-bsdf --plugin` (include/microsim/bsdf_plugin.h): the GGX
 * mirror (F = 1) of roughness alpha=A with the Kulla & Conty 2017 compensation lobe, written from the math.
 *   single scattering: f cos o = D(h) G2(i, o) / (4 cos i) (Walter et al. 2007 eq. 20, G2 height-correlated,
 *     Heitz 2014 eq. 99);
 *   its albedo E(mu) = the mean over the visible normals of wi of G2 / G1(wi) (a reflection below the horizon
 *     counting 0), tabulated at create() on 64 mu by a 64 x 64 midpoint grid of the visible-normal sampler's
 *     uniforms, E_avg = 2 integral E(mu) mu dmu;
 *   the lobe: f_ms = (1 - E(mu_i)) (1 - E(mu_o)) / (pi (1 - E_avg)) (Kulla & Conty 2017, slide "energy
 *     compensation"), reciprocal, and with it the BSDF's albedo is 1 up to the table's error.
 * sample(): the lobe with probability 1 - E(mu_i) (cosine-weighted), else a visible-normal reflection (Heitz
 * 2018); the pdf the mixture's, the weight eval / pdf. It claims no exact reference: `--reference none`.
 * bug=non-reciprocal, a planted bug: the lobe (1 - E(mu_i))^2 for (1 - E(mu_i)) (1 - E(mu_o)): energy and
 * sampling stay consistent, only reciprocity sees it. */
#include "microsim/bsdf_plugin.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { kMus = 64, kGrid = 64 };

typedef struct {
  double alpha, e[kMus], e_avg;
  int non_reciprocal;
} kc_bsdf;

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void normalize3(double v[3]) {
  const double n = sqrt(dot3(v, v));
  v[0] /= n, v[1] /= n, v[2] /= n;
}

static double ggx_d(const kc_bsdf* b, const double m[3]) {
  if (m[2] <= 0) return 0;
  const double a2 = b->alpha * b->alpha, e = (m[0] * m[0] + m[1] * m[1]) / a2 + m[2] * m[2];
  return 1 / (M_PI * a2 * e * e);
}

static double lambda(const kc_bsdf* b, const double w[3]) {
  return (-1 + sqrt(1 + b->alpha * b->alpha * (w[0] * w[0] + w[1] * w[1]) / (w[2] * w[2]))) / 2;
}

/* A visible normal of w (w_z > 0) from two uniforms: the view stretched to alpha 1, a point of the projected
 * hemisphere, the normal unstretched (Heitz 2018). */
static void visible_normal(const kc_bsdf* b, const double w[3], double u1, double u2, double m[3]) {
  double v[3] = {b->alpha * w[0], b->alpha * w[1], w[2]};
  normalize3(v);
  const double len2 = v[0] * v[0] + v[1] * v[1];
  double t1[3] = {1, 0, 0};
  if (len2 > 0) t1[0] = -v[1] / sqrt(len2), t1[1] = v[0] / sqrt(len2);
  const double t2[3] = {v[1] * t1[2] - v[2] * t1[1], v[2] * t1[0] - v[0] * t1[2], v[0] * t1[1] - v[1] * t1[0]};
  const double r = sqrt(u1), phi = 2 * M_PI * u2, s = (1 + v[2]) / 2;
  const double p1 = r * cos(phi), p2 = (1 - s) * sqrt(1 - p1 * p1) + s * r * sin(phi);
  const double p3 = sqrt(fmax(0, 1 - p1 * p1 - p2 * p2));
  for (int i = 0; i < 3; ++i) m[i] = p1 * t1[i] + p2 * t2[i] + p3 * v[i];
  m[0] *= b->alpha, m[1] *= b->alpha, m[2] = fmax(0, m[2]);
  normalize3(m);
}

static void reflect(const double w[3], const double m[3], double out[3]) {
  const double c = dot3(w, m);
  for (int i = 0; i < 3; ++i) out[i] = 2 * c * m[i] - w[i];
}

/* E at mu: linear between the nodes (j + 0.5) / kMus, constant beyond the end ones. */
static double albedo(const kc_bsdf* b, double mu) {
  double x = mu * kMus - 0.5;
  x = x < 0 ? 0 : x > kMus - 1 ? kMus - 1 : x;
  const int j = (int)x < kMus - 2 ? (int)x : kMus - 2;
  return b->e[j] + (x - j) * (b->e[j + 1] - b->e[j]);
}

static void tabulate(kc_bsdf* b) {
  b->e_avg = 0;
  for (int j = 0; j < kMus; ++j) {
    const double mu = (j + 0.5) / kMus, wi[3] = {sqrt(1 - mu * mu), 0, mu};
    double sum = 0, m[3], wo[3];
    for (int a = 0; a < kGrid; ++a)
      for (int c = 0; c < kGrid; ++c) {
        visible_normal(b, wi, (a + 0.5) / kGrid, (c + 0.5) / kGrid, m);
        reflect(wi, m, wo);
        if (wo[2] > 0) sum += (1 + lambda(b, wi)) / (1 + lambda(b, wi) + lambda(b, wo));
      }
    b->e[j] = sum / (kGrid * kGrid);
    b->e_avg += 2 * b->e[j] * mu / kMus;
  }
}

/* f cos o of both lobes, and the pdf sample() draws wo with. */
static void evaluate(const kc_bsdf* b, const double wi[3], const double wo[3], double* value, double* pdf) {
  *value = 0, *pdf = 0;
  if (wi[2] <= 0 || wo[2] <= 0) return;
  const double ei = albedo(b, wi[2]), eo = albedo(b, wo[2]);
  const double lobe = (1 - ei) * (b->non_reciprocal ? 1 - ei : 1 - eo) / (M_PI * (1 - b->e_avg));
  double h[3] = {wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]};
  normalize3(h);
  const double d = ggx_d(b, h), li = lambda(b, wi), lo = lambda(b, wo);
  *value = d / ((1 + li + lo) * 4 * wi[2]) + lobe * wo[2];
  *pdf = (1 - ei) * wo[2] / M_PI + ei * d / ((1 + li) * 4 * wi[2]);
}

static void* create(const char* params) {
  kc_bsdf* b = calloc(1, sizeof *b);
  b->alpha = 0.5;
  char buffer[512];
  strncpy(buffer, params ? params : "", sizeof buffer - 1);
  for (char* item = strtok(buffer, " "); item; item = strtok(NULL, " ")) {
    char* value = strchr(item, '=');
    if (!value) goto bad;
    *value++ = '\0';
    if (!strcmp(item, "alpha")) b->alpha = atof(value);
    else if (!strcmp(item, "bug") && !strcmp(value, "non-reciprocal")) b->non_reciprocal = 1;
    else goto bad;
  }
  if (!(b->alpha > 0)) goto bad;
  tabulate(b);
  return b;
bad:
  free(b);
  return NULL;
}

static void destroy(void* self) { free(self); }

static int sample(void* self, const double wi[3], const double u[3], double wo[3], double* pdf, double* weight) {
  const kc_bsdf* b = self;
  if (wi[2] <= 0) return 0;
  double out[3];
  if (u[2] < 1 - albedo(b, wi[2])) { /* the lobe, cosine-weighted */
    const double r = sqrt(u[0]), phi = 2 * M_PI * u[1];
    out[0] = r * cos(phi), out[1] = r * sin(phi), out[2] = sqrt(fmax(0, 1 - u[0]));
  } else {
    double m[3];
    visible_normal(b, wi, u[0], u[1], m);
    reflect(wi, m, out);
  }
  double value;
  evaluate(b, wi, out, &value, pdf);
  if (!(*pdf > 0)) return 0;
  weight[0] = value / *pdf;
  memcpy(wo, out, sizeof out);
  return 1;
}

static void eval(void* self, const double wi[3], const double wo[3], double* value) {
  double pdf;
  evaluate(self, wi, wo, value, &pdf);
}

static double pdf(void* self, const double wi[3], const double wo[3]) {
  double value, p;
  evaluate(self, wi, wo, &value, &p);
  return p;
}

static const microsim_bsdf_plugin plugin = {MICROSIM_BSDF_PLUGIN_ABI, "Kulla-Conty compensated GGX mirror", 1, 0, 0, 0,
                                            create, destroy, sample, eval, pdf, 0};

const microsim_bsdf_plugin* microsim_bsdf_plugin_entry(void) { return &plugin; }
