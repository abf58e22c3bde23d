#!/usr/bin/python3
"""The energy-compensation tables in renderers' layouts (docs/records/energy-tables.md), written to docs/data/:

  layout-cycles.{exr,csv,txt}       Cycles ggx_E (32 x 32) and ggx_Eavg; .txt: as Cycles prints its tables
  layout-enterprise-pbr.{exr,csv,bin} Enterprise PBR GGX_E (32 x 32) and GGX_E_avg; .bin: float32
  layout-uniform.{exr,csv,bin}      32 x 32 at cell centres in alpha and mu; .bin: normalised uint16
  layout-filament-dfg.{exr,bin}     Filament's DFG (128 x 128), both channels; .bin: per texel two half floats,
                                    R = DFG.x, G = DFG.y, in GL order
  layout-{cycles,enterprise-pbr,uniform}-beckmann.*  the same three 32 x 32 layouts for a Beckmann mirror
                                    (`--ndf beckmann`; no renderer ships one: for a renderer with a Beckmann lobe)

each node the analytic reference of a GGX (or Beckmann) mirror with its quadrature error, and prints the interpolation error
of each layout at its cell centres (the "is 32x32 enough?" table of the record), overall and where renderers
mostly look (mu >= 0.1 and alpha >= 0.01); cells touching a node of alpha below 1e-4 (microsim's GGX clamps
alpha there) are left out. About 15 minutes on 2 cores (Filament's 32k quadratures are most
of it).

Usage: /usr/bin/python3 scripts/energy_tables.py [build/microsim] [--ndf ggx|beckmann]
(--ndf: that NDF's tables alone; the Beckmann ones take about 30 s)
"""
import argparse
import csv
import math
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "docs", "data")
LAYOUTS = [  # name, NDF, encoded file's extension, whether the CSV goes to docs/data (Filament's is 2.4 MB)
    ("cycles", "ggx", "txt", True),
    ("enterprise-pbr", "ggx", "bin", True),
    ("uniform", "ggx", "bin", True),
    ("filament-dfg", "ggx", "bin", False),
    ("cycles", "beckmann", "txt", True),
    ("enterprise-pbr", "beckmann", "bin", True),
    ("uniform", "beckmann", "bin", True),
]


def centre_errors(path):
    rows = []
    with open(path, newline="") as f:
        for row in csv.DictReader(line for line in f if not line.startswith("#")):
            error = float(row["error"])
            if not math.isnan(error):  # NaN: a cell touching a node below the reference's alpha range
                rows.append((float(row["alpha"]), float(row["mu"]), error))
    return rows


def summary(errors):
    if not errors:
        return "-", "-"
    worst = max(abs(e) for _, _, e in errors)
    rms = math.sqrt(sum(e * e for _, _, e in errors) / len(errors))
    return f"{worst:.2g}", f"{rms:.2g}"


def main():
    parser = argparse.ArgumentParser(description="Renderers' energy-compensation tables, written to docs/data/.")
    parser.add_argument("microsim", nargs="?", default=os.path.join(ROOT, "build", "microsim"))
    parser.add_argument("--ndf", choices=["ggx", "beckmann"], help="this NDF's tables alone (default: both)")
    options = parser.parse_args()
    microsim = os.path.realpath(options.microsim)
    os.makedirs(DATA, exist_ok=True)
    lines = ["| layout | NDF | nodes | max abs (all) | RMS (all) | max abs (mu >= 0.1, alpha >= 0.01) | RMS (same) | worst at |",
             "|---|---|---|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as tmp:
        for name, ndf, ext, keep_csv in LAYOUTS:
            if options.ndf and ndf != options.ndf:
                continue
            stem = f"layout-{name}" + ("" if ndf == "ggx" else f"-{ndf}")
            base = os.path.join(DATA, stem)
            centres = os.path.join(tmp, f"{stem}-centres.csv")
            args = [microsim, "albedo", "--layout", name, "--ndf", ndf, "--out", base + ".exr",
                    "--encoded", f"{base}.{ext}", "--centres", centres, "--json", os.path.join(tmp, f"{stem}.json")]
            args += ["--csv", base + ".csv"] if keep_csv else []
            subprocess.run(args, check=True, stdout=subprocess.DEVNULL)
            errors = centre_errors(centres)
            inner = [e for e in errors if e[1] >= 0.1 and e[0] >= 0.01]
            worst = max(errors, key=lambda e: abs(e[2]))
            nodes = "128 x 128" if name == "filament-dfg" else "32 x 32"
            lines.append(f"| {name} | {ndf} | {nodes} | {' | '.join(summary(errors))} | {' | '.join(summary(inner))} | "
                         f"alpha {worst[0]:.3g}, mu {worst[1]:.3g} |")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
