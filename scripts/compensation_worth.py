#!/usr/bin/python3
"""What energy compensation is worth in each renderer's layout (docs/records/energy-tables.md): the albedo of a
GGX mirror (F = 1) compensated with a Kulla-Conty multiple-scattering lobe built from the layout's table read
by bilinear interpolation, against the same lobe built from the exact E, and both against the Smith random
walk's albedo of all orders.

Kulla & Conty 2017 (slides "Revisiting physically based shading at Imageworks", the E_ms lobe): f_ms(mu_o,
mu_i) = (1 - E(mu_o)) (1 - E(mu_i)) / (pi (1 - E_avg)), whose directional albedo is (1 - E(mu_o)) I / (1 -
E_avg) with I = 2 int_0^1 (1 - E(mu)) mu dmu. With the exact E, I = 1 - E_avg and the compensated albedo
E + E_ms is 1 at every (alpha, mu). A renderer evaluates the single-scattering lobe exactly (its albedo is
the true E) but builds f_ms from its table: E_T(alpha, mu) interpolated bilinearly in the layout's own
coordinates, and E_avg read from the layout's E_avg table (linear in roughness) where it has one, else
integrated from E_T itself (then I / (1 - E_avg) = 1). So the compensated albedo is

    E(mu_o) + (1 - E_T(mu_o)) I_T / (1 - E_avg,T),

and its difference from 1 is what the layout's resolution and interpolation alone cost. Also printed: the
scaling form f_ss / E_T (Turquin 2019; Filament's energy compensation 1 + F0 (1 / DFG.y - 1) at F0 = 1),
whose albedo is E / E_T.

The layouts' nodes: docs/data/layout-*.csv (the reference values, not their encodings), and Filament's
128 x 128 computed here (`albedo --layout filament-dfg`, its CSV is not kept in docs/data). The exact E at the
evaluation points: `albedo --model analytic`; the walk: `albedo --model smith-walk` at the same alphas and
Gauss-Legendre mus.

Usage: /usr/bin/python3 scripts/compensation_worth.py [build/microsim]
"""
import csv
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "docs", "data")
ALPHAS = "0.02,0.1,0.3,0.6,1"
MUS = 6               # Gauss-Legendre nodes in mu: the evaluation points
WALK_RAYS = 100_000   # per cell: a mirror's walk weight is 1 per path that leaves, so few are needed
FILAMENT_TOLERANCE = 1e-7
LAYOUTS = ["cycles", "enterprise-pbr", "uniform", "filament-dfg"]
EDGES = {"cycles"}    # nodes at i / (n - 1); the others at cell centres (i + 0.5) / n (scatter/albedo_layout.h)


class Layout:
    """A layout's nodes from the CSV microsim writes, read as the renderer reads them."""

    def __init__(self, name, path):
        self.name = name
        with open(path, newline="") as f:
            lines = f.read().splitlines()
        axes = next(line for line in lines if line.startswith("# x: "))
        x_is_roughness = axes.startswith("# x: roughness index")
        self.roughness_is_alpha = "roughness = alpha" in axes
        rows = list(csv.DictReader(line for line in lines if not line.startswith("#")))
        ri = [int(r["x"] if x_is_roughness else r["y"]) for r in rows]
        mj = [int(r["y"] if x_is_roughness else r["x"]) for r in rows]
        n_r, n_mu = max(ri) + 1, max(mj) + 1
        self.E = np.zeros((n_r, n_mu))
        self.E_avg = np.full(n_r, np.nan)
        for r, i, j in zip(rows, ri, mj):
            self.E[i, j] = float(r["E"])
            if "E_avg" in r:
                self.E_avg[i] = float(r["E_avg"])
        self.has_average = not np.isnan(self.E_avg).any()
        self.r_nodes, self.mu_nodes = self.positions(n_r), self.positions(n_mu)

    def positions(self, n):
        i = np.arange(n)
        return i / (n - 1) if self.name in EDGES else (i + 0.5) / n

    def roughness(self, alpha):
        return alpha if self.roughness_is_alpha else math.sqrt(alpha)

    def row(self, alpha):
        """E over the mu nodes, interpolated linearly in roughness (clamped to the edge nodes)."""
        r = self.roughness(alpha)
        return np.array([np.interp(r, self.r_nodes, self.E[:, j]) for j in range(self.E.shape[1])])

    def lookup(self, alpha, mu):
        return float(np.interp(mu, self.mu_nodes, self.row(alpha)))

    def compensation(self, alpha):
        """I_T / (1 - E_avg,T): the factor of (1 - E_T(mu_o)) in the lobe's albedo."""
        row = self.row(alpha)
        mu = (np.arange(200_000) + 0.5) / 200_000  # midpoint rule on a piecewise-linear E_T
        integral = 2 * float(np.mean((1 - np.interp(mu, self.mu_nodes, row)) * mu))
        if not self.has_average:
            return 1.0
        e_avg = float(np.interp(self.roughness(alpha), self.r_nodes, self.E_avg))
        return integral / (1 - e_avg)


