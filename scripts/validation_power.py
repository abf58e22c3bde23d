#!/usr/bin/python3
"""The power of an experiment's planned validation, measured (docs/records/experiments.md, "Its power, measured").

The planner (src/experiment/plan.h, validation_samples) asks for N = lambda / (4 d^2) samples so that ANY
deviation of total variation d in a binning is detected with the asked power: a deviation q of a
distribution p has the chi-square noncentrality lambda = N sum (q - p)^2 / p >= 4 N TV^2 (Cauchy-Schwarz),
with equality for q_i = p_i (1 + delta s_i), s_i = +-1 splitting p's mass in halves (TV = delta / 2). This
script draws that least detectable deviation and counts how often the validator rejects it:
  - samples of heitz2018 (correct for GGX; `microsim.sample`), each kept with probability
    (1 + delta s) / (1 + delta), s = sign(m.y): the VNDF of a view at phi 0 is symmetric in y, so each
    half holds mass 1/2, and y = 0 is a bin edge of both the sphere and the lobe binnings (their 2 rows
    sectors start at phi 0), so the binned TV is delta / 2 = d exactly;
  - N = the planned count (`microsim plan --json` of a spec with that detect_tv);
  - R repetitions, each its own seed; the share rejected at the spec's level, with a 95% Wilson interval;
  - controls: delta = 0 (the correct sampler: rejected at about the level) and d / 2 (power well below).
Usage: scripts/validation_power.py [--tv 0.01] [--repeats 100] [--alpha 0.3] [--theta 40] [--rows 15]
                                   [--no-controls] [--json OUT]
The microsim Python module is found in build/python (or $MICROSIM_PYTHONPATH)."""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.environ.get("MICROSIM_PYTHONPATH", os.path.join(ROOT, "build", "python")))
import microsim  # noqa: E402


def planned_samples(binary, tv, alpha, theta, rows, power, level):
    """The planner's sample count for detect_tv = tv (microsim plan --json)."""
    spec = (f'[[material]]\nname = "m"\nalphas = [{alpha}]\ntype = "mirror"\n[[quantity]]\nkind = "validation"\n'
            f'material = "m"\nsampler = "heitz2018"\ntheta = [{theta}]\nrows = {rows}\ndetect_tv = {tv}\n'
            f'power = {power}\nsignificance = {level}\n')
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "power.toml")
        with open(path, "w") as f:
            f.write(spec)
        out = os.path.join(tmp, "plan.json")
        done = subprocess.run([binary, "plan", path, "--json", out], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                              text=True)
        if done.returncode != 0:
            sys.exit(f"validation_power: microsim plan failed ({done.returncode}): {done.stderr.strip()}")
        with open(out) as f:
            return int(json.load(f)["plan"]["decisions"][0]["units"])


def deviated_samples(n, delta, alpha, theta, seed):
    """n samples of heitz2018 reweighted by (1 + delta sign(m.y)) (rejection; the first n kept)."""
    rng = np.random.default_rng(seed)
    wi = np.array([math.sin(math.radians(theta)), 0.0, math.cos(math.radians(theta))])
    kept = []
    have = 0
    while have < n:
        batch = min(int((n - have) * (1 + abs(delta)) * 1.05) + 1000, 1 << 22)  # bounded memory per draw
        m, _ = microsim.sample("heitz2018", np.tile(wi, (batch, 1)), alpha, rng.random((batch, 2)))
        m = m[np.isfinite(m).all(axis=1)]
        keep = rng.random(len(m)) < (1 + delta * np.sign(m[:, 1])) / (1 + abs(delta))
        kept.append(m[keep])
        have += int(keep.sum())
    return np.concatenate(kept)[:n]


def wilson(k, n, z=1.96):
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def rejection_rate(n, delta, a):
    rejected = 0
    for r in range(a.repeats):
        samples = deviated_samples(n, delta, a.alpha, a.theta, seed=1000003 * (r + 1) + int(delta * 1e6))
        result = microsim.validate(samples, a.alpha, a.theta, rows=a.rows, significance=a.level)
        rejected += 0 if result.passed else 1
    low, high = wilson(rejected, a.repeats)
    return {"delta": delta, "binned_tv": delta / 2, "rejected": rejected, "repeats": a.repeats,
            "rate": rejected / a.repeats, "wilson95": [low, high]}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tv", type=float, default=0.01, help="detect_tv of the planned validation")
    p.add_argument("--repeats", type=int, default=100)
    p.add_argument("--alpha", type=float, default=0.3)
    p.add_argument("--theta", type=float, default=40.0)
    p.add_argument("--rows", type=int, default=15)
    p.add_argument("--power", type=float, default=0.9)
    p.add_argument("--level", type=float, default=0.01)
    p.add_argument("--binary", default=os.path.join(ROOT, "build", "microsim"))
    p.add_argument("--json", help="write the results here")
    p.add_argument("--no-controls", action="store_true", help="only the deviation of TV --tv (not d / 2 and 0)")
    a = p.parse_args()
    if not (0 < a.tv < 0.5) or a.repeats < 1:
        p.error(f"--tv {a.tv} must be in (0, 0.5) and --repeats {a.repeats} at least 1")
    n = planned_samples(a.binary, a.tv, a.alpha, a.theta, a.rows, a.power, a.level)
    rows = [rejection_rate(n, delta, a) for delta in ((2 * a.tv,) if a.no_controls else (2 * a.tv, a.tv, 0.0))]
    print(f"planned: {n} samples to detect TV {a.tv} with power {a.power} at level {a.level} "
          f"(alpha {a.alpha}, theta {a.theta}, rows {a.rows})")
    print("| binned TV | rejected | rate | 95% interval |\n|---|---|---|---|")
    for r in rows:
        print(f"| {r['binned_tv']:g} | {r['rejected']} / {r['repeats']} | {r['rate']:.3f} | "
              f"{r['wilson95'][0]:.3f} - {r['wilson95'][1]:.3f} |")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"planned_samples": n, "args": vars(a), "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
