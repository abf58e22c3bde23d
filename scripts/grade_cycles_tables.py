#!/usr/bin/python3
"""Grade Blender Cycles' shipped energy-compensation tables (docs/records/energy-tables.md).

Reads Cycles' `shader.tables` (intern/cycles/scene/shader.tables in blender/blender, src/scene/shader.tables in
the standalone Cycles repository), takes its arrays table_ggx_E (32 x 32), table_ggx_glass_E and
table_ggx_glass_inv_E (16 x 16 x 16) as text, and runs

  microsim albedo --grade TABLE.txt --layout cycles|cycles-glass|cycles-glass-inv --tolerance T
                  --table-samples 8388608 --json ...

(2^23 samples per node: cycles_precompute.cpp's count for these tables), then prints, per index slice of the
glass tables, the largest |table - reference| and how many nodes lie beyond the tolerance and beyond the
noise of the stated sample count. About 4 minutes on 2 cores (the glass references are most of it).

Usage: /usr/bin/python3 scripts/grade_cycles_tables.py SHADER_TABLES [build/microsim] [--tolerance 1e-4]
Exit: 0 when every table passes, 1 when one does not, 2 when the file lacks a table.
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TABLES = [("ggx_E", "cycles"), ("ggx_glass_E", "cycles-glass"), ("ggx_glass_inv_E", "cycles-glass-inv")]


def array_text(source, name):
    m = re.search(r"table_%s\[\d+\]\s*=\s*\{(.*?)\};" % re.escape(name), source, re.S)
    if m is None:
        sys.exit(f"grade_cycles_tables: no table_{name} in the file")
    return m.group(1).strip() + "\n"


def slice_summary(grade):
    by_z = {}
    for c in grade["cells"]:
        if c.get("graded", True):
            by_z.setdefault(c["z"], []).append(c)
    for z in sorted(by_z):
        cells = by_z[z]
        worst = max(cells, key=lambda c: abs(c["value"] - c["reference"]))
        off = sum(not c["within_tolerance"] for c in cells)
        noisy = sum(not c["within_noise"] for c in cells)
        print(f"  z {z:2d} ior {worst['ior']:.6g}: max |table - reference| {abs(worst['value'] - worst['reference']):.3g} "
              f"(alpha {worst['alpha']:.3g}, mu {worst['mu']:.3g}: {worst['value']:.6f} for {worst['reference']:.6f}); "
              f"beyond tolerance {off}, beyond noise {noisy} of {len(cells)}")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("tables", help="Cycles' shader.tables")
    p.add_argument("microsim", nargs="?", default=os.path.join(ROOT, "build", "microsim"))
    p.add_argument("--tolerance", default="1e-4")
    args = p.parse_args()
    with open(args.tables) as f:
        source = f.read()
    failed = False
    with tempfile.TemporaryDirectory() as tmp:
        for name, layout in TABLES:
            table, report = os.path.join(tmp, name + ".txt"), os.path.join(tmp, name + ".json")
            with open(table, "w") as f:
                f.write(array_text(source, name))
            r = subprocess.run([args.microsim, "albedo", "--grade", table, "--layout", layout, "--tolerance",
                                args.tolerance, "--table-samples", str(1 << 23), "--json", report],
                               capture_output=True, text=True)
            if r.returncode not in (0, 1):
                sys.exit(f"grade_cycles_tables: {layout}: exit {r.returncode}\n{r.stderr}")
            failed |= r.returncode == 1
            with open(report) as f:
                grade = json.load(f)
            print(f"{name} ({layout}): {'PASS' if r.returncode == 0 else 'FAIL'}, max {grade['max_abs']:.3g}, "
                  f"RMS {grade['rms']:.3g}")
            if "cells" in grade and grade["cells"] and "z" in grade["cells"][0]:
                slice_summary(grade)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
