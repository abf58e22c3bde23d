/* A renderer's rough GGX BSDF wrapped for `microsim check-bsdf --plugin` (include/microsim/bsdf_plugin.h): a
 * conductor (kind=conductor eta=ETA k=K) or a dielectric (kind=dielectric eta=ETA, the index inside over
 * outside) of roughness alpha=A (or alpha_x=AX alpha_y=AY, anisotropic along the frame's axes), radiance
 * transport, height-correlated masking, written from the math:
 *   the anisotropic D (Heitz 2014 eq. 85), Lambda and G2 = 1 / (1 + Lambda_i + Lambda_o) (Heitz 2014 eq. 86, 99),
 *   visible-normal sampling (Heitz 2018: the view stretched to the hemisphere configuration, a point of the
 *   projected hemisphere, the normal unstretched), reflection or refraction chosen with probability F,
 *   f of eq. 20 and 21 (the refraction divided by eta^2 in radiance mode), the half-vector Jacobians of eq. 14
 *   and 17, exact Fresnel for a dielectric and for a conductor (complex index).
 * Built with -DMICROSIM_PLANTED_EVAL_BUG it forgets the radiance factor in eval() only: sample() stays right,
 * so only the eval check sees it. Built with -DMICROSIM_NDF_SAMPLING it draws its normals from D(m) cos instead
 * (Walter et al. 2007 eq. 35-36, the slopes stretched by the roughness; Mitsuba 3's sample_visible = false), a
 * normal facing away from wi losing the sample, and says so in its flags (MICROSIM_BSDF_NDF_SAMPLING); with
 * -DMICROSIM_NDF_UNDECLARED too it samples so without saying it (a test's negative control). */
#include "microsim/bsdf_plugin.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
  int dielectric;
  double ax, ay, eta, k;
} ggx_bsdf;

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void normalize3(double v[3]) {
  const double n = sqrt(dot3(v, v));
  v[0] /= n, v[1] /= n, v[2] /= n;
}

static double ggx_d(const ggx_bsdf* b, const double m[3]) {
  if (m[2] <= 0) return 0;
  const double x = m[0] / b->ax, y = m[1] / b->ay, e = x * x + y * y + m[2] * m[2];
  return 1 / (M_PI * b->ax * b->ay * e * e);
}

static double ggx_lambda(const ggx_bsdf* b, const double w[3]) {
  const double x = b->ax * w[0], y = b->ay * w[1], t2 = (x * x + y * y) / (w[2] * w[2]);
  return (-1 + sqrt(1 + t2)) / 2;
}

/* Fresnel of a dielectric for cos c > 0 on the incident side, eta = n_transmitted / n_incident. */
static double fresnel_dielectric(double c, double eta) {
  const double s2 = (1 - c * c) / (eta * eta);
  if (s2 >= 1) return 1;
  const double ct = sqrt(1 - s2), rs = (c - eta * ct) / (c + eta * ct), rp = (eta * c - ct) / (eta * c + ct);
  return (rs * rs + rp * rp) / 2;
}

/* Fresnel of a conductor of complex index eta + i k for cos c (Born & Wolf 14.2). */
static double fresnel_conductor(double c, double eta, double k) {
  const double c2 = c * c, s2 = 1 - c2, a = eta * eta - k * k - s2, t = sqrt(a * a + 4 * eta * eta * k * k);
  const double aa = sqrt((t + a) / 2 > 0 ? (t + a) / 2 : 0);
  const double rs = (t + c2 - 2 * aa * c) / (t + c2 + 2 * aa * c);
  const double rp = rs * (c2 * t + s2 * s2 - 2 * aa * c * s2) / (c2 * t + s2 * s2 + 2 * aa * c * s2);
  return (rs + rp) / 2;
}

