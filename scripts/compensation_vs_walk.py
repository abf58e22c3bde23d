"""Energy compensation against the Smith walk: how far the Kulla-Conty (2017) and Turquin (2019) compensated GGX
mirrors and conductors are from the multiple scattering they stand in for, the random walk of Heitz et al. 2016.

For a mirror (F = 1), with E(mu) the single-scattering albedo (microsim.albedo_table, analytic, 64 Gauss-Legendre
nodes, interpolated) and E_avg = 2 int E(mu) mu dmu:
- Kulla & Conty 2017: f = f_ss + (1 - E(mu_i)) (1 - E(mu_o)) / (pi (1 - E_avg));
- Turquin 2019: f = f_ss (1 + (1 - E(mu_i)) / E(mu_i)) = f_ss / E(mu_i).
Both conserve energy by construction (albedo 1), as the mirror's walk does: the albedo differences printed are
the error of integrating the Kulla-Conty term per bin and of the walk's order cap, not physics. They differ from
the walk in the shape of the lobe. Per (alpha, theta): the walk's
total lobe over the hemispheres binning (microsim.smith_walk, 16 rows per hemisphere, `--rays` paths), the
single-scattering lobe (microsim.analytic_scatter), the Kulla-Conty term integrated per bin at the bin's centre
(midpoint rule), and for each scheme the albedo difference and the total-variation distance of the shapes with its
noise floor (the walk's noise only: 1/2 sqrt(2/pi) sum sigma_i / albedo, the
variance of the total over orders taken as the sum of the orders' variances).

A conductor (`--material conductor:ETA,K`, one channel) loses energy, and each scheme carries its Fresnel by its own
rule, so the albedo differences are then physics: f_ss holds the exact Fresnel of each facet, and
- Kulla & Conty 2017 scale the mirror's multiple-scattering term by F_avg^2 E_avg / (1 - F_avg (1 - E_avg)), with
  F_avg = 2 int F(mu) mu dmu (microsim.albedo_table's F_avg);
- Turquin 2019 scale by 1 + F0 (1 - E(mu_i)) / E(mu_i), F0 the Fresnel at normal incidence.
A dielectric (`--material dielectric:ETA`, light from outside) loses nothing: the walk and the lobes cover both
hemispheres, E(mu) is the single-scattering E_R + E_T of that dielectric (microsim.albedo_table), and only Turquin's
rule is measured, as Blender Cycles applies it to its rough glass (f_ss / E(mu_i), E from its glass tables); the
Kulla-Conty columns are left empty (their dielectric form, a multiple-scattering lobe split between the sides, is
not written here).
Run: PYTHONPATH=build/python /usr/bin/python3 scripts/compensation_vs_walk.py [--rays N] [--material M]"""
import argparse

import numpy as np

import microsim

ALPHAS = [0.1, 0.3, 0.6, 1.0]
THETAS = [0, 30, 60, 85]
ROWS = 16


def albedo_curve(alpha, material):
    """The mirror's (F = 1) E(mu) interpolated and E_avg, which both schemes use whatever the Fresnel, and F_avg (1
    for the mirror; a conductor's table holds it beside its own E, which includes the Fresnel)."""
    if material.startswith("dielectric"):
        t = microsim.albedo_table(alphas=[alpha], mus=64, material=material)
        mus, e = np.array(t["mus"]), np.array(t["quantities"]["E1"]["value"][0])
        return (lambda mu: np.interp(mu, mus, e)), t["quantities"]["E1"]["average"][0], None
    t = microsim.albedo_table(alphas=[alpha], mus=64, material="mirror")
    mus = np.array(t["mus"])
    e = np.array(t["quantities"]["E1"]["value"][0])
    e_avg = t["quantities"]["E1"]["average"][0]
    f_avg = 1.0 if material == "mirror" else microsim.albedo_table(alphas=[alpha], mus=8, material=material)["F_avg"]
    return (lambda mu: np.interp(mu, mus, e)), e_avg, f_avg


def normal_fresnel(material):
    """F0 of a conductor ETA,K (Fresnel at normal incidence, ((n-1)^2 + k^2) / ((n+1)^2 + k^2)); 1 for the mirror."""
    if material == "mirror":
        return 1.0
    n, k = (float(v) for v in material.split(":")[1].split(","))
    return ((n - 1) ** 2 + k ** 2) / ((n + 1) ** 2 + k ** 2)


def row(alpha, theta, rays, material, curve):
    E, e_avg, f_avg = curve
    walk = microsim.smith_walk(alpha, theta, material=material, rays=rays, rows=ROWS, max_order=1000)
    mean = np.array(walk["mean_weight"])[0].sum(axis=0)  # over orders
    var = (np.array(walk["stderr"])[0] ** 2).sum(axis=0)
    ss = np.array(microsim.analytic_scatter(alpha, theta, material=material, rows=ROWS)["order1"])[0]
    centres = np.array(walk["binning"]["centres"])
    omega = np.array(walk["binning"]["solid_angle"])
    mu_o = np.clip(centres[..., 2], 0, None)
    mu_i = np.cos(np.radians(theta))
    if f_avg is None:  # a dielectric: Turquin's scale of both lobes only
        kc, turquin = None, ss / E(mu_i)
    else:
        fresnel_ms = f_avg ** 2 * e_avg / (1 - f_avg * (1 - e_avg))  # Kulla & Conty 2017, the multiple-scattering Fresnel
        kc = ss + fresnel_ms * (1 - E(mu_i)) * (1 - E(mu_o)) / (np.pi * (1 - e_avg)) * mu_o * omega * (mu_o > 0)
        turquin = ss * (1 + normal_fresnel(material) * (1 - E(mu_i)) / E(mu_i))
    walk_albedo = mean.sum()
    floor = 0.5 * np.sqrt(2 / np.pi) * np.sqrt(var).sum() / walk_albedo
    se = walk["summary"]["channels"][0]["albedo"]["total"]["both"]["standard_error"]  # over paths (0 for the mirror)
    out = [alpha, theta, walk_albedo, se]
    for lobe in (kc, turquin):
        if lobe is None:
            out += [None, None, floor]
            continue
        tv = 0.5 * np.abs(lobe / lobe.sum() - mean / walk_albedo).sum()
        out += [lobe.sum() - walk_albedo, tv, floor]
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rays", type=int, default=1_000_000)
    p.add_argument("--material", default="mirror",
                   help="mirror, one conductor channel conductor:ETA,K, or dielectric:ETA (light from outside)")
    a = p.parse_args()
    print("| alpha | theta | walk albedo (SE) | KC - walk | KC lobe TV | Turquin - walk | Turquin lobe TV | TV noise floor |")
    print("|---|---|---|---|---|---|---|---|")
    for alpha in ALPHAS:
        curve = albedo_curve(alpha, a.material)
        for theta in THETAS:
            al, th, w, se, kc_d, kc_tv, fl, tq_d, tq_tv, _ = row(alpha, theta, a.rays, a.material, curve)
            kc = "- | -" if kc_d is None else f"{kc_d:+.5f} | {kc_tv:.4f}"
            print(f"| {al} | {th} | {w:.5f} ({se:.5f}) | {kc} | {tq_d:+.5f} | {tq_tv:.4f} | {fl:.4f} |")


if __name__ == "__main__":
    main()
