#!/bin/bash
# The energy-compensation tables of docs/guide/scattering-and-energy-tables.md ("Energy-compensation tables"), written to
# docs/data/albedo-*.{exr,csv}: GGX, alphas 0.1 0.25 0.5 0.75 1, 16 Gauss-Legendre mus; the mirror from the
# analytic single scattering, the Smith random walk (4e6 paths per cell) and the explicit smith surface
# (1024^2, 1e6 paths per cell); the dielectric of eta 1.5 from outside and from inside, analytic and walk
# (1e6 paths per cell). About 2.5 minutes on 2 cores. Usage: bash scripts/albedo_tables.sh [build/microsim]
set -euo pipefail
cd "$(dirname "$0")/.."
microsim="$(realpath "${1:-build/microsim}")"
mkdir -p docs/data
cd docs/data
grid=(--alphas 0.1,0.25,0.5,0.75,1 --mus 16)

table() {  # NAME ARGS...: one table, its EXR and CSV, its stdout beside the time it took
  local name="$1"
  shift
  local start=$SECONDS
  "$microsim" albedo "${grid[@]}" "$@" --out "albedo-$name.exr" --csv "albedo-$name.csv"
  echo "albedo-$name: $((SECONDS - start)) s"
}

table ggx-mirror-analytic --model analytic
table ggx-mirror-smith-walk --model smith-walk --rays 4000000
table ggx-mirror-surface1024 --model surface --res 1024 --rays 1000000
for side in outside inside; do
  flag=()
  [ "$side" = inside ] && flag=(--inside)
  table "ggx-dielectric1.5-$side-analytic" --model analytic --material dielectric:1.5 "${flag[@]}"
  table "ggx-dielectric1.5-$side-smith-walk" --model smith-walk --material dielectric:1.5 "${flag[@]}" --rays 1000000
done
