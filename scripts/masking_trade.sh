#!/usr/bin/env bash
# microsim: regenerates the measurements of docs/records/heightfield-trade.md (the speed/accuracy trade of the
# heightfield surface) and the masking table of docs/records/masking-table.md. Every number comes from the CLI:
#   microsim trace masking --table   (builds the surfaces in memory, traces VNDF and masking per view)
#   microsim surface build           (build time and peak RSS per resolution)
#   microsim trace masking --surface (tracing a stored 4096^2 tile: peak RSS, rays per second)
# Usage: scripts/masking_trade.sh [OUTDIR] [PART...]
#   parts: table joint table1 res corr tile seeds build big backface (default: all but backface and joint)
# Runtime on 2 cores (shared, loaded): table ~35 min, table1 ~20 min, the trade parts ~30 min, big ~10 min.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
B=${MICROSIM:-$here/build/microsim}
out=${1:-$here/out/masking}
shift || true
parts=${*:-table table1 res corr tile seeds build big}
mkdir -p "$out"
has() { [[ " $parts " == *" $1 "* ]]; }
tm() { /usr/bin/time -f "%e s wall, %U s user, peak RSS %M KiB" "$@"; }
trade() {  # name res corr
  tm "$B" trace masking --table --assemblies smith --alphas 0.5 --thetas 60,75,85 --res "$2" --corr-cells "$3" \
    --samples 1000000 --vndf-rays 2000000 --markdown "$out/$1.md" --json "$out/$1.json" > /dev/null 2> "$out/$1.log"
}

# The masking table (docs/reference/masking.md): 5 assemblies x alpha {0.1, 0.5, 1} x theta {30, 60, 75, 85}, three
# realisations (seeds 1, 2, 3) per cell, 5e5 surface points and 1e6 VNDF rays per view and realisation.
has table && tm "$B" trace masking --table --res 1024 --seeds 1,2,3 --samples 500000 --vndf-rays 1000000 \
  --markdown "$out/table-1024-seeds123.md" --json "$out/table-1024-seeds123.json" > /dev/null 2> "$out/table-1024-seeds123.log"
# The same for `smith` with the NDF matched bin by bin (docs/records/masking-table.md 6.3, `--ndf-match joint`).
has joint && tm "$B" trace masking --table --assemblies smith --ndf-match joint --res 1024 --seeds 1,2,3 --samples 500000 \
  --vndf-rays 1000000 --markdown "$out/table-joint-1024-seeds123.md" --json "$out/table-joint-1024-seeds123.json" \
  > /dev/null 2> "$out/table-joint-1024-seeds123.log"
# The one-realisation table (seed 1, 1e6 points and 2e6 VNDF rays per view).
has table1 && tm "$B" trace masking --table --res 1024 --markdown "$out/table-1024.md" --json "$out/table-1024.json" \
  > /dev/null 2> "$out/table-1024.log"
# Resolution at a fixed correlation length of 16 cells (tile = N/16 correlation lengths).
if has res; then for n in 256 512 2048; do trade "res-$n-l16" "$n" 16; done; fi
# Correlation length in cells at N = 1024 (discretisation of a feature vs tile size in features).
if has corr; then for c in 4 8 32; do trade "res-1024-l$c" 1024 "$c"; done; fi
# Fixed tile of 64 correlation lengths, finer and finer cells.
if has tile; then trade "res-256-l4" 256 4; trade "res-512-l8" 512 8; trade "res-2048-l32" 2048 32; fi
# Seed-to-seed spread at the default setting (realisations of the same random surface).
if has seeds; then
  tm "$B" trace masking --table --assemblies smith --alphas 0.5 --thetas 60,75,85 --res 1024 --corr-cells 16 --seeds 1,2,3 \
    --samples 1000000 --vndf-rays 2000000 --markdown "$out/res-1024-l16-seeds123.md" --json "$out/res-1024-l16-seeds123.json" \
    > /dev/null 2> "$out/res-1024-l16-seeds123.log"
fi
# Build time and peak RSS of the surface itself.
if has build; then
  for n in 256 1024 4096; do
    tm "$B" surface build --assembly smith --alpha 0.5 --res "$n" --out "$out/smith-$n.exr" > "$out/build-$n.txt" 2> "$out/build-$n.log" || true
  done
fi
# A 4096^2 tile traced with both Embree geometries (peak RSS, build and tracing rates).
if has big; then
  for g in triangles grid; do
    tm "$B" trace masking --surface "$out/smith-4096.exr" --theta 75 --phi 30 --samples 1000000 --vndf-rays 2000000 \
      --geometry "$g" --json "$out/big-4096-$g.json" > "$out/big-4096-$g.txt" 2> "$out/big-4096-$g.log"
  done
fi
# Back-facing first hits (convex-edge grazes, docs/records/heightfield-trade.md section 1): the VNDF diagnostics of
# `trace vndf --surface` (back-facing hits left, grazes passed over) at the steepest views.
if has backface; then
  "$B" surface build --assembly smith --alpha 1 --res 1024 --seed 1 --out "$out/smith-a1-1024.exr" > /dev/null 2>&1
  for th in 75 85; do
    "$B" trace vndf --surface "$out/smith-a1-1024.exr" --theta "$th" --phi 30 --rays 8000000 --out "$out/backface-$th.exr" \
      --json "$out/backface-$th.json" > "$out/backface-$th.txt" 2> "$out/backface-$th.log"
  done
fi
echo "done: $out"
