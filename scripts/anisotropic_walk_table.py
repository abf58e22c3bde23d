#!/usr/bin/python3
"""The anisotropic GGX mirror's walk table (docs/records/energy-tables.md), written to
docs/data/albedo-anisotropic-walk.csv:

per (alpha_x, alpha_y) in {0.1, 0.25, 0.5, 1}^2 and node (mu, phi) (8 Gauss-Legendre mu nodes x 4 phi nodes over
[0, pi/2]), the Smith random walk's (Heitz et al. 2016; lanes kernel, 1e5 paths a node, seed 1) E (every order),
E1 (order 1), E_ms (orders >= 2) and the unfinished weight, with standard errors, and their averages. Beside it
the analytic single-scattering table at the same nodes (tolerance 1e-8): this prints per alpha pair E1_avg and
E_ms_avg of the walk, the analytic E_avg, the z-score of E1_avg against it, and the largest node z-score of E1.

Usage: /usr/bin/python3 scripts/anisotropic_walk_table.py [build/microsim]
"""
import csv
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "docs", "data")
ALPHAS = "0.1,0.25,0.5,1"
AXES = ["--alphas", ALPHAS, "--alphas-y", ALPHAS, "--mus", "8", "--phis", "4", "--threads", "2"]


def rows_of(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(line for line in f if not line.startswith("#")))


def key(r):
    return tuple(round(float(r[k]), 9) for k in ("alpha_x", "alpha_y", "mu", "phi"))


def main():
    microsim = os.path.realpath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build", "microsim"))
    out = os.path.join(DATA, "albedo-anisotropic-walk.csv")
    subprocess.run([microsim, "albedo", "--model", "smith-walk", *AXES, "--rays", "100000", "--seed", "1",
                    "--walk-kernel", "lanes", "--csv", out], check=True, capture_output=True)
    walk = rows_of(out)
    with tempfile.TemporaryDirectory() as tmp:
        exact_csv = os.path.join(tmp, "exact.csv")
        subprocess.run([microsim, "albedo", "--model", "analytic", *AXES, "--tolerance", "1e-8", "--csv", exact_csv],
                       check=True, capture_output=True)
        exact = {key(r): r for r in rows_of(exact_csv)}
    print("| alpha_x | alpha_y | E1_avg (walk) | E_avg (analytic) | z | E_ms_avg (walk) | max node abs z of E1 |")
    print("|---|---|---|---|---|---|---|")
    pairs = sorted({key(r)[:2] for r in walk})
    for ax, ay in pairs:
        cells = [r for r in walk if key(r)[:2] == (ax, ay)]
        first = cells[0]
        e = exact[key(first)]
        z = (float(first["E1_avg"]) - float(e["E_avg"])) / float(first["E1_avg_se"])
        worst = max(abs(float(r["E1"]) - float(exact[key(r)]["E"])) / float(r["E1_se"]) for r in cells)
        print(f"| {ax:g} | {ay:g} | {float(first['E1_avg']):.5f} +- {float(first['E1_avg_se']):.1e} | "
              f"{float(e['E_avg']):.5f} | {z:+.2f} | {float(first['E_ms_avg']):.5f} +- {float(first['E_ms_avg_se']):.1e} "
              f"| {worst:.2f} |")
    print(f"nodes: {len(walk)}; largest unfinished weight: {max(float(r['unfinished']) for r in walk):.2g}")


if __name__ == "__main__":
    main()
