#!/usr/bin/python3
"""microsim: how often `validate` rejects a correct renderer dump (the false-rejection rate at its level).

Writes RUNS dumps of the correct gold conductor of examples/renderer_dump.py (seeds SEED0, SEED0 + 1, ...),
validates each as the README's Example 2 does (`--bsdf conductor --above-horizon --dropped N`), and prints
how many runs were rejected (exit 1) against the level's expectation, and per test the fraction of runs
with p below the level and below the per-test Sidak level. The dumps go to a temporary folder, removed at
the end. Records: docs/records/validation.md.
Usage: /usr/bin/python3 scripts/calibrate_dump_validation.py [--runs 300] [--samples 30000] [--seed0 20000]
       [--alpha 0.3] [--theta 60] [--microsim build/microsim]
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TESTS = ("chi2_sphere", "chi2_lobe", "bsdf_albedo", "bsdf_bins", "dropped_fraction")


def validate_one(tmp, seed, a):
    dump = os.path.join(tmp, "dump.npy")
    out = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "renderer_dump.py"), dump, "--alpha",
                          str(a.alpha), "--theta", str(a.theta), "--samples", str(a.samples), "--seed", str(seed)],
                         check=True, capture_output=True, text=True).stdout
    dropped = re.search(r"dropped below the horizon: (\d+)", out).group(1)
    report = os.path.join(tmp, "report.json")
    rc = subprocess.run([a.microsim, "validate", "--from", dump, "--alpha", str(a.alpha), "--theta", str(a.theta),
                         "--columns", "x,y,z,pdf,weight", "--bsdf", "conductor", "--eta", "0.2", "--k", "3.9",
                         "--above-horizon", "--dropped", dropped, "--json", report],
                        capture_output=True).returncode
    if rc not in (0, 1):
        sys.exit(f"validate exited {rc} for seed {seed}")
    with open(report) as f:
        tests = json.load(f)["tests"]
    return rc, {t: tests[t]["p_value"] for t in TESTS}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=300)
    p.add_argument("--samples", type=int, default=30000)
    p.add_argument("--seed0", type=int, default=20000)
    p.add_argument("--alpha", type=float, default=0.3)
    p.add_argument("--theta", type=float, default=60.0)
    p.add_argument("--level", type=float, default=0.01)
    p.add_argument("--microsim", default=os.path.join(ROOT, "build", "microsim"))
    a = p.parse_args()
    rejected, ps = 0, {t: [] for t in TESTS}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(a.seed0, a.seed0 + a.runs):
            rc, p_values = validate_one(tmp, seed, a)
            rejected += rc == 1
            for t in TESTS:
                ps[t].append(p_values[t])
    per_test = 1 - (1 - a.level) ** (1 / len(TESTS))
    print(f"{a.runs} correct dumps of {a.samples} samples (alpha {a.alpha}, theta {a.theta}, seeds {a.seed0}..): "
          f"{rejected} rejected at level {a.level} (expected about {a.level * a.runs:.1f})")
    for t in TESTS:
        frac = lambda level: sum(x < level for x in ps[t]) / a.runs
        print(f"  {t:18s} p < {a.level}: {frac(a.level):.3f}   p < {per_test:.4f} (Sidak): {frac(per_test):.3f}")


if __name__ == "__main__":
    main()
