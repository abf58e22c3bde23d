#!/usr/bin/python3
"""The planner's honesty check: does a run at FACTOR times the planned cost move the results by more
than the stated target?

  scripts/honesty_check.py SPEC --planned DIR --out DIR4 [--factor 4] [--seed S] [--binary B] [--json OUT]

DIR is the planned run of SPEC (run here with `microsim run SPEC --out DIR` if it does not exist yet). The
costly run is the same spec with every target divided by sqrt(FACTOR) and another seed (default: the spec's
+ 1000), written as JSON beside DIR4: every count rule of the planner scales as 1 / target^2 (a standard
error, a TV noise floor and a chi-square's least detectable TV all fall as 1 / sqrt(n)), so its plan is about
FACTOR times the planned cost (the ratio of the units actually run is printed). Then, measurement by
measurement (the same labels in both plans):
  albedo      each cell and E_avg the target applies to: the relative difference (against the target, a
              relative standard error) and the z-score of the difference against the two runs' combined error;
  scattering  `microsim compare-scattering` of the two scattering-K.exr over the orders the plan targeted:
              the per-order TV between the two runs (against the target, a TV to resolve);
  vndf        the TV between the two runs' normalised histograms (against the target);
  validation  both verdicts and p-values;
  masking, or a measurement not run: listed as skipped (not compared).
Reads results.json (src/experiment/results_json.cpp); prints a table, exit 0 (1 if a TV exceeds its target or
a verdict differs; 2 on bad usage, or when no measurement could be compared)."""
import argparse
import json
import math
import os
import subprocess
import sys
import tomllib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TARGET_KEYS = ("target_tv", "target_relative_error", "detect_tv")


def run(binary, spec, out, seed=None):
    cmd = [binary, "run", spec, "--out", out] + (["--seed", str(seed)] if seed else [])
    print("honesty: " + " ".join(cmd), file=sys.stderr)
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


def costly_spec(spec_path, factor, seed, where):
    with open(spec_path, "rb") as f:
        spec = json.load(f) if spec_path.endswith(".json") else tomllib.load(f)
    for q in spec.get("quantity", []):
        if "dump" in q:
            sys.exit("honesty_check: a dump's validation has the file's count; no costly run of it")
        for key in TARGET_KEYS:
            if key in q:
                q[key] = q[key] / math.sqrt(factor)
    spec["seed"] = seed if seed else spec.get("seed", 1) + 1000
    path = os.path.join(where, os.path.basename(os.path.splitext(spec_path)[0]) + f"-x{factor:g}.json")
    with open(path, "w") as f:
        json.dump(spec, f, indent=1)
    return path


def flat(values):
    if isinstance(values, list):
        return [x for v in values for x in flat(v)]
    return [values]


def albedo_rows(a, b, target):
    prefix = "E1" if a["model"] == "analytic" else "E"
    out = []
    for name in a["quantity_names"]:
        if not name.startswith(prefix) or name not in b["quantities"]:
            continue
        qa, qb = a["quantities"][name], b["quantities"][name]
        va, vb = flat(qa["value"]) + flat(qa["average"]), flat(qb["value"]) + flat(qb["average"])
        ea, eb = flat(qa["error"]) + flat(qa["average_error"]), flat(qb["error"]) + flat(qb["average_error"])
        rel = [abs(x - y) / abs(x) for x, y in zip(va, vb) if x]
        z = [abs(x - y) / math.hypot(s, t) for x, y, s, t in zip(va, vb, ea, eb) if math.hypot(s, t) > 0]
        out.append((name, len(rel), max(rel), sum(r <= target for r in rel) / len(rel), max(z) if z else 0.0))
    return out


def tv(a, b):
    sa, sb = sum(a), sum(b)
    return 0.5 * sum(abs(x / sa - y / sb) for x, y in zip(a, b))


