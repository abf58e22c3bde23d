#!/usr/bin/python3
"""The Smith walk's reflected / transmitted split on Blender Cycles' rough-glass nodes
(docs/records/energy-tables.md), summarised in docs/data/glass-walk-split.csv:

`microsim albedo --layout cycles-glass|cycles-glass-inv --model smith-walk --rays 100000 --walk-kernel lanes
--seed 1` per layout (16 x 16 x 16 nodes, about a minute each on 2 cores; the full tables, 1.2 MB each, are
written to a temporary directory, or kept with --keep DIR). Per index node the summary holds the means over
the in-range (roughness, mu) nodes (roughness > 0) of E_R, E_T (every order), E1_R, E1_T (order 1),
E_ms = E - E1 and the share of the multiple scattering that is transmitted, sum (E_T - E1_T) / sum (E - E1).
Order 1 is single scattering with the Smith microsurface's own masking, not the reflection form for both lobes
that Cycles' tables hold (scatter/albedo_glass_walk.h).

Usage: /usr/bin/python3 scripts/glass_walk_table.py [build/microsim] [--keep DIR]
"""
import csv
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "docs", "data")
QUANTITIES = ["E_R", "E_T", "E1_R", "E1_T"]


def rows_of(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(line for line in f if not line.startswith("#")))


def summarise(layout, rows):
    out = []
    for z in sorted({int(r["z"]) for r in rows}):
        cells = [r for r in rows if int(r["z"]) == z and float(r["roughness"]) > 0.001]
        n = len(cells)
        mean = {q: sum(float(r[q]) for r in cells) / n for q in QUANTITIES}
        ms = sum(float(r["E"]) - float(r["E1"]) for r in cells)
        ms_t = sum(float(r["E_T"]) - float(r["E1_T"]) for r in cells)
        ior = float(cells[0]["ior"])
        out.append({"layout": layout, "z": z, "t": cells[0]["t"],
                    "relative_index": f"{(1 / ior if layout.endswith('-inv') else ior):.9g}",
                    **{q: f"{mean[q]:.6f}" for q in QUANTITIES}, "E_ms": f"{ms / n:.6f}",
                    "E_ms_T_share": f"{ms_t / ms:.5f}",
                    "largest_se": f"{max(float(r[q + '_se']) for r in cells for q in QUANTITIES):.2g}",
                    "largest_unfinished": f"{max(float(r['unfinished']) for r in cells):.2g}"})
    return out


def main():
    args = [a for a in sys.argv[1:] if a != "--keep"]
    keep = sys.argv[sys.argv.index("--keep") + 1] if "--keep" in sys.argv else None
    if keep:
        args.remove(keep)
    microsim = os.path.realpath(args[0] if args else os.path.join(ROOT, "build", "microsim"))
    summary = []
    with tempfile.TemporaryDirectory() as tmp:
        for layout in ("cycles-glass", "cycles-glass-inv"):
            path = os.path.join(keep or tmp, f"{layout}-walk.csv")
            subprocess.run([microsim, "albedo", "--layout", layout, "--model", "smith-walk", "--rays", "100000",
                            "--seed", "1", "--walk-kernel", "lanes", "--threads", "2", "--csv", path], check=True,
                           capture_output=True)
            summary += summarise(layout, rows_of(path))
    out = os.path.join(DATA, "glass-walk-split.csv")
    with open(out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(summary[0]))
        w.writeheader()
        w.writerows(summary)
    print("| layout | relative index | E_R | E_T | E1_R | E1_T | E_ms | transmitted share of E_ms |")
    print("|---|---|---|---|---|---|---|---|")
    for s in summary:
        print(f"| {s['layout']} | {float(s['relative_index']):.4g} | {s['E_R']} | {s['E_T']} | {s['E1_R']} | "
              f"{s['E1_T']} | {s['E_ms']} | {s['E_ms_T_share']} |")
    print(f"largest node standard error: {max(float(s['largest_se']) for s in summary):.2g}; largest unfinished: "
          f"{max(float(s['largest_unfinished']) for s in summary):.2g}")


if __name__ == "__main__":
    main()
