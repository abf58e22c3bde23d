#!/usr/bin/python3
"""Cycles' rough-glass tables over its index axis (docs/records/energy-tables.md), written to docs/data/:

  layout-cycles-glass.{csv,txt}      ggx_glass_E (16 x 16 x 16 over sqrt(alpha), mu, t) and ggx_glass_Eavg
  layout-cycles-glass-inv.{csv,txt}  ggx_glass_inv_E and ggx_glass_inv_Eavg: light from inside, index 1 / ior

each node the analytic single-scattering albedo E = E_R + E_T of a GGX dielectric (Walter et al. 2007 with the
height-correlated masking for both lobes, as Cycles evaluates it) with its quadrature error estimate; .txt: the
values as Cycles prints them (z slices, blank lines between). Prints the record's tables: E_avg per index node
and roughness, and the largest error estimate. About 10 minutes on 2 cores.

Usage: /usr/bin/python3 scripts/glass_tables.py [build/microsim]
"""
import csv
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "docs", "data")
TOLERANCE = "1e-7"  # a fifth of the 6 decimals' rounding


def rows_of(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(line for line in f if not line.startswith("#")))


def main():
    microsim = os.path.realpath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "build", "microsim"))
    os.makedirs(DATA, exist_ok=True)
    for name in ("cycles-glass", "cycles-glass-inv"):
        base = os.path.join(DATA, f"layout-{name}")
        out = subprocess.run([microsim, "albedo", "--layout", name, "--tolerance", TOLERANCE, "--threads", "2",
                              "--csv", base + ".csv", "--encoded", base + ".txt"],
                             check=True, capture_output=True, text=True).stdout
        print(out)
        rows = rows_of(base + ".csv")
        worst = max(float(r["E_error"]) for r in rows)
        print(f"{name}: {len(rows)} nodes, largest error estimate {worst:.2g}")
        xs = (1, 4, 8, 15)  # r = x / 15
        print("| t | ior | " + " | ".join(f"E_avg at r = {x}/15 (alpha {(x / 15) ** 2:.3g})" for x in xs) + " |")
        print("|---|---|" + "---|" * len(xs))
        for z in (0, 3, 5, 8, 12, 15):
            cells = {int(r["x"]): r for r in rows if int(r["z"]) == z and int(r["y"]) == 0}
            t, ior = float(cells[1]["t"]), float(cells[1]["ior"])
            print(f"| {t:.4g} | {ior:.6g} | " + " | ".join(f"{float(cells[x]['E_avg']):.6f}" for x in xs) + " |")
        print()


if __name__ == "__main__":
    main()