def compare(binary, dir_a, dir_b, k, d_a, m_a, m_b):
    """(within the target, lines) for measurement k: d_a its planned decision, m_a and m_b its two results;
    None when it is not compared (not run, or a masking measurement)."""
    kind, target = d_a["kind"], d_a["target"]
    if not (m_a.get("ran") and m_b.get("ran")):
        return None, ["not compared: not run (not runnable in this version)"]
    if kind == "masking":
        return None, ["not compared: this script does not compare masking measurements yet"]
    if kind == "albedo":
        rows = albedo_rows(m_a["values"], m_b["values"], target)
        return all(r[2] <= 3 * target for r in rows), [
            f"{n}: {c} cells, largest relative difference {d:.2e} (target {target:g}), {w:.0%} within it, "
            f"largest |z| {z:.2f}" for n, c, d, w, z in rows]
    if kind == "scattering":
        orders = d_a.get("targeted_orders", [0])
        names = ",".join("5+" if o == 4 else str(o + 1) for o in orders)
        out = os.path.join(dir_b, f"compare-{k}.json")
        subprocess.run([binary, "compare-scattering", os.path.join(dir_a, f"scattering-{k}.exr"),
                        os.path.join(dir_b, f"scattering-{k}.exr"), "--orders", names, "--json", out],
                       stdout=subprocess.DEVNULL)
        with open(out) as f:
            c = json.load(f)
        tvs = [lobe["tv"] for lobe in c["comparisons"][0]["lobes"] if lobe["channel"] == "c0"]
        return max(tvs) <= target, [f"orders {names}: TV between the runs {', '.join(f'{t:.4f}' for t in tvs)} "
                                    f"(target {target:g})"]
    if kind == "vndf":
        sys.path.insert(0, os.path.join(os.path.dirname(binary), "python"))
        import microsim
        ha = microsim.read_histogram(os.path.join(dir_a, f"vndf-{k}.exr"))
        hb = microsim.read_histogram(os.path.join(dir_b, f"vndf-{k}.exr"))
        d = {name: tv(ha["binnings"][name]["counts"].ravel(), hb["binnings"][name]["counts"].ravel())
             for name in ha["binnings"]}
        return max(d.values()) <= target, [f"TV between the runs: {', '.join(f'{n} {t:.4f}' for n, t in d.items())} "
                                           f"(target {target:g})"]
    va, vb = m_a["values"]["validation"], m_b["values"]["validation"]
    return va["verdict"] == vb["verdict"], [f"verdicts {va['verdict']} / {vb['verdict']}, p {va.get('p_value', '?')} / "
                                            f"{vb.get('p_value', '?')} (detect TV {target:g})"]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("spec")
    p.add_argument("--planned", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--factor", type=float, default=4.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--binary", default=os.path.join(ROOT, "build", "microsim"))
    p.add_argument("--json")
    a = p.parse_args()
    if a.factor <= 1:
        p.error(f"--factor {a.factor}: must be > 1")
    if not os.path.exists(a.planned):
        run(a.binary, a.spec, a.planned)
    if not os.path.exists(a.out):
        os.makedirs(a.out + "-spec", exist_ok=True)
        run(a.binary, costly_spec(a.spec, a.factor, a.seed, a.out + "-spec"), a.out)
    res = [json.load(open(os.path.join(d, "results.json"))) for d in (a.planned, a.out)]
    ms = [r["results"]["measurements"] for r in res]
    decisions = res[0]["plan"]["decisions"]
    ok, report = True, []
    for k, (d_a, m_a, m_b) in enumerate(zip(decisions, *ms)):
        good, lines = compare(a.binary, a.planned, a.out, k, d_a, m_a, m_b)
        ok = ok and good is not False
        units = [m["cost"]["units"] for m in (m_a, m_b)]
        ratio = units[1] / units[0] if units[0] else float("nan")
        report.append({"measurement": m_a["measurement"], "units": units, "ok": good, "lines": lines})
        print(f"[{k}] {m_a['measurement']}: units {units[0]} -> {units[1]} (x{ratio:.2f}): {'skipped' if good is None else 'ok' if good else 'MOVED'}")
        for line in lines:
            print("     " + line)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(report, f, indent=1)
    if all(r["ok"] is None for r in report):
        print("honesty_check: no measurement was compared", file=sys.stderr)
        return 2
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