def albedo_json(microsim, tmp, name, *args):
    out = os.path.join(tmp, name + ".json")
    subprocess.run([microsim, "albedo", "--alphas", ALPHAS, "--mus", str(MUS), *args, "--out",
                    os.path.join(tmp, name + ".exr"), "--json", out], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    with open(out) as f:
        return json.load(f)


def main():
    microsim = os.path.realpath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build", "microsim"))
    with tempfile.TemporaryDirectory() as tmp:
        filament = os.path.join(tmp, "layout-filament-dfg.csv")
        subprocess.run([microsim, "albedo", "--layout", "filament-dfg", "--tolerance", str(FILAMENT_TOLERANCE),
                        "--out", os.path.join(tmp, "f.exr"), "--csv", filament], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        layouts = [Layout(n, filament if n == "filament-dfg" else os.path.join(DATA, f"layout-{n}.csv"))
                   for n in LAYOUTS]
        exact = albedo_json(microsim, tmp, "analytic", "--model", "analytic")
        walk = albedo_json(microsim, tmp, "walk", "--model", "smith-walk", "--rays", str(WALK_RAYS))
    report(exact, walk, layouts)


def cell(table, name, a, m):
    q = table["quantities"][name]
    return q["value"][a][m], q["error"][a][m]


def report(exact, walk, layouts):
    """Per (alpha, mu): the walk's all-orders albedo and each layout's Kulla-Conty compensated albedo - 1 (the
    exact-E lobe's compensated albedo is 1 identically); then each layout's largest errors."""
    alphas, mus = exact["alphas"], exact["mus"]
    print(f"| alpha | mu | E (single) | walk (all orders) | {' | '.join(lay.name for lay in layouts)} |")
    print("|---|---|---|---|" + "---|" * len(layouts))
    errors = {lay.name: [] for lay in layouts}  # (alpha, mu, Kulla-Conty - 1, E / E_T - 1)
    for a, alpha in enumerate(alphas):
        factors = [lay.compensation(alpha) for lay in layouts]
        for m, mu in enumerate(mus):
            e, _ = cell(exact, "E1", a, m)
            w, w_err = cell(walk, "E", a, m)
            row = []
            for lay, factor in zip(layouts, factors):
                e_t = lay.lookup(alpha, mu)
                kc = e + (1 - e_t) * factor
                errors[lay.name].append((alpha, mu, kc - 1, e / e_t - 1))
                row.append(f"{kc - 1:+.1e}")
            print(f"| {alpha:g} | {mu:.4f} | {e:.6f} | {w:.6f} +- {w_err:.1g} | {' | '.join(row)} |")
    inner = lambda x: x[1] >= 0.1 and x[0] < max(alphas)  # noqa: E731
    print("\n| layout | max abs, all | mu >= 0.1, alpha <= 0.6 | alpha 1 | scaling form: all | same, mu >= 0.1, "
          "alpha <= 0.6 |")
    print("|---|---|---|---|---|---|")
    for lay in layouts:
        e = errors[lay.name]
        worst = lambda rows, k: max(abs(x[k]) for x in rows)  # noqa: E731
        print(f"| {lay.name} | {worst(e, 2):.2g} | {worst(list(filter(inner, e)), 2):.2g} | "
              f"{worst([x for x in e if x[0] == max(alphas)], 2):.2g} | {worst(e, 3):.2g} | "
              f"{worst(list(filter(inner, e)), 3):.2g} |")


if __name__ == "__main__":
    main()
