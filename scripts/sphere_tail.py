#!/usr/bin/python3
"""Why `validate --against HIST.exr` rejects a correct sampler in the sphere bins of a traced heightfield
(docs/records/surfaces.md 8.1): per row of the sphere binning, the tile's triangles against GGX's
expected count, the own-NDF Smith VNDF mass against the analytic one (the NDF part) and the traced mass
against the own-NDF one (the masking part); then a Monte Carlo of validate's two-sample sphere-bin test
(the statistic and pooling rule of src/stats/chi2.cpp, two_sample_homogeneity) with the sampler drawn from
the analytic D_v and the trace drawn from
  - the analytic D_v (calibration: rejects at the test's level),
  - Smith's VNDF with the tile's own NDF (the NDF error alone, no masking error),
  - the same with the rows from --from-row on replaced by the analytic law.

Usage: PYTHONPATH=build/python scripts/sphere_tail.py SURF.exr HIST.exr [--samples 1000000] [--runs 100]
       [--from-row 14] [--seed 7]
HIST.exr is a `trace vndf --surface SURF.exr` histogram (its view and ray count are read from it); the GGX
triangle counts per row assume an isotropic alpha.
"""
import argparse
import math
import sys

import numpy as np
from scipy.stats import chi2

import microsim

LEVEL = 1 - (1 - 0.01) ** 0.5  # validate's Sidak level of each of its two binned tests


def triangle_slopes(field):
    """(sx, sy) of the 2 N^2 triangles (microgeom/heightfield.h: cell (i, j) split along (i, j)-(i+1, j+1))."""
    h = np.asarray(field.heights, dtype=np.float64)  # h[j, i]
    cell = field.tile_size / field.resolution
    hx, hy = np.roll(h, -1, axis=1), np.roll(h, -1, axis=0)
    hxy = np.roll(hx, -1, axis=0)
    sx = np.concatenate([((hx - h) / cell).ravel(), ((hxy - hy) / cell).ravel()])
    sy = np.concatenate([((hxy - hx) / cell).ravel(), ((hy - h) / cell).ravel()])
    return sx, sy


def sphere_bins_of(sx, sy, rows):
    """stats/binning.h, DirectionBinning::sphere(rows), of the normals normalize(-sx, -sy, 1)."""
    cols = 2 * rows
    z = 1 / np.sqrt(1 + sx * sx + sy * sy)
    row = np.clip(np.floor((1 - z) / (2 / rows)).astype(int), 0, rows - 1)
    phi = np.mod(np.arctan2(-sy, -sx), 2 * np.pi)
    col = np.clip(np.floor(phi / (2 * np.pi / cols)).astype(int), 0, cols - 1)
    return row * cols + col


def two_sample_p(a, b):
    """validate's two-sample chi-square (NIST e-Handbook 1.3.5.15) with its pooling of sparse cells."""
    na, nb = a.sum(), b.sum()
    k1, k2 = math.sqrt(nb / na), math.sqrt(na / nb)
    cells = np.nonzero(a + b > 0)[0]
    weight = (a + b)[cells] * min(na, nb) / (na + nb)
    order = np.argsort(weight, kind="stable")
    cells, weight = cells[order], weight[order]
    k = int(np.searchsorted(weight, 5.0))
    pool_weight = weight[:k].sum()
    while k > 0 and pool_weight < 5 and k < len(cells):
        pool_weight += weight[k]
        k += 1
    single, pooled = cells[k:], cells[:k]
    stat = np.sum((k1 * a[single] - k2 * b[single]) ** 2 / (a[single] + b[single]))
    dof = len(single) - 1
    if len(pooled):
        pa, pb = a[pooled].sum(), b[pooled].sum()
        stat += (k1 * pa - k2 * pb) ** 2 / (pa + pb)
        dof += 1
    return chi2.sf(stat, dof)


def simulate(p_sampler, p_trace, samples, rays, runs, rng):
    """(median p, fraction rejected at LEVEL) of `runs` simulated validations."""
    p_sampler, p_trace = p_sampler / p_sampler.sum(), p_trace / p_trace.sum()
    ps = np.array([two_sample_p(rng.multinomial(samples, p_sampler).astype(float),
                                rng.multinomial(rays, p_trace).astype(float)) for _ in range(runs)])
    return float(np.median(ps)), float(np.mean(ps < LEVEL))


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("surface")
    ap.add_argument("histogram")
    ap.add_argument("--samples", type=int, default=1000000)
    ap.add_argument("--runs", type=int, default=100)
    ap.add_argument("--from-row", type=int, default=14)
    ap.add_argument("--seed", type=int, default=7)
    return ap.parse_args()


