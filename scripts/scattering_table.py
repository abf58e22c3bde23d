#!/usr/bin/python3
"""microsim: the measured scattering table of docs/records/scattering.md.

For every configuration (assembly, alpha, theta, material) it runs, with the microsim command line:
  - `scatter --surface`: every bounce traced on an explicit heightfield of the assembly;
  - `scatter --model smith-walk`: the Smith random walk of the assembly's reference NDF (Heitz et al. 2016);
  - `scatter --model analytic`: the single-scattering BSDF binned by cubature;
  - `compare-scattering surface walk`: per-order albedo difference and TV distance of the shapes.
and writes one Markdown table (albedo per order, explicit vs walk, TV per order, and the energy that single
scattering loses and each model recovers) plus a CSV with every number and its standard error.

Run from the repository (after scripts/setup.sh):
  /usr/bin/python3 scripts/scattering_table.py [--rays N] [--res N] [--quick] [--out docs/records/scattering-table.md]
Surfaces and runs go to a work folder (default build/scattering-table), reused when a file is already there
for the same parameters (the file names carry them).
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import time

# A gold-like conductor, one (eta, k) per RGB channel (approximate values at 650, 550, 450 nm).
GOLD = "conductor:0.143,3.983;0.374,2.385;1.442,1.603"
MATERIALS = [
    ("mirror", "mirror", False),
    ("gold", GOLD, False),
    ("glass 1.5 outside", "dielectric:1.5", False),
    ("glass 1.5 inside", "dielectric:1.5", True),
]
MAIN_ASSEMBLIES = ["smith", "beckmann"]
CONTRAST_ASSEMBLIES = ["mixture", "sorted", "spikes"]  # at alpha 1 only
ALPHAS = [0.1, 0.5, 1.0]
THETAS = [0, 30, 60, 75, 85]
REFERENCE_NDF = {"beckmann": "beckmann"}  # every other assembly is GGX


CPU = {}  # CPU seconds of the commands run, by step: "surface build", "scatter --surface", ...


def step_of(cmd):
    if cmd[1] == "scatter":
        return "scatter --surface" if "--surface" in cmd else "scatter " + cmd[cmd.index("--model") + 1]
    return " ".join(cmd[1:3]) if cmd[1] == "surface" else cmd[1]


def run(cmd, ok=(0,)):
    before = os.times()
    r = subprocess.run(cmd, capture_output=True, text=True)
    after = os.times()
    step = step_of(cmd)
    CPU[step] = CPU.get(step, 0.0) + (after.children_user - before.children_user) + (
        after.children_system - before.children_system)
    if r.returncode not in ok:
        sys.exit(f"scattering_table: {' '.join(cmd)} exited {r.returncode}\n{r.stderr}")
    return r


class Table:
    def __init__(self, args):
        self.args = args
        self.exe = args.microsim
        self.work = args.work
        os.makedirs(self.work, exist_ok=True)

    def path(self, name):
        return os.path.join(self.work, name)

    def surface(self, assembly, alpha):
        out = self.path(f"surface-{assembly}-a{alpha}-r{self.args.res}.exr")
        if not os.path.exists(out):
            run([self.exe, "surface", "build", "--assembly", assembly, "--alpha", str(alpha), "--res",
                 str(self.args.res), "--seed", "1", "--quiet", "--out", out])
        return out

    def scatter(self, name, model_args, theta, material):
        out = self.path(name + ".exr")
        js = self.path(name + ".json")
        if not os.path.exists(js):
            cmd = [self.exe, "scatter", *model_args, "--theta", str(theta), "--phi", "0", "--material", material,
                   "--rows", str(self.args.rows), "--out", out, "--json", js]
            if "analytic" not in model_args:
                cmd += ["--rays", str(self.args.rays), "--seed", "1"]
            if "--surface" in model_args:
                cmd += ["--geometry", self.args.geometry]
            run(cmd)
        with open(js) as f:
            return out, json.load(f)

    def compare(self, name, a, b):
        """compare-scattering of orders 1, 2 and the total; an order with too little data for its test (exit 2,
        e.g. order 2 at normal incidence on a smooth surface) is left out and shown as a dash."""
        js = self.path(name + "-compare.json")
        for orders in ("1,2,total", "1,total", "total"):
            if os.path.exists(js):
                break
            cmd = [self.exe, "compare-scattering", a, b, "--orders", orders, "--json", js]
            if subprocess.run(cmd, capture_output=True, text=True).returncode not in (0, 1):
                continue
        if not os.path.exists(js):
            return {"comparisons": [{"lobes": []}]}
        with open(js) as f:
            return json.load(f)

    def row(self, assembly, alpha, theta_deg, label, material, inside):
        theta = 180 - theta_deg if inside else theta_deg
        ndf = REFERENCE_NDF.get(assembly, "ggx")
        tag = f"{assembly}-a{alpha}-t{theta}-{label.replace(' ', '_')}-r{self.args.res}-n{self.args.rays}"
        surf = self.surface(assembly, alpha)
        s_exr, s = self.scatter("surface-" + tag, ["--surface", surf], theta, material)
        wtag = f"walk-{ndf}-a{alpha}-t{theta}-{label.replace(' ', '_')}-n{self.args.rays}"
        w_exr, w = self.scatter(wtag, ["--model", "smith-walk", "--ndf", ndf, "--alpha", str(alpha)], theta, material)
        _, a = self.scatter(f"analytic-{ndf}-a{alpha}-t{theta}-{label.replace(' ', '_')}",
                            ["--model", "analytic", "--ndf", ndf, "--alpha", str(alpha)], theta, material)
        c = self.compare(tag, s_exr, w_exr)
        return summarise(assembly, alpha, theta_deg, label, s, w, a, c)


def albedo(summary, order, channel=0):
    e = summary["channels"][channel]["albedo"][order]["both"]
    return e["value"], e.get("standard_error", 0.0)


def tv_of(compare, order, channel=0):
    channel_name = None
    for lobe in compare["comparisons"][0]["lobes"]:
        if channel_name is None:
            channel_name = lobe["channel"]
        if lobe["channel"] == channel_name and lobe["order"] == order:
            return lobe["tv"], lobe["tv_noise_floor"], lobe["chi2"]["p_value"]
    return None, None, None


def summarise(assembly, alpha, theta, label, s, w, a, c):
    r = {"assembly": assembly, "alpha": alpha, "theta": theta, "material": label}
    for who, summary in (("explicit", s), ("walk", w)):
        for order in ("order1", "order2", "total"):
            v, e = albedo(summary, order)
            r[f"{who}_{order}"], r[f"{who}_{order}_se"] = v, e
        r[f"{who}_order3plus"] = r[f"{who}_total"] - r[f"{who}_order1"] - r[f"{who}_order2"]
        # The light that crossed the interface (a dielectric): the hemisphere the JSON says holds it.
        sides = summary.get("hemispheres", {})
        crossed = "lower" if sides.get("lower") == "transmitted" else "upper"
        r[f"{who}_transmitted"] = summary["channels"][0]["albedo"]["total"][crossed]["value"]
        r[f"{who}_unfinished"] = summary["channels"][0]["unfinished"]["value"]
        r[f"{who}_lost"] = summary["channels"][0]["lost"]["value"]
    r["analytic_order1"] = albedo(a, "order1")[0]
    for order in ("order1", "order2", "total"):
        tv, floor, p = tv_of(c, order)
        r[f"tv_{order}"], r[f"tv_{order}_floor"], r[f"chi2_p_{order}"] = tv, floor, p
    # The energy single scattering loses (for a mirror: 1 - E_ss; in general what the multiple-scattering
    # model sends out beyond order 1 of the analytic model), recovered by each measurement.
    r["explicit_recovered"] = r["explicit_total"] - r["analytic_order1"]
    r["walk_recovered"] = r["walk_total"] - r["analytic_order1"]
    return r


def fmt(v, digits=4):
    return "–" if v is None else f"{v:.{digits}f}"


def table(head, rows, cells):
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        lines.append("| " + " | ".join([r["assembly"], f"{r['alpha']:g}", f"{r['theta']:g}", r["material"]] + cells(r)) + " |")
    return lines


def markdown(rows, args, seconds):
    key = ["assembly", "alpha", "theta", "material"]
    lines = ["# The measured scattering table", "",
             f"_Recorded {time.strftime('%Y-%m-%d')}. Regenerate: `/usr/bin/python3 scripts/scattering_table.py` "
             "(writes this page and docs/data/scattering-table.csv)._", "",
             "Albedo per bounce order (E1, E2, orders 3 and up) and in total, explicit surface against the Smith walk, "
             "beside the analytic single scattering:", ""]
    lines += table(key + ["E1 analytic", "E1 explicit", "E1 walk", "E2 explicit", "E2 walk", "E3+ explicit", "E3+ walk",
                          "E explicit", "E walk"], rows,
                   lambda r: [fmt(r["analytic_order1"]), fmt(r["explicit_order1"]), fmt(r["walk_order1"]),
                              fmt(r["explicit_order2"]), fmt(r["walk_order2"]), fmt(r["explicit_order3plus"]),
                              fmt(r["walk_order3plus"]), fmt(r["explicit_total"]), fmt(r["walk_total"])])
    lines += ["", "Shapes and energy: TV distance of the explicit and walk lobes per order (its noise floor in "
              "parentheses), the transmitted albedo T of a dielectric, and the energy single scattering loses "
              "(1 - E1 analytic, for the lossless materials) that each model recovers (E - E1 analytic):", ""]
    tv = lambda r, k: "–" if r[f"tv_{k}"] is None else f"{r[f'tv_{k}']:.3f} ({r[f'tv_{k}_floor']:.3f})"
    lines += table(key + ["TV1", "TV2", "TV all", "T explicit", "T walk", "SS loss", "recovered explicit",
                          "recovered walk"], rows,
                   lambda r: [tv(r, "order1"), tv(r, "order2"), tv(r, "total"), fmt(r["explicit_transmitted"]),
                              fmt(r["walk_transmitted"]), "–" if r["material"] == "gold" else fmt(1 - r["analytic_order1"]), fmt(r["explicit_recovered"]),
                              fmt(r["walk_recovered"])])
    se = max(max(r["explicit_total_se"], r["walk_total_se"], r["explicit_order1_se"]) for r in rows)
    lines.append("")
    lines.append(f"{len(rows)} configurations, {args.rays} paths per run, surfaces {args.res}^2 (seed 1), "
                 f"{args.rows} rows per hemisphere; largest standard error of an albedo {se:.1e}; "
                 f"{seconds:.0f} s wall on this machine. Gold: channel R of {GOLD}.")
    if CPU:
        lines += ["", f"CPU seconds of the commands this run executed (a file already in the work folder is reused, "
                  f"not timed), explicit surfaces traced with `--geometry {args.geometry}`: "
                  + ", ".join(f"{step} {cpu:.0f} s" for step, cpu in sorted(CPU.items(), key=lambda kv: -kv[1]))
                  + f"; total {sum(CPU.values()):.0f} s."]
    return "\n".join(lines) + "\n"


def configurations(quick):
    for assembly in MAIN_ASSEMBLIES:
        for alpha in ALPHAS if not quick else [0.5]:
            for theta in THETAS if not quick else [30, 75]:
                for label, material, inside in MATERIALS:
                    yield assembly, alpha, theta, label, material, inside
    for assembly in CONTRAST_ASSEMBLIES if not quick else []:
        for theta in THETAS:
            for label, material, inside in MATERIALS:
                yield assembly, 1.0, theta, label, material, inside


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--microsim", default="build/microsim")
    p.add_argument("--rays", type=int, default=1000000)
    p.add_argument("--res", type=int, default=1024)
    p.add_argument("--rows", type=int, default=8)
    p.add_argument("--geometry", default="pyramid", help="the explicit surfaces' tracer (scatter --geometry)")
    p.add_argument("--work", default="build/scattering-table")
    p.add_argument("--out", default="docs/records/scattering-table.md")
    p.add_argument("--csv", default="docs/data/scattering-table.csv")
    p.add_argument("--quick", action="store_true", help="a few configurations only (a smoke run)")
    args = p.parse_args()
    table = Table(args)
    start = time.time()
    rows = []
    for i, config in enumerate(configurations(args.quick)):
        rows.append(table.row(*config))
        print(f"scattering_table: {i + 1} {config[:4]} explicit {rows[-1]['explicit_total']:.4f} "
              f"walk {rows[-1]['walk_total']:.4f}", file=sys.stderr)
    seconds = time.time() - start
    with open(args.out + ".tmp", "w") as f:
        f.write(markdown(rows, args, seconds))
    os.replace(args.out + ".tmp", args.out)
    os.makedirs(os.path.dirname(args.csv) or ".", exist_ok=True)
    with open(args.csv + ".tmp", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    os.replace(args.csv + ".tmp", args.csv)
    print(f"scattering_table: wrote {args.out} and {args.csv} ({seconds:.0f} s)", file=sys.stderr)


if __name__ == "__main__":
    main()
