#!/usr/bin/python3
"""The Smith walk's two kernels side by side in one bench_walk binary (docs/records/walk-speed.md, "Third round").

Runs BM_WalkKernels (1 thread: the scalar walk, kernel 0; the walk in SIMD lanes on the CPU's best target,
kernel 1, and on AVX2, kernel 2) for each material, the kernels one after the other, their order reversed
from round to round, ROUNDS times, and prints per round and as medians the paths per CPU second (the
process's CPU time: on a loaded machine the wall clock also counts the time others hold the core), the
ratios lanes / scalar per round, and the load average before and after. When the binary was built with
MICROSIM_HEITZ2016_DIR, BM_Heitz2016Paths (the Heitz et al. 2016 supplemental code: mirror and dielectric)
runs in the same rounds, right after the kernels, as a reference point.

  scripts/bench_walk_kernels.py build/bench_walk [--rounds 7] [--min-time 0.5]
"""
import argparse
import json
import os
import statistics
import subprocess
import sys

PATHS_PER_ITERATION = 64 * 4096  # BM_WalkKernels: 64 blocks of kPathsPerBlock paths
MATERIALS = {0: "mirror", 1: "dielectric 1.5", 2: "gold (3 channels)"}
KERNELS = {0: "scalar", 1: "lanes", 2: "lanes AVX2"}


def run_once(binary, material, kernel, min_time):
    """(paths per CPU second, paths per wall second, label) of one run of BM_WalkKernels (kernel "heitz":
    BM_Heitz2016Paths), or None when the binary has no such benchmark."""
    name = (f"BM_Heitz2016Paths/material:{material}/" if kernel == "heitz"
            else f"BM_WalkKernels/material:{material}/kernel:{kernel}/")
    out = subprocess.run([binary, f"--benchmark_filter={name}", f"--benchmark_min_time={min_time}",
                          "--benchmark_format=json"], check=True, capture_output=True, text=True).stdout
    found = json.loads(out)["benchmarks"] if out.strip() else []  # no match: Google Benchmark prints nothing
    if not found:
        return None
    b = found[0]
    scale = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}[b["time_unit"]]
    return (PATHS_PER_ITERATION / (b["cpu_time"] * scale), PATHS_PER_ITERATION / (b["real_time"] * scale),
            b.get("label", ""))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("binary")
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--min-time", type=float, default=0.5)
    args = parser.parse_args()
    load_before = os.getloadavg()
    cpu = {(m, k): [] for m in MATERIALS for k in KERNELS}
    ratios = {m: [] for m in MATERIALS}
    ratios_avx2 = {m: [] for m in MATERIALS}
    labels = {}
    for r in range(args.rounds):
        order = list(KERNELS) if r % 2 == 0 else list(reversed(KERNELS))
        for m, name in MATERIALS.items():
            got = {}
            for k in order:
                rate, _, label = run_once(args.binary, m, k, args.min_time)
                got[k] = rate
                cpu[(m, k)].append(rate)
                labels[(m, k)] = label
            heitz = run_once(args.binary, m, "heitz", args.min_time) if m in (0, 1) else None
            if heitz:
                cpu.setdefault((m, "heitz"), []).append(heitz[0])
            ratios[m].append(got[1] / got[0])
            ratios_avx2[m].append(got[2] / got[0])
            print(f"round {r + 1} {name}: scalar {got[0] / 1e6:.2f} lanes {got[1] / 1e6:.2f} lanes AVX2 "
                  f"{got[2] / 1e6:.2f} M paths per CPU s, ratios {ratios[m][-1]:.2f} {ratios_avx2[m][-1]:.2f}",
                  flush=True)
    load_after = os.getloadavg()
    print(f"\nload average (1, 5, 15 min) before {load_before[0]:.1f} {load_before[1]:.1f} {load_before[2]:.1f}, "
          f"after {load_after[0]:.1f} {load_after[1]:.1f} {load_after[2]:.1f}")
    print(f"medians over {args.rounds} rounds (M paths per CPU second, 1 thread; ns per path):")
    print("| material | scalar | lanes | lanes / scalar (range) | lanes AVX2 | AVX2 / scalar (range) | lanes' label |")
    print("|---|---|---|---|---|---|---|")
    for m, name in MATERIALS.items():
        s, l, a = (statistics.median(cpu[(m, k)]) for k in KERNELS)
        print(f"| {name} | {s / 1e6:.2f} ({1e9 / s:.0f} ns) | {l / 1e6:.2f} ({1e9 / l:.0f} ns) | "
              f"**{statistics.median(ratios[m]):.2f}x** ({min(ratios[m]):.2f}-{max(ratios[m]):.2f}) | "
              f"{a / 1e6:.2f} ({1e9 / a:.0f} ns) | {statistics.median(ratios_avx2[m]):.2f}x "
              f"({min(ratios_avx2[m]):.2f}-{max(ratios_avx2[m]):.2f}) | {labels[(m, 1)]} |")
    if (0, "heitz") in cpu:
        print("\nthe Heitz 2016 code in the same rounds (M paths per CPU second; lanes / Heitz per round):")
        for m in (0, 1):
            h = cpu[(m, "heitz")]
            per_round = [l / x for l, x in zip(cpu[(m, 1)], h)]
            print(f"| {MATERIALS[m]} | Heitz 2016 {statistics.median(h) / 1e6:.2f} ({1e9 / statistics.median(h):.0f} ns) "
                  f"| lanes / Heitz {statistics.median(per_round):.2f}x ({min(per_round):.2f}-{max(per_round):.2f}) "
                  f"| scalar / Heitz {statistics.median(s / x for s, x in zip(cpu[(m, 0)], h)):.2f}x |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
