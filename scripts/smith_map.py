#!/usr/bin/python3
"""Where Smith holds: for each assembly (and NDF matching), roughness alpha and view angle
theta, the number of rays at which a traced VNDF becomes distinguishable from Smith's VNDF, with the
surface's own NDF and with the analytic NDF.

Method. One `microsim trace vndf` per cell at R0 rays (lobe bins, the tracer's own chi-square test). The
chi-square statistic X2 with k degrees of freedom of a histogram that differs from the claimed law has
(approximately) a noncentral chi-square law with noncentrality lambda proportional to the ray count, so
lambda(R0) is estimated by X2 - k (unbiased; sd sqrt(2 (k + 2 lambda))). The ray count at which the test at
level 0.01 rejects half the time is R* = R0 lambda* / lambda(R0), lambda* the noncentrality whose
noncentral chi-square median is the level-0.01 critical value. When lambda(R0) is not 2 sd above 0 the
measurement gives only a lower bound (R* > R0 lambda* / (lambda + 2 sd)). The uncertainty interval uses
lambda +- 1 sd.

Usage:
  scripts/smith_map.py [--microsim build/microsim] [--work DIR] [--assemblies smith:radial,smith:joint]
                       [--alphas 0.05,0.1,0.3,0.5,1] [--thetas 0,15,30,45,60,75] [--res 1024] [--seed 1]
                       [--rays 4000000] [--phi 30] [--cached-only] [--reuse OLD.json] [--json map.json] [--svg map.svg]
Prints a markdown table per assembly. Cells already traced (their JSON in --work) are reused, and so are the
cells of --reuse (a --json of an earlier run) with the same assembly, match, alpha, theta, rays, resolution,
seed and phi (cells without the last three, written before they were recorded, were measured at the
defaults 1024, 1, 30).
"""
import argparse
import json
import math
import os
import subprocess
import sys

from scipy.optimize import brentq
from scipy.stats import chi2, ncx2

LEVEL = 0.01


def run(cmd):
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def surface(args, assembly, match, alpha):
    path = os.path.join(args.work, f"{assembly}-{match}-a{alpha}-n{args.res}-s{args.seed}.exr")
    if not os.path.exists(path) and not args.cached_only:
        run(["nice", "-n", "15", args.microsim, "surface", "build", "--assembly", assembly, "--alpha", str(alpha),
             "--res", str(args.res), "--seed", str(args.seed), "--ndf-match", match, "--out", path, "--quiet"])
    return path


def trace(args, surf, theta):
    base = os.path.splitext(surf)[0] + f"-t{theta}-p{args.phi}-r{args.rays}"
    js = base + ".json"
    if not os.path.exists(js) and args.cached_only:
        return None
    if not os.path.exists(js):
        run(["nice", "-n", "15", args.microsim, "trace", "vndf", "--surface", surf, "--theta", str(theta), "--phi",
             str(args.phi), "--rays", str(args.rays), "--seed", str(args.seed), "--out", base + ".exr", "--json", js])
    with open(js) as f:
        return json.load(f)


def critical_noncentrality(dof):
    """lambda* whose noncentral chi-square median is the level-LEVEL critical value."""
    c = chi2.ppf(1 - LEVEL, dof)
    return brentq(lambda lam: ncx2.median(dof, lam) - c if lam > 0 else chi2.median(dof) - c, 1e-9, 100 * c + 100)


def resolving_rays(stat, dof, rays):
    """(estimate, low, high, bound): R* and its 1-sd interval; bound = True when only a lower bound."""
    lam = stat - dof
    sd = math.sqrt(2 * (dof + 2 * max(lam, 0.0)))
    star = critical_noncentrality(dof)
    if lam < 2 * sd:
        return {"rays": rays * star / (max(lam, 0.0) + 2 * sd), "low": None, "high": None, "lower_bound": True,
                "lambda": lam, "lambda_sd": sd}
    return {"rays": rays * star / lam, "low": rays * star / (lam + sd),
            "high": rays * star / (lam - sd) if lam > sd else None, "lower_bound": False, "lambda": lam,
            "lambda_sd": sd}


def cell(args, assembly, match, alpha, theta):
    j = trace(args, surface(args, assembly, match, alpha), theta)
    if j is None:
        return None
    lobe = [c for c in j["comparisons"] if c["binning"] == "lobe"][0]
    out = {"assembly": assembly, "match": match, "alpha": alpha, "theta": theta, "rays": j["rays"],
           "res": args.res, "seed": args.seed, "phi": args.phi,
           "tv_analytic": lobe["tv_smith_analytic"], "tv_own": lobe["tv_smith_empirical"],
           "tv_noise": lobe["tv_noise_floor"]}
    for key, name in (("chi2_smith_empirical", "own"), ("chi2_smith_analytic", "analytic")):
        c = lobe[key]
        out[name] = resolving_rays(c["statistic"], c["dof"], j["rays"])
        out[name]["chi2"], out[name]["dof"], out[name]["p"] = c["statistic"], c["dof"], c["p_value"]
    return out


def reused_cell(args, old, assembly, match, alpha, theta):
    """The cell of an earlier run's JSON measured with the same parameters (None if there is none)."""
    defaults = {"res": 1024, "seed": 1, "phi": 30.0}
    for c in old:
        if (c["assembly"], c["match"], c["alpha"], c["theta"], c["rays"]) != (assembly, match, alpha, theta, args.rays):
            continue
        if all(c.get(k, defaults[k]) == getattr(args, k) for k in defaults):
            return c
    return None


