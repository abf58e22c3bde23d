"""Energy compensation against the Smith walk: how far the Kulla-Conty (2017) and Turquin (2019) compensated GGX
mirrors are from the multiple scattering they stand in for, the random walk of Heitz et al. 2016.

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
Run: PYTHONPATH=build/python /usr/bin/python3 scripts/compensation_vs_walk.py [--rays N]"""
import argparse

import numpy as np

import microsim

ALPHAS = [0.1, 0.3, 0.6, 1.0]
THETAS = [0, 30, 60, 85]
ROWS = 16


def albedo_curve(alpha):
    t = microsim.albedo_table(alphas=[alpha], mus=64)
    mus = np.array(t["mus"])
    e = np.array(t["quantities"]["E1"]["value"][0])
    e_avg = t["quantities"]["E1"]["average"][0]
    return lambda mu: np.interp(mu, mus, e), e_avg


def row(alpha, theta, rays, E, e_avg):
    walk = microsim.smith_walk(alpha, theta, rays=rays, rows=ROWS, max_order=1000)
    mean = np.array(walk["mean_weight"])[0].sum(axis=0)  # over orders
    var = (np.array(walk["stderr"])[0] ** 2).sum(axis=0)
    ss = np.array(microsim.analytic_scatter(alpha, theta, rows=ROWS)["order1"])[0]
    centres = np.array(walk["binning"]["centres"])
    omega = np.array(walk["binning"]["solid_angle"])
    mu_o = np.clip(centres[..., 2], 0, None)
    mu_i = np.cos(np.radians(theta))
    kc = ss + (1 - E(mu_i)) * (1 - E(mu_o)) / (np.pi * (1 - e_avg)) * mu_o * omega * (mu_o > 0)
    turquin = ss / E(mu_i)
    walk_albedo = mean.sum()
    floor = 0.5 * np.sqrt(2 / np.pi) * np.sqrt(var).sum() / walk_albedo
    out = [alpha, theta, walk_albedo]
    for lobe in (kc, turquin):
        tv = 0.5 * np.abs(lobe / lobe.sum() - mean / walk_albedo).sum()
        out += [lobe.sum() - walk_albedo, tv, floor]
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rays", type=int, default=1_000_000)
    a = p.parse_args()
    print("| alpha | theta | walk albedo | KC - walk | KC lobe TV | Turquin - walk | Turquin lobe TV | TV noise floor |")
    print("|---|---|---|---|---|---|---|---|")
    for alpha in ALPHAS:
        E, e_avg = albedo_curve(alpha)
        for theta in THETAS:
            al, th, w, kc_d, kc_tv, fl, tq_d, tq_tv, _ = row(alpha, theta, a.rays, E, e_avg)
            print(f"| {al} | {th} | {w:.5f} | {kc_d:+.5f} | {kc_tv:.4f} | {tq_d:+.5f} | {tq_tv:.4f} | {fl:.4f} |")


if __name__ == "__main__":
    main()