/* A visible normal of the view w (w[2] > 0) from two uniforms. */
static void sample_visible_normal(const ggx_bsdf* b, const double w[3], double u1, double u2, double m[3]) {
  double v[3] = {b->ax * w[0], b->ay * w[1], w[2]};
  normalize3(v);
  const double len2 = v[0] * v[0] + v[1] * v[1];
  double t1[3] = {1, 0, 0};
  if (len2 > 0) t1[0] = -v[1] / sqrt(len2), t1[1] = v[0] / sqrt(len2);
  const double t2[3] = {v[1] * t1[2] - v[2] * t1[1], v[2] * t1[0] - v[0] * t1[2], v[0] * t1[1] - v[1] * t1[0]};
  const double r = sqrt(u1), phi = 2 * M_PI * u2, s = (1 + v[2]) / 2;
  const double p1 = r * cos(phi), p2 = (1 - s) * sqrt(1 - p1 * p1) + s * r * sin(phi);
  const double p3 = sqrt(fmax(0, 1 - p1 * p1 - p2 * p2));
  for (int i = 0; i < 3; ++i) m[i] = p1 * t1[i] + p2 * t2[i] + p3 * v[i];
  m[0] *= b->ax, m[1] *= b->ay, m[2] = fmax(0, m[2]);
  normalize3(m);
}

/* A normal of the distribution D(m) cos from two uniforms: slopes of tan^2 = u1 / (1 - u1) at azimuth 2 pi u2
 * (Walter et al. 2007 eq. 35-36 for alpha 1), stretched by (alpha_x, alpha_y). */
static void sample_ndf_normal(const ggx_bsdf* b, double u1, double u2, double m[3]) {
  const double r = sqrt(u1 / (1 - u1)), phi = 2 * M_PI * u2;
  m[0] = -b->ax * r * cos(phi), m[1] = -b->ay * r * sin(phi), m[2] = 1;
  normalize3(m);
}

/* The pair seen from wi's side (mirrored when wi is below): wi' and wo' in `up`, eta across over wi's side. */
static double upper_side(const ggx_bsdf* b, const double wi[3], const double wo[3], double up_i[3], double up_o[3]) {
  const double side = wi[2] < 0 ? -1 : 1;
  up_i[0] = wi[0], up_i[1] = wi[1], up_i[2] = side * wi[2];
  up_o[0] = wo[0], up_o[1] = wo[1], up_o[2] = side * wo[2];
  return side > 0 ? b->eta : 1 / b->eta;
}

/* The density of the sampled normal m (per unit solid angle of m) given wi: the visible normals' (Heitz 2018
 * eq. 2), or D(m) cos(m) when the normals come from the NDF. */
static double normal_pdf(const ggx_bsdf* b, const double wi[3], const double m[3]) {
  const double c = dot3(wi, m);
#ifdef MICROSIM_NDF_SAMPLING
  return c > 0 ? ggx_d(b, m) * m[2] : 0;
#else
  return c > 0 ? ggx_d(b, m) * c / (wi[2] * (1 + ggx_lambda(b, wi))) : 0;
#endif
}

/* f |cos wo| and the pdf of wo, in radiance transport, for wi on the upper side (eta across over it). */
static void evaluate(const ggx_bsdf* b, const double wi[3], const double wo[3], double eta, double* value, double* pdf,
                     int eval_bug) {
  *value = 0, *pdf = 0;
  if (wi[2] <= 0 || wo[2] == 0) return;
  const int reflect = wo[2] > 0;
  if (!b->dielectric && !reflect) return;
  double h[3];
  for (int i = 0; i < 3; ++i) h[i] = reflect ? wi[i] + wo[i] : -(wi[i] + eta * wo[i]);
  if (dot3(h, h) == 0) return;
  normalize3(h);
  if (h[2] < 0) h[0] = -h[0], h[1] = -h[1], h[2] = -h[2];
  const double ih = dot3(wi, h), oh = dot3(wo, h);
  if (ih <= 0 || (reflect ? oh <= 0 : oh >= 0)) return;
  const double D = ggx_d(b, h), G = 1 / (1 + ggx_lambda(b, wi) + ggx_lambda(b, wo));
  const double F = b->dielectric ? fresnel_dielectric(ih, eta) : fresnel_conductor(ih, b->eta, b->k);
  const double dv = normal_pdf(b, wi, h);
  if (reflect) {
    *value = F * D * G / (4 * wi[2]);
    *pdf = dv * (b->dielectric ? F : 1) / (4 * oh);
    return;
  }
  const double denom = (ih + eta * oh) * (ih + eta * oh);
  const double radiance = eval_bug ? 1 : 1 / (eta * eta);
  *value = (1 - F) * D * G * eta * eta * ih * fabs(oh) / (wi[2] * denom) * radiance;
  *pdf = dv * (1 - F) * eta * eta * fabs(oh) / denom;
}

