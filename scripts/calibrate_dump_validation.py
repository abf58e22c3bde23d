#!/usr/bin/python3
"""microsim: how often `validate` rejects a correct renderer dump (the false-rejection rate at its level).

Writes RUNS dumps of a correct renderer's samples (seeds SEED0, SEED0 + 1, ...), validates each with
`--above-horizon --dropped N` (or as --convention says), and prints how many runs were rejected (exit 1) against the level's expectation,
and per test the fraction of runs with p below the level and below the per-test Sidak level. The dumps go to a
temporary folder, removed at the end. Records: docs/records/validation.md.
- `--material conductor` (default): the gold conductor of examples/renderer_dump.py (float32 .npy), validated
  as the README's Example 2 does (`--bsdf conductor --eta 0.2 --k 3.9`).
- `--material dielectric`: the rough glass of `renderer_dump` in tests/python/test_renderer_conventions.py
  (kind 'dielectric', eta 1.5, pbrt-v4's radiance transport and height-correlated G2, its lost samples dropped;
  imported, PYTHONPATH=build/python is added), saved as .npy of --dtype (default float32) and validated as that
  test file does (`--bsdf dielectric:1.5`); with `--convention mitsuba`, Mitsuba 3's instead: separable G1 G1 and
  its lost samples kept as rows of weight 0 (`--masking separable --lost-as-zero-weight`); with `--normals ndf`, its
  normals drawn from D(m) cos (`--sampling ndf`; the weights, heavy-tailed then, are not tested: columns
  x,y,z,pdf,-). It also prints the report's test keys, the statistical tests
  taken from it, and which tests the rejected runs failed.
--rows is passed to validate when given (else validate's default, 31); --jobs runs that many validations at
once; --p-values CSV writes each run's seed, exit code and p-values.
Usage: /usr/bin/python3 scripts/calibrate_dump_validation.py [--material conductor|dielectric] [--runs 300]
       [--samples 30000] [--seed0 20000] [--alpha 0.3] [--theta 60] [--rows R] [--dtype float32|float64]
       [--convention pbrt|mitsuba] [--normals vndf|ndf] [--jobs 1] [--p-values CSV] [--microsim build/microsim]
"""
import argparse
import concurrent.futures
import json
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TESTS = ("chi2_sphere", "chi2_lobe", "bsdf_albedo", "bsdf_bins", "dropped_fraction")
GLASS_ETA = 1.5


def conductor_dump(dump, seed, a):
    out = subprocess.run([sys.executable, os.path.join(ROOT, "examples", "renderer_dump.py"), dump, "--alpha",
                          str(a.alpha), "--theta", str(a.theta), "--samples", str(a.samples), "--seed", str(seed)],
                         check=True, capture_output=True, text=True).stdout
    dropped = re.search(r"dropped below the horizon: (\d+)", out).group(1)
    return ["--above-horizon", "--dropped", dropped], ["--bsdf", "conductor", "--eta", "0.2", "--k", "3.9"]


def dielectric_dump(dump, seed, a):
    import numpy as np
    for path in (os.path.join(ROOT, "build", "python"), os.path.join(ROOT, "tests", "python")):
        if path not in sys.path:
            sys.path.insert(0, path)
    import test_renderer_conventions as trc
    from conftest import view
    mitsuba = a.convention == "mitsuba"
    directions, pdfs, weights, dropped = trc.renderer_dump(
        "dielectric", view(a.theta), (a.alpha, a.alpha), eta=GLASS_ETA, seed=seed, n=a.samples,
        masking="separable" if mitsuba else "height-correlated", lost="zero-weight" if mitsuba else "dropped",
        normals=a.normals)
    np.save(dump, np.column_stack([directions, pdfs, weights]).astype(a.dtype))
    claims = ["--masking", "separable", "--lost-as-zero-weight"] if mitsuba else ["--above-horizon", "--dropped",
                                                                                  str(dropped)]
    if a.normals == "ndf":
        claims += ["--sampling", "ndf"]
    return claims, ["--bsdf", f"dielectric:{GLASS_ETA}"]