def traced_sphere(path):
    """(counts, analytic probabilities, rows, cols, view, alpha) of a trace vndf histogram's sphere bins."""
    hist = microsim.read_histogram(path)
    sphere = hist["binnings"]["sphere"]
    counts = np.asarray(sphere["counts"], dtype=float)
    rows, cols = counts.shape
    analytic = np.asarray(sphere["expected_probability"], dtype=float).ravel()
    wi = np.array([float(x) for x in str(hist["attributes"]["wi"]).split(",")])
    alpha = float(str(hist["attributes"]["alpha"]).split(",")[0])
    return counts.ravel(), analytic, rows, cols, wi, alpha


def own_ndf_smith(sx, sy, wi, rows):
    """Smith's VNDF with the tile's own NDF per sphere bin (projected areas (w_z - s . w_xy)+), and the
    triangle count per bin."""
    bins = sphere_bins_of(sx, sy, rows)
    area = np.maximum(wi[2] - sx * wi[0] - sy * wi[1], 0.0)
    own = np.bincount(bins, weights=area, minlength=rows * 2 * rows)
    return own / own.sum(), np.bincount(bins, minlength=rows * 2 * rows)


def ggx_triangles_in_row(r, rows, alpha, n):
    """GGX's expected count of n triangles whose normal lies in upper row r (isotropic alpha)."""
    z_hi, z_lo = 1 - 2 * r / rows, max(0.0, 1 - 2 * (r + 1) / rows)
    u_lo = math.sqrt(1 / z_hi ** 2 - 1) / alpha
    u_hi = math.inf if z_lo == 0 else math.sqrt(1 / z_lo ** 2 - 1) / alpha
    return n * (1 / (1 + u_lo ** 2) - (0.0 if math.isinf(u_hi) else 1 / (1 + u_hi ** 2))), z_hi, z_lo


def print_rows(triangles, own, analytic, traced, rows, cols, alpha, first_row):
    n = int(triangles.sum())
    print("| row | theta_m (deg) | triangles | GGX | bins occupied | per bin | own/analytic mass | traced/own mass |")
    print("|---|---|---|---|---|---|---|---|")
    for r in range(first_row, rows // 2 + 1):
        ggx, z_hi, z_lo = ggx_triangles_in_row(r, rows, alpha, n)
        sl = slice(r * cols, (r + 1) * cols)
        print(f"| {r} | {math.degrees(math.acos(z_hi)):.1f}-{math.degrees(math.acos(z_lo)):.1f} | "
              f"{triangles[sl].sum()} | {ggx:.1f} | {np.sum(triangles[sl] > 0)}/{cols} | "
              f"{triangles[sl].min()}-{triangles[sl].max()} | {own[sl].sum() / analytic[sl].sum():.3f} | "
              f"{traced[sl].sum() / own[sl].sum():.3f} |")


def main():
    args = parse_args()
    counts, analytic, rows, cols, wi, alpha = traced_sphere(args.histogram)
    sx, sy = triangle_slopes(microsim.load_heightfield(args.surface))
    own, triangles = own_ndf_smith(sx, sy, wi, rows)
    traced = counts / counts.sum()
    rays = int(counts.sum())
    print(f"{args.surface}: {len(sx)} triangles, alpha {alpha}, view {wi}, {rays} traced rays")
    print_rows(triangles, own, analytic, traced, rows, cols, alpha, max(0, args.from_row - 6))

    rng = np.random.default_rng(args.seed)
    tail = own.copy()
    tail[args.from_row * cols:] = analytic[args.from_row * cols:]
    print(f"\nsimulated validate, sphere bins ({args.runs} runs, {args.samples} samples against {rays} rays, "
          f"level {LEVEL:.5f}): median p, fraction rejected")
    for name, law in (("trace = analytic D_v (calibration)", analytic),
                      ("trace = own-NDF Smith VNDF (NDF error only)", own),
                      (f"own-NDF Smith, rows >= {args.from_row} analytic", tail)):
        median, rejected = simulate(analytic, law, args.samples, rays, args.runs, rng)
        print(f"  {name}: {median:.3g}, {rejected:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
