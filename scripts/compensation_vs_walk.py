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
A dielectric (`--material dielectric:ETA`) loses nothing: the walk and the lobes cover both hemispheres, E(mu) is the
single-scattering E_R + E_T of that dielectric from the side of the light (microsim.albedo_table, `inside` for light
from inside, relative index 1/ETA), and the table is printed twice, light from outside (theta) and from inside
(180 - theta), with the albedo split into R (the side of the light) and T (the other side). Turquin's rule is as
Blender Cycles applies it to its rough glass (f_ss / E(mu_i)). Kulla & Conty 2017 (slides "Revisiting Physically
Based Shading at Imageworks", dielectric multiple scattering) add a multiple-scattering lobe on each side, of the
shape of the mirror's term with each side's own E and E_avg:
  reflection, light on side s: r_s (1 - E_s(mu_i)) (1 - E_s(mu_o)) / (pi (1 - E_avg,s)),
  transmission from side s to side s': t_s (1 - E_s(mu_i)) (1 - E_s'(mu_o)) / (pi (1 - E_avg,s')),
with r_s + t_s = 1, so each side conserves energy, and the split written as t_out = x (1 - F_avg(eta)),
t_in = (1 - x) (1 - F_avg(1/eta)) (F_avg the smooth interface's cosine-weighted Fresnel average): x is fixed by
reciprocity, the energy the two multiple-scattering lobes exchange under uniform light (radiance L outside,
eta^2 L inside) balancing, x (1 - F_avg(eta)) (1 - E_avg,out) = eta^2 (1 - x) (1 - F_avg(1/eta)) (1 - E_avg,in); the
transmitted lobes are then reciprocal pointwise, f_T(out -> in) = eta^2 f_T(in -> out) in this energy convention.
The Kulla-Conty term is integrated over each bin's rows exactly in phi and by 8-point Gauss-Legendre in mu.
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


def walk_and_single(alpha, theta, rays, material):
    """The walk's dict, its lobe summed over orders and that lobe's variance, and the single-scattering lobe."""
    walk = microsim.smith_walk(alpha, theta, material=material, rays=rays, rows=ROWS, max_order=1000)
    mean = np.array(walk["mean_weight"])[0].sum(axis=0)  # over orders
    var = (np.array(walk["stderr"])[0] ** 2).sum(axis=0)
    ss = np.array(microsim.analytic_scatter(alpha, theta, material=material, rows=ROWS)["order1"])[0]
    return walk, mean, var, ss


def noise_floor(mean, var):
    """The TV distance the walk's own noise alone gives: 1/2 sqrt(2/pi) sum sigma_i / albedo."""
    return 0.5 * np.sqrt(2 / np.pi) * np.sqrt(var).sum() / mean.sum()


def tv(lobe, mean):
    return 0.5 * np.abs(lobe / lobe.sum() - mean / mean.sum()).sum()


def row(alpha, theta, rays, material, curve):
    E, e_avg, f_avg = curve
    walk, mean, var, ss = walk_and_single(alpha, theta, rays, material)
    centres = np.array(walk["binning"]["centres"])
    omega = np.array(walk["binning"]["solid_angle"])
    mu_o = np.clip(centres[..., 2], 0, None)
    mu_i = np.cos(np.radians(theta))
    fresnel_ms = f_avg ** 2 * e_avg / (1 - f_avg * (1 - e_avg))  # Kulla & Conty 2017, the multiple-scattering Fresnel
    kc = ss + fresnel_ms * (1 - E(mu_i)) * (1 - E(mu_o)) / (np.pi * (1 - e_avg)) * mu_o * omega * (mu_o > 0)
    turquin = ss * (1 + normal_fresnel(material) * (1 - E(mu_i)) / E(mu_i))
    walk_albedo = mean.sum()
    floor = noise_floor(mean, var)
    se = walk["summary"]["channels"][0]["albedo"]["total"]["both"]["standard_error"]  # over paths (0 for the mirror)
    out = [alpha, theta, walk_albedo, se]
    for lobe in (kc, turquin):
        out += [lobe.sum() - walk_albedo, tv(lobe, mean), floor]
    return out


def fresnel_average(eta):
    """F_avg = 2 int_0^1 F(mu) mu dmu of a smooth dielectric interface, relative index eta (n_t / n_i), unpolarised.
    Below 1 the Fresnel is 1 under the critical cosine mu_c = sqrt(1 - eta^2) (total internal reflection) and the
    rest is integrated in cos theta_t (mu dmu = eta^2 cos_t dcos_t), in which F is smooth up to the critical angle;
    above 1, in mu. Gauss-Legendre, 64 nodes."""
    x, w = np.polynomial.legendre.leggauss(64)
    u, w = (x + 1) / 2, w / 2  # on [0, 1]
    if eta < 1:
        ct = u
        mu = np.sqrt(1 - eta ** 2 * (1 - ct ** 2))  # Snell: sin theta_i = eta sin theta_t
        jacobian = eta ** 2 * ct  # mu dmu / dct
    else:
        mu = u
        ct = np.sqrt(1 - (1 - mu ** 2) / eta ** 2)
        jacobian = mu
    rs = (mu - eta * ct) / (mu + eta * ct)
    rp = (eta * mu - ct) / (eta * mu + ct)
    tir = 1 - eta ** 2 if eta < 1 else 0.0  # 2 int_0^mu_c mu dmu
    return tir + 2 * np.sum(w * (rs ** 2 + rp ** 2) / 2 * jacobian)


def dielectric_sides(alpha, material, mus=64, tolerance=1e-8):
    """Per side of the light (False: outside, True: inside), E(mu) = E_R + E_T of single scattering interpolated
    on microsim.albedo_table's `mus` Gauss-Legendre nodes, and E_avg."""
    sides = {}
    for inside in (False, True):
        t = microsim.albedo_table(alphas=[alpha], mus=mus, tolerance=tolerance, material=material, inside=inside)
        nodes, e = np.array(t["mus"]), np.array(t["quantities"]["E1"]["value"][0])
        sides[inside] = (lambda mu, nodes=nodes, e=e: np.interp(mu, nodes, e)), t["quantities"]["E1"]["average"][0]
    return sides


def kulla_conty_split(eta, e_avg_out, e_avg_in):
    """Kulla & Conty 2017's split of the multiple-scattering energy, per side of the light (False: outside, True:
    inside): (reflected share, transmitted share). t_out = x (1 - F_avg(eta)) and t_in = (1 - x) (1 - F_avg(1/eta)),
    x from the balance of the energy the two sides' lobes exchange (radiance L outside, eta^2 L inside):
    t_out (1 - E_avg,out) = eta^2 t_in (1 - E_avg,in)."""
    f_out, f_in = fresnel_average(eta), fresnel_average(1 / eta)
    k = eta ** 2 * (1 - f_in) * (1 - e_avg_in) / ((1 - f_out) * (1 - e_avg_out))
    x = k / (1 + k)
    t_out, t_in = x * (1 - f_out), (1 - x) * (1 - f_in)
    return {False: (1 - t_out, t_out), True: (1 - t_in, t_in)}


def row_integrals(E, edges, nodes=8):
    """int |z| (1 - E(|z|)) dz over each row between consecutive edges (descending z, within one hemisphere)."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    hi, lo = edges[:-1], edges[1:]
    mu = np.abs(lo[:, None] + (hi - lo)[:, None] * (x + 1) / 2)
    return (hi - lo) / 2 * np.sum(w * mu * (1 - E(mu)), axis=1)


def kulla_conty_lobe(sides, split, mu_i, inside, shape):
    """Kulla & Conty's multiple-scattering lobe as albedo per bin of the hemispheres binning (rows uniform in z from
    1 down to -1, columns uniform in phi), light from `inside` at cosine mu_i: the lobe on each side has the shape
    (1 - E_side(mu_o)) mu_o / (pi (1 - E_avg,side)) and the share of split[inside] of the energy 1 - E(mu_i)."""
    rows, cols = shape
    edges = np.linspace(1, -1, rows + 1)
    loss = 1 - sides[inside][0](mu_i)
    lobe = np.empty(rows)
    for first, exit_inside in ((0, False), (rows // 2, True)):
        E, e_avg = sides[exit_inside]
        share = split[inside][0 if exit_inside == inside else 1]
        integral = row_integrals(E, edges[first:first + rows // 2 + 1])
        lobe[first:first + rows // 2] = share * loss * integral / (np.pi * (1 - e_avg))
    return np.repeat(lobe[:, None] * (2 * np.pi / cols), cols, axis=1)


def dielectric_row(alpha, theta, rays, material, sides, split):
    """One view of a dielectric: the walk's R (the side of the light) with its standard error and T, then for
    Kulla-Conty and Turquin the R, T and R + T differences and the lobe's TV, then the TV noise floor, then the
    share of the walk's higher orders (2 and up) on the other side and Kulla-Conty's (its t for that side)."""
    walk, mean, var, ss = walk_and_single(alpha, theta, rays, material)
    inside = theta > 90
    mu_i = abs(np.cos(np.radians(theta)))
    rows = mean.shape[0]
    kc = ss + kulla_conty_lobe(sides, split, mu_i, inside, mean.shape)
    turquin = ss / sides[inside][0](mu_i)
    same = slice(rows // 2, rows) if inside else slice(0, rows // 2)
    se = walk["summary"]["channels"][0]["albedo"]["total"]["upper"]["standard_error"]  # R's and T's: R + T = 1
    walk_r = mean[same].sum()
    walk_t = mean.sum() - walk_r
    out = [alpha, theta, walk_r, se, walk_t]
    for lobe in (kc, turquin):
        r = lobe[same].sum()
        out += [r - walk_r, lobe.sum() - r - walk_t, lobe.sum() - mean.sum(), tv(lobe, mean)]
    higher = np.array(walk["mean_weight"])[0][1:].sum(axis=0)
    return out + [noise_floor(mean, var), 1 - higher[same].sum() / higher.sum(), split[inside][1]]


def dielectric_tables(material, rays):
    """The outside and the inside tables of a dielectric."""
    eta = float(material.split(":")[1])
    sides = {alpha: dielectric_sides(alpha, material) for alpha in ALPHAS}
    for inside in (False, True):
        print(f"\nLight from {'inside (theta > 90)' if inside else 'outside'}:\n")
        print("| alpha | theta | walk R (SE) | walk T | KC R - walk | KC T - walk | KC R+T - walk | KC lobe TV | "
              "Turquin R - walk | Turquin T - walk | Turquin R+T - walk | Turquin lobe TV | TV noise floor | "
              "walk orders 2+ T share (KC) |")
        print("|---" * 14 + "|")
        for alpha in ALPHAS:
            split = kulla_conty_split(eta, sides[alpha][False][1], sides[alpha][True][1])
            for theta in THETAS:
                v = dielectric_row(alpha, 180 - theta if inside else theta, rays, material, sides[alpha], split)
                print(f"| {v[0]} | {v[1]} | {v[2]:.5f} ({v[3]:.5f}) | {v[4]:.5f} | " +
                      " | ".join(f"{d:+.5f}" if k % 4 != 3 else f"{d:.4f}" for k, d in enumerate(v[5:13])) +
                      f" | {v[13]:.4f} | {v[14]:.3f} ({v[15]:.3f}) |")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rays", type=int, default=1_000_000)
    p.add_argument("--material", default="mirror",
                   help="mirror, one conductor channel conductor:ETA,K, or dielectric:ETA (light from both sides)")
    a = p.parse_args()
    if a.material.startswith("dielectric"):
        dielectric_tables(a.material, a.rays)
        return
    print("| alpha | theta | walk albedo (SE) | KC - walk | KC lobe TV | Turquin - walk | Turquin lobe TV | TV noise floor |")
    print("|---|---|---|---|---|---|---|---|")
    for alpha in ALPHAS:
        curve = albedo_curve(alpha, a.material)
        for theta in THETAS:
            al, th, w, se, kc_d, kc_tv, fl, tq_d, tq_tv, _ = row(alpha, theta, a.rays, a.material, curve)
            print(f"| {al} | {th} | {w:.5f} ({se:.5f}) | {kc_d:+.5f} | {kc_tv:.4f} | {tq_d:+.5f} | {tq_tv:.4f} | "
                  f"{fl:.4f} |")


if __name__ == "__main__":
    main()