static void* create(const char* params) {
  ggx_bsdf* b = calloc(1, sizeof *b);
  b->ax = b->ay = 0.3, b->eta = 1.5;
  char buffer[512];
  strncpy(buffer, params ? params : "", sizeof buffer - 1);
  for (char* item = strtok(buffer, " "); item; item = strtok(NULL, " ")) {
    char* value = strchr(item, '=');
    if (!value) goto bad;
    *value++ = '\0';
    if (!strcmp(item, "kind")) b->dielectric = !strcmp(value, "dielectric");
    else if (!strcmp(item, "alpha")) b->ax = b->ay = atof(value);
    else if (!strcmp(item, "alpha_x")) b->ax = atof(value);
    else if (!strcmp(item, "alpha_y")) b->ay = atof(value);
    else if (!strcmp(item, "eta")) b->eta = atof(value);
    else if (!strcmp(item, "k")) b->k = atof(value);
    else goto bad;
  }
  if (b->ax > 0 && b->ay > 0 && b->eta > 0) return b;
bad:
  free(b);
  return NULL;
}

static void destroy(void* self) { free(self); }

static int sample(void* self, const double wi[3], const double u[3], double wo[3], double* pdf, double* weight) {
  const ggx_bsdf* b = self;
  const double z[3] = {0, 0, 1};
  double up[3], up_z[3], m[3], out[3];
  const double eta = upper_side(b, wi, z, up, up_z), side = wi[2] < 0 ? -1 : 1;
  if (up[2] <= 0) return 0;
#ifdef MICROSIM_NDF_SAMPLING
  sample_ndf_normal(b, u[0], u[1], m);
#else
  sample_visible_normal(b, up, u[0], u[1], m);
#endif
  const double c = dot3(up, m);
  if (c <= 0) return 0; /* a normal facing away from wi (drawn from the NDF only) */
  const double F = b->dielectric ? fresnel_dielectric(c, eta) : 1;
  if (!b->dielectric || u[2] < F) {
    for (int i = 0; i < 3; ++i) out[i] = 2 * c * m[i] - up[i];
    if (out[2] <= 0) return 0;
  } else {
    const double ct = sqrt(1 - (1 - c * c) / (eta * eta));
    for (int i = 0; i < 3; ++i) out[i] = -up[i] / eta + (c / eta - ct) * m[i];
    normalize3(out);
    if (out[2] >= 0) return 0;
  }
  double value;
  evaluate(b, up, out, eta, &value, pdf, 0);
  if (!(*pdf > 0)) return 0;
  weight[0] = value / *pdf; /* one channel */
  wo[0] = out[0], wo[1] = out[1], wo[2] = side * out[2];
  return 1;
}

static void eval(void* self, const double wi[3], const double wo[3], double* value) {
  const ggx_bsdf* b = self;
  double up_i[3], up_o[3], pdf;
  const double eta = upper_side(b, wi, wo, up_i, up_o);
#ifdef MICROSIM_PLANTED_EVAL_BUG
  evaluate(b, up_i, up_o, eta, value, &pdf, 1);
#else
  evaluate(b, up_i, up_o, eta, value, &pdf, 0);
#endif
}

static double pdf(void* self, const double wi[3], const double wo[3]) {
  const ggx_bsdf* b = self;
  double up_i[3], up_o[3], value, p;
  const double eta = upper_side(b, wi, wo, up_i, up_o);
  evaluate(b, up_i, up_o, eta, &value, &p, 0);
  return p;
}

static const microsim_bsdf_plugin plugin = {MICROSIM_BSDF_PLUGIN_ABI, "rough GGX (conductor or dielectric)", 1, 0, 0, 0,
                                            create, destroy, sample, eval, pdf
#if MICROSIM_BSDF_PLUGIN_ABI >= 2
#if defined(MICROSIM_NDF_SAMPLING) && !defined(MICROSIM_NDF_UNDECLARED)
                                            , MICROSIM_BSDF_NDF_SAMPLING /* flags: normals from the NDF */
#else
                                            , 0 /* flags: eval() deterministic, visible normals */
#endif
#endif
};

const microsim_bsdf_plugin* microsim_bsdf_plugin_entry(void) { return &plugin; }
