#!/usr/bin/python3
"""The anisotropic GGX mirror's energy table and what the renderers' isotropic approximation costs
(docs/records/energy-tables.md), written to docs/data/albedo-anisotropic.csv:

E(mu, phi; alpha_x, alpha_y) on 16 Gauss-Legendre mu nodes x 8 phi nodes over [0, pi/2], and E_avg, each the
analytic single-scattering albedo with its quadrature error (tolerance 1e-8). Cycles (r = sqrt(sqrt(ax ay)))
and Enterprise PBR (r_uv = sqrt(r_u r_v)) both read their isotropic table at alpha = sqrt(ax ay); beside each
E_avg(ax, ay) this prints the isotropic E_avg there and the largest |E(mu, phi) - E_iso(mu)| over the nodes.
About a minute on 2 cores.

Usage: /usr/bin/python3 scripts/anisotropic_tables.py [build/microsim]
"""
import csv
import math
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "docs", "data")
ALPHAS = [0.05, 0.1, 0.25, 0.5, 1.0]


def rows_of(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(line for line in f if not line.startswith("#")))


def main():
    microsim = os.path.realpath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build", "microsim"))
    out = os.path.join(DATA, "albedo-anisotropic.csv")
    lists = ",".join(str(a) for a in ALPHAS)
    subprocess.run([microsim, "albedo", "--model", "analytic", "--alphas", lists, "--alphas-y", lists, "--mus", "16",
                    "--phis", "8", "--tolerance", "1e-8", "--threads", "2", "--csv", out], check=True,
                   capture_output=True)
    aniso = rows_of(out)
    means = sorted({round(math.sqrt(ax * ay), 12) for ax in ALPHAS for ay in ALPHAS})
    with tempfile.TemporaryDirectory() as tmp:
        iso_csv = os.path.join(tmp, "iso.csv")
        subprocess.run([microsim, "albedo", "--model", "analytic", "--alphas", ",".join(repr(m) for m in means),
                        "--mus", "16", "--tolerance", "1e-8", "--threads", "2", "--out", os.path.join(tmp, "iso.exr"),
                        "--csv", iso_csv], check=True, capture_output=True)
        iso = rows_of(iso_csv)
    iso_e = {(round(float(r["alpha"]), 9), round(float(r["mu"]), 12)): float(r["E1"]) for r in iso}
    iso_avg = {round(float(r["alpha"]), 9): float(r["E1_avg"]) for r in iso}
    print("| alpha_x | alpha_y | E_avg | E_avg iso at sqrt(ax ay) | difference | max abs E - E_iso over (mu, phi) |")
    print("|---|---|---|---|---|---|")
    for ax in ALPHAS:
        for ay in ALPHAS:
            if ay < ax:
                continue
            g = round(math.sqrt(ax * ay), 9)
            cells = [r for r in aniso if float(r["alpha_x"]) == ax and float(r["alpha_y"]) == ay]
            avg = float(cells[0]["E_avg"])
            worst = max(abs(float(r["E"]) - iso_e[(g, round(float(r["mu"]), 12))]) for r in cells)
            print(f"| {ax:g} | {ay:g} | {avg:.6f} | {iso_avg[g]:.6f} | {avg - iso_avg[g]:+.2g} | {worst:.2g} |")


if __name__ == "__main__":
    main()
