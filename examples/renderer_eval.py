"""A renderer's eval() and pdf() at the pairs (wi, wo) of `microsim bsdf-queries`, written from the math as
pbrt-v4 (DielectricBxDF::f and ::PDF, ConductorBxDF) and Mitsuba 3 (roughdielectric, roughconductor) compute them,
in float32 as a renderer does: for the direction wg it was given and ws, the lobe by the sides of the pair, the
generalised half vector (Walter et al. 2007 eq. 13, 16), backfacing microfacets 0, a refraction's f divided by
etap^2 in radiance mode, pdf = D_wg(h) (F or 1 - F) times the half-vector Jacobian (eq. 14, 17) with the visible
normals of Heitz 2018. Each row of the output: wi, wo, f(wi, wo) |cos wo|, pdf(wo | wi).
`--bug` plants one of the bugs `microsim check-eval` must catch: eta2_twice, lobe_by_ws_only, pdf_without_fresnel
(a glass), no_hemisphere_check (gold).
Run: python3 examples/renderer_eval.py queries.npy eval.npy [--kind dielectric|conductor] [--bug NAME]"""
import argparse

import numpy as np

ALPHA = 0.3
ETA = 1.5
GOLD = (0.2, 3.9)


def ggx_d(m, a, form="stable"):
    """GGX D (Walter et al. 2007 eq. 33) as Mitsuba 3 writes it ("stable": from the components of m); as pbrt-v4's
    TrowbridgeReitzDistribution::D ("pbrt": tan^2 = (1 - cos^2) / cos^2 times the squares of cos phi = x / sin
    theta and sin phi clamped to [-1, 1], which cancel unless a clamp binds: then the relative error is about
    eps / alpha^2, up to 28% at alpha 1e-3 in float32); or as Karis 2013's real-time form ("ue4": a^2 / (pi
    ((a^2 - 1) cos^2 + 1)^2), which cancels near the peak everywhere: 3% typical at alpha 1e-3 in float32)."""
    one = m.dtype.type(1)
    c2 = m[:, 2] ** 2
    if form == "ue4":
        d = (c2 * a * a - c2) + one
        return np.where(m[:, 2] > 0, a * a / (np.pi * d * d), 0)
    if form == "pbrt":
        s2 = np.maximum(0, one - c2)
        s = np.sqrt(s2)
        with np.errstate(all="ignore"):
            cos_phi = np.where(s == 0, one, np.clip(m[:, 0] / s, -one, one))
            sin_phi = np.where(s == 0, 0, np.clip(m[:, 1] / s, -one, one))
        e = s2 / c2 * ((cos_phi / a) ** 2 + (sin_phi / a) ** 2)
        return np.where(m[:, 2] > 0, 1 / (np.pi * a * a * c2 * c2 * (1 + e) ** 2), 0)
    e = (m[:, 0] / a) ** 2 + (m[:, 1] / a) ** 2 + m[:, 2] ** 2
    return np.where(m[:, 2] > 0, 1 / (np.pi * a * a * e ** 2), 0)


def ggx_lambda(w, a):
    t2 = (a * a) * (w[:, 0] ** 2 + w[:, 1] ** 2) / w[:, 2] ** 2
    return (-1 + np.sqrt(1 + t2)) / 2


def fresnel_dielectric(c, eta):
    """Unpolarised F for cos c on the side of index 1 (c < 0: from the other side, eta inverted)."""
    eta = np.where(c < 0, 1 / eta, eta)
    c = np.abs(c)
    s2 = (1 - c ** 2) / eta ** 2
    ct = np.sqrt(np.maximum(0, 1 - s2))
    rs = (c - eta * ct) / (c + eta * ct)
    rp = (eta * c - ct) / (eta * c + ct)
    return np.where(s2 >= 1, 1, (rs ** 2 + rp ** 2) / 2)


def fresnel_conductor(c, eta, k):
    c2 = c * c
    s2 = 1 - c2
    a = eta * eta - k * k - s2
    t = np.sqrt(a * a + 4 * eta * eta * k * k)
    a2b2 = t
    aa = np.sqrt(np.maximum(0, (t + a) / 2))
    rs = (a2b2 + c2 - 2 * aa * c) / (a2b2 + c2 + 2 * aa * c)
    rp = rs * (c2 * a2b2 + s2 * s2 - 2 * aa * c * s2) / (c2 * a2b2 + s2 * s2 + 2 * aa * c * s2)
    return (rs + rp) / 2


