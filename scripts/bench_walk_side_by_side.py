#!/usr/bin/python3
"""The Smith walk's paths per second, two bench_walk binaries side by side (docs/records/walk-speed.md).

Runs BM_WalkPaths on 1 thread (mirror and dielectric) of each binary in turn, ROUNDS times, so that both
see the same load of a shared machine, and prints per round and as medians the paths per CPU second
(the process's CPU time: on a loaded machine the wall clock also counts the time others hold the core)
and per wall-clock second, and the ratio NEW / OLD. When NEW was built with MICROSIM_HEITZ2016_DIR, its
BM_Heitz2016Paths (the Heitz et al. 2016 supplemental code on the same configuration) runs in the same
rounds and NEW / Heitz 2016 is printed too.

  scripts/bench_walk_side_by_side.py OLD/bench_walk NEW/bench_walk [--rounds 5] [--min-time 0.5]

OLD is typically bench_walk built from an earlier commit in a worktree of its own:
  git worktree add /tmp/walk-old COMMIT && cmake -S /tmp/walk-old -B /tmp/walk-old/build \\
      -DCMAKE_BUILD_TYPE=Release && cmake --build /tmp/walk-old/build --target bench_walk
"""
import argparse
import json
import statistics
import subprocess
import sys

PATHS_PER_ITERATION = 64 * 4096  # BM_WalkPaths: 64 blocks of kPathsPerBlock paths
MATERIALS = {0: "mirror", 1: "dielectric 1.5"}


def run_once(binary, min_time, heitz=False):
    """{material: (paths per CPU second, paths per wall second)} of one run of BM_WalkPaths on 1 thread, or
    with heitz of BM_Heitz2016Paths ({} when the binary was built without it)."""
    name = "BM_Heitz2016Paths/material:[01]/" if heitz else "BM_WalkPaths/material:[01]/threads:1"
    out = subprocess.run([binary, f"--benchmark_filter={name}", f"--benchmark_min_time={min_time}",
                          "--benchmark_format=json"], check=True, capture_output=True, text=True).stdout
    rates = {}
    for b in json.loads(out)["benchmarks"]:
        material = int(b["name"].split("material:")[1].split("/")[0])
        scale = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}[b["time_unit"]]
        # real_time and cpu_time are per iteration.
        rates[material] = (PATHS_PER_ITERATION / (b["cpu_time"] * scale),
                           PATHS_PER_ITERATION / (b["real_time"] * scale))
    return rates


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("old")
    parser.add_argument("new")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--min-time", type=float, default=0.5)
    args = parser.parse_args()
    ratios = {m: [] for m in MATERIALS}
    cpu = {(m, k): [] for m in MATERIALS for k in ("old", "new")}
    wall = {(m, k): [] for m in MATERIALS for k in ("old", "new")}
    for r in range(args.rounds):
        # Alternate which binary goes first, so that neither always meets the same phase of the load.
        order = [("old", args.old), ("new", args.new)] if r % 2 == 0 else [("new", args.new), ("old", args.old)]
        got = {k: run_once(b, args.min_time) for k, b in order}
        heitz = run_once(args.new, args.min_time, heitz=True)
        for m in heitz:
            cpu.setdefault((m, "heitz"), []).append(heitz[m][0])
            wall.setdefault((m, "heitz"), []).append(heitz[m][1])
        for m, name in MATERIALS.items():
            for k in ("old", "new"):
                cpu[(m, k)].append(got[k][m][0])
                wall[(m, k)].append(got[k][m][1])
            ratios[m].append(got["new"][m][0] / got["old"][m][0])
            print(f"round {r + 1} {name}: old {got['old'][m][0] / 1e6:.2f} new {got['new'][m][0] / 1e6:.2f} "
                  f"M paths per CPU s, ratio {ratios[m][-1]:.2f}", flush=True)
    print("\nmedians over rounds (M paths/s on 1 thread; CPU time, then wall clock):")
    print("| material | old (CPU) | new (CPU) | ratio (CPU) | ratio range | old (wall) | new (wall) |")
    print("|---|---|---|---|---|---|---|")
    for m, name in MATERIALS.items():
        med = lambda k, d: statistics.median(d[(m, k)]) / 1e6
        print(f"| {name} | {med('old', cpu):.2f} | {med('new', cpu):.2f} | {statistics.median(ratios[m]):.2f}x | "
              f"{min(ratios[m]):.2f}-{max(ratios[m]):.2f}x | {med('old', wall):.2f} | {med('new', wall):.2f} |")
    if (0, "heitz") in cpu:
        print("\nthe Heitz 2016 code in the same rounds (M paths per CPU s; new / Heitz per round):")
        for m, name in MATERIALS.items():
            per_round = [n / h for n, h in zip(cpu[(m, "new")], cpu[(m, "heitz")])]
            print(f"| {name} | Heitz 2016 {statistics.median(cpu[(m, 'heitz')]) / 1e6:.2f} | new / Heitz "
                  f"{statistics.median(per_round):.2f}x ({min(per_round):.2f}-{max(per_round):.2f}x) | old / Heitz "
                  f"{statistics.median(o / h for o, h in zip(cpu[(m, 'old')], cpu[(m, 'heitz')])):.2f}x |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