def short(v):
    """2.2e6 (two significant digits, no '+' or leading zero in the exponent)."""
    if v >= 1e15:
        return "inf"
    m, e = f"{v:.1e}".split("e")
    return f"{m}e{int(e)}"


def fmt_rays(r):
    text = short(r["rays"])
    if r["lower_bound"]:
        return "> " + text
    lo, hi = r["low"], r["high"]
    return f"{text} ({short(lo)}-{short(hi)})" if hi else f"{text} ({short(lo)}-)"


def markdown(cells, alphas, thetas):
    """One table (as in docs/records/surfaces.md 8.3): a row per (assembly, match, alpha), a column per theta,
    each cell 'own NDF / analytic NDF', '-' where not measured."""
    keys = sorted({(c["assembly"], c["match"]) for c in cells}, key=lambda k: (k[0], k[1] != "radial", k[1]))
    lines = ["| assembly, match | alpha | " + " | ".join(f"theta {t:g}" for t in thetas) + " |",
             "|---|---|" + "---|" * len(thetas)]
    for a in alphas:
        for key in keys:
            row = []
            for t in thetas:
                m = [c for c in cells if (c["assembly"], c["match"]) == key and c["alpha"] == a and c["theta"] == t]
                row.append(f"{fmt_rays(m[0]['own'])} / {fmt_rays(m[0]['analytic'])}" if m else "-")
            lines.append(f"| {key[0]}, {key[1]} | {a:g} | " + " | ".join(row) + " |")
    return "\n".join(lines)


def colour(log_rays):
    """log10 rays 5 (red) .. 10 (green)."""
    f = min(1.0, max(0.0, (log_rays - 5) / 5))
    return f"rgb({int(220 * (1 - f) + 30)},{int(190 * f + 40)},{60})"


def svg(cells, alphas, thetas, path):
    keys = sorted({(c["assembly"], c["match"]) for c in cells})
    cw, ch, left, top = 52, 26, 60, 40
    pw = left + cw * len(thetas) + 20
    ph = top + ch * len(alphas) + 40
    width, height = pw * 2, ph * len(keys) + 30
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="sans-serif" '
           f'font-size="10">', f'<rect width="{width}" height="{height}" fill="white"/>']
    for i, key in enumerate(keys):
        for k, ref in enumerate(("own", "analytic")):
            x0, y0 = k * pw, i * ph
            out.append(f'<text x="{x0 + 5}" y="{y0 + 15}" font-size="11">{key[0]} {key[1]}: Smith with {ref} NDF '
                       f'(log10 rays to distinguish)</text>')
            for ti, t in enumerate(thetas):
                out.append(f'<text x="{x0 + left + ti * cw + cw / 2}" y="{y0 + top - 5}" text-anchor="middle">'
                           f'{t}&#176;</text>')
            for ai, a in enumerate(alphas):
                out.append(f'<text x="{x0 + left - 5}" y="{y0 + top + ai * ch + ch / 2 + 4}" text-anchor="end">'
                           f'a={a}</text>')
                for ti, t in enumerate(thetas):
                    m = [c for c in cells if (c["assembly"], c["match"]) == key and c["alpha"] == a and c["theta"] == t]
                    x, y = x0 + left + ti * cw, y0 + top + ai * ch
                    if not m:
                        out.append(f'<rect x="{x}" y="{y}" width="{cw - 2}" height="{ch - 2}" fill="#ddd"/>')
                        continue
                    r = m[0][ref]
                    lr = math.log10(r["rays"]) if r["rays"] > 0 else 0
                    label = (">" if r["lower_bound"] else "") + f"{lr:.1f}"
                    out.append(f'<rect x="{x}" y="{y}" width="{cw - 2}" height="{ch - 2}" fill="{colour(lr)}"/>')
                    out.append(f'<text x="{x + cw / 2 - 1}" y="{y + ch / 2 + 3}" text-anchor="middle">{label}</text>')
    out.append(f'<text x="5" y="{height - 10}">grey: not measured; ">": lower bound (the measured noncentrality is '
               f'within 2 sd of 0); colour: red 1e5 .. green 1e10 rays</text>')
    out.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--microsim", default="build/microsim")
    p.add_argument("--work", default="smith-map")
    p.add_argument("--assemblies", default="smith:radial,smith:joint")
    p.add_argument("--alphas", default="0.05,0.1,0.3,0.5,1")
    p.add_argument("--thetas", default="0,15,30,45,60,75")
    p.add_argument("--res", type=int, default=1024)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--rays", type=int, default=4000000)
    p.add_argument("--phi", type=float, default=30.0)
    p.add_argument("--cached-only", action="store_true",
                   help="only the cells whose trace JSON is in --work (the others are left out: 'not measured')")
    p.add_argument("--reuse", help="an earlier --json: its cells measured with the same parameters are kept")
    p.add_argument("--json")
    p.add_argument("--svg")
    args = p.parse_args()
    os.makedirs(args.work, exist_ok=True)
    alphas = [float(a) for a in args.alphas.split(",")]
    thetas = [float(t) for t in args.thetas.split(",")]
    old = []
    if args.reuse:
        with open(args.reuse) as f:
            old = json.load(f)
    cells = []
    for spec in args.assemblies.split(","):
        assembly, match = spec.split(":")
        for a in alphas:
            for t in thetas:
                c = reused_cell(args, old, assembly, match, a, t) or cell(args, assembly, match, a, t)
                if c is not None:
                    cells.append(c)
                    print(json.dumps(c), file=sys.stderr, flush=True)
    print(markdown(cells, alphas, thetas))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(cells, f, indent=1)
    if args.svg:
        svg(cells, alphas, thetas, args.svg)
    return 0


if __name__ == "__main__":
    sys.exit(main())