def renderer_eval(q, kind, dtype=np.float32, transport="radiance", masking="height-correlated", bug=None,
                  normals="vndf", alpha=ALPHA, d_form="stable"):
    """(value, pdf) per query row (wg, ws) as a renderer computes them, in `dtype`; normals='ndf': pdf() of a
    sample() that draws m from D(m) cos (Walter et al. 2007) instead of the visible normals; d_form: ggx_d's."""
    q = q.astype(dtype)
    wg, ws = q[:, :3], q[:, 3:]
    cg, cs = wg[:, 2], ws[:, 2]
    one = dtype(1)
    with np.errstate(all="ignore"):
        reflect = cs > 0 if bug == "lobe_by_ws_only" else cg * cs > 0
        if kind == "conductor":
            reflect = np.ones_like(cs, bool) if bug == "no_hemisphere_check" else (cg > 0) & (cs > 0)
        etap = np.where(reflect, one, np.where(cg > 0, dtype(ETA), one / dtype(ETA)))
        h = ws * etap[:, None] + wg
        h = h / np.linalg.norm(h, axis=1)[:, None]
        h = h * np.where(h[:, 2] < 0, -one, one)[:, None]
        hg, hs = np.einsum("ij,ij->i", wg, h), np.einsum("ij,ij->i", ws, h)
        ok = (hg * cg > 0) & (hs * cs > 0) & (cg != 0) & (cs != 0)
        D = ggx_d(h, dtype(alpha), d_form)
        lg, ls = ggx_lambda(wg, dtype(alpha)), ggx_lambda(ws, dtype(alpha))
        G = 1 / (1 + lg + ls) if masking == "height-correlated" else 1 / ((1 + lg) * (1 + ls))
        if kind == "conductor":
            F = fresnel_conductor(np.abs(hg), dtype(GOLD[0]), dtype(GOLD[1]))
            f = D * G * F / np.abs(4 * cg * cs)
            dm = D * h[:, 2] if normals == "ndf" else 1 / (1 + lg) * D * np.abs(hg) / np.abs(cg)
            pdf = np.where(reflect, dm / (4 * np.abs(hg)), 0)
            f = np.where(ok | (bug == "no_hemisphere_check"), np.where(reflect, f, 0), 0)
            return np.nan_to_num(f * np.abs(cs)), np.nan_to_num(np.where(ok, pdf, 0))
        F = fresnel_dielectric(hg, dtype(ETA))
        fr = D * G * F / np.abs(4 * cg * cs)
        denom = (hs + hg / etap) ** 2
        ft = D * G * (1 - F) * np.abs(hs * hg / (denom * cg * cs))
        if transport == "radiance":
            ft = ft / etap ** (4 if bug == "eta2_twice" else 2)
        f = np.where(ok, np.where(reflect, fr, ft), 0)
        dv = D * h[:, 2] if normals == "ndf" else 1 / (1 + lg) * D * np.abs(hg) / np.abs(cg)
        jac = np.where(reflect, 1 / (4 * np.abs(hs)), np.abs(hs) / denom)
        p_lobe = np.where(reflect, one if bug == "pdf_without_fresnel" else F, 1 - F)
        pdf = np.where(ok, dv * jac * p_lobe, 0)
    return np.nan_to_num(f * np.abs(cs)), np.nan_to_num(pdf)



def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("queries")
    p.add_argument("out")
    p.add_argument("--kind", choices=["dielectric", "conductor"], default="dielectric")
    p.add_argument("--transport", choices=["radiance", "importance"], default="radiance")
    p.add_argument("--masking", choices=["height-correlated", "separable"], default="height-correlated")
    p.add_argument("--bug", choices=["eta2_twice", "lobe_by_ws_only", "pdf_without_fresnel", "no_hemisphere_check"])
    a = p.parse_args()
    q = np.load(a.queries)
    value, pdf = renderer_eval(q, a.kind, transport=a.transport, masking=a.masking, bug=a.bug)
    np.save(a.out, np.column_stack([q, value, pdf]).astype(np.float32))
    print(f"{len(q)} rows: wi, wo, f |cos wo|, pdf (float32) written to {a.out}")


if __name__ == "__main__":
    main()