def validate_one(tmp, seed, a):
    dump = os.path.join(tmp, f"dump-{seed}.npy")
    lost, bsdf = (dielectric_dump if a.material == "dielectric" else conductor_dump)(dump, seed, a)
    report = os.path.join(tmp, f"report-{seed}.json")
    rows = ["--rows", str(a.rows)] if a.rows else []
    columns = "x,y,z,pdf,-" if a.normals == "ndf" else "x,y,z,pdf,weight"
    rc = subprocess.run([a.microsim, "validate", "--from", dump, "--alpha", str(a.alpha), "--theta", str(a.theta),
                         "--columns", columns, *bsdf, *lost, *rows,
                         "--json", report], capture_output=True).returncode
    if rc not in (0, 1):
        sys.exit(f"validate exited {rc} for seed {seed}")
    with open(report) as f:
        tests = json.load(f)["tests"]
    os.remove(dump)
    os.remove(report)
    if a.material == "conductor":
        return rc, {t: tests[t]["p_value"] for t in TESTS}, None
    # The dielectric's report: every test with a p-value is statistical (the Sidak family); failed: its tests that
    # did not pass (a chi-square says 'rejected', a check 'passed').
    failed = sorted(t for t, v in tests.items() if v.get("rejected") is True or v.get("passed") is False)
    return rc, {t: v["p_value"] for t, v in tests.items() if "p_value" in v}, (sorted(tests), failed)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--material", choices=["conductor", "dielectric"], default="conductor")
    p.add_argument("--runs", type=int, default=300)
    p.add_argument("--samples", type=int, default=30000)
    p.add_argument("--seed0", type=int, default=20000)
    p.add_argument("--alpha", type=float, default=0.3)
    p.add_argument("--theta", type=float, default=60.0)
    p.add_argument("--level", type=float, default=0.01)
    p.add_argument("--rows", type=int, help="rows of validate's sphere and lobe binnings (default: validate's)")
    p.add_argument("--dtype", choices=["float32", "float64"], default="float32",
                   help="the dielectric dump's storage (the conductor's example writes float32)")
    p.add_argument("--convention", choices=["pbrt", "mitsuba"], default="pbrt",
                   help="the dielectric's: pbrt-v4 (lost samples dropped, height-correlated) or Mitsuba 3's")
    p.add_argument("--normals", choices=["vndf", "ndf"], default="vndf",
                   help="the dielectric's sampled normals: visible (default) or D(m) cos (directions and pdfs tested)")
    p.add_argument("--jobs", type=int, default=1, help="validations run at once")
    p.add_argument("--p-values", help="write seed, exit code and each test's p-value per run to this CSV")
    p.add_argument("--microsim", default=os.path.join(ROOT, "build", "microsim"))
    a = p.parse_args()
    if a.material == "conductor" and a.dtype != "float32":
        p.error("--dtype is for --material dielectric (examples/renderer_dump.py writes float32)")
    if a.material == "conductor" and (a.convention != "pbrt" or a.normals != "vndf"):
        p.error("--convention and --normals are for --material dielectric")
    seeds = range(a.seed0, a.seed0 + a.runs)
    with tempfile.TemporaryDirectory() as tmp:
        if a.jobs > 1:
            with concurrent.futures.ProcessPoolExecutor(a.jobs) as pool:
                results = list(pool.map(validate_one, [tmp] * a.runs, seeds, [a] * a.runs))
        else:
            results = [validate_one(tmp, seed, a) for seed in seeds]
    found = results[0][1]  # the dielectric's statistical tests, in the conductor's order, any other after
    tests = TESTS if a.material == "conductor" else (tuple(t for t in TESTS if t in found)
                                                      + tuple(sorted(t for t in found if t not in TESTS)))
    rejected, ps = 0, {t: [] for t in tests}
    for rc, p_values, _ in results:
        rejected += rc == 1
        for t in tests:
            ps[t].append(p_values[t])
    if a.p_values:
        with open(a.p_values, "w") as f:
            f.write(",".join(["seed", "exit", *tests]) + "\n")
            for seed, (rc, p_values, _) in zip(seeds, results):
                f.write(",".join([str(seed), str(rc), *(repr(p_values[t]) for t in tests)]) + "\n")
    per_test = 1 - (1 - a.level) ** (1 / len(tests))
    if a.material == "dielectric":
        print(f"report tests: {', '.join(results[0][2][0])}; statistical (with a p-value): {', '.join(tests)}")
        print(f"{a.runs} correct rough-dielectric dumps ({a.convention}, normals {a.normals}, eta {GLASS_ETA}, {a.dtype}) of {a.samples} samples "
              f"(alpha {a.alpha}, theta {a.theta}, seeds {a.seed0}.., rows {a.rows or 'default'}): "
              f"{rejected} rejected at level {a.level} (expected about {a.level * a.runs:.1f})")
    else:
        print(f"{a.runs} correct dumps of {a.samples} samples (alpha {a.alpha}, theta {a.theta}, seeds {a.seed0}..): "
              f"{rejected} rejected at level {a.level} (expected about {a.level * a.runs:.1f})")
    for t in tests:
        frac = lambda level: sum(x < level for x in ps[t]) / a.runs
        print(f"  {t:18s} p < {a.level}: {frac(a.level):.3f}   p < {per_test:.4f} (Sidak): {frac(per_test):.3f}")
    if a.material == "dielectric":
        by = {}
        for rc, _, (_, failed) in results:
            for t in failed if rc == 1 else []:
                by[t] = by.get(t, 0) + 1
        print("  rejected runs' failed tests: " + (", ".join(f"{t} {n}" for t, n in sorted(by.items())) or "none"))


if __name__ == "__main__":
    main()
