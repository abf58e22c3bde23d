#!/usr/bin/env bash
# microsim: which smith tile serves which sample count as a reference of `validate --against` (the reference
# bias of docs/reference/validator.md). For each tile size and seed: build a `smith` tile (GGX alpha 0.1,
# --ndf-match joint), trace its visible normals at theta 30 (4e6 rays, the pyramid tracer), then validate
# heitz2018 (exact) and heitz2018-talk (the negative control) against it with 1e6 samples, and print one row:
# the exit codes, the p-values, and the largest sample count the trace serves as D_v.
#   scripts/tile_reference_sizes.sh [BINARY] [SIZES] [SEEDS]     (defaults: build/microsim "1024 2048" "1 2 3")
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
bin=${1:-$here/build/microsim}
sizes=${2:-1024 2048}
seeds=${3:-1 2 3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
json_field() { /usr/bin/python3 -c "import json,sys; j=json.load(open(sys.argv[1])); print(j$2)" "$1" 2>/dev/null || echo "-"; }
echo "| N | seed | trace s | heitz2018: exit, p | talk: exit, p | reference bias (exact sampler's rejection probability at 1e6) / samples served |"
echo "|---|---|---|---|---|---|"
for n in $sizes; do
  for s in $seeds; do
    "$bin" surface build --assembly smith --alpha 0.1 --ndf-match joint --res "$n" --seed "$s" --out "$work/s.exr" --quiet > /dev/null
    t0=$(date +%s.%N)
    "$bin" trace vndf --surface "$work/s.exr" --theta 30 --rays 4000000 --seed "$s" --geometry pyramid \
      --out "$work/h.exr" > /dev/null 2>&1
    t1=$(date +%s.%N)
    row="| $n | $s | $(printf '%.1f' "$(echo "$t1 - $t0" | bc)") |"
    for sampler in heitz2018 heitz2018-talk; do
      set +e
      "$bin" validate --sampler "$sampler" --alpha 0.1 --theta 30 --samples 1000000 --against "$work/h.exr" \
        --json "$work/v.json" > /dev/null 2> "$work/err.txt"
      code=$?
      set -e
      if [[ $code == 2 ]]; then
        row+=" 2 (refused) |"
        served=$(grep -o 'serves at most [0-9]* samples' "$work/err.txt" | grep -o '[0-9]*' || echo "?")
        bias="refused, serves $served"
      else
        row+=" $code, $(json_field "$work/v.json" "['p_value']") |"
        bias="$(json_field "$work/v.json" "['tests']['reference_bias']['value']") / $(json_field "$work/v.json" \
          "['tests']['reference_bias']['detail'].split('serves ')[-1]")"
      fi
      rm -f "$work/v.json"
    done
    echo "$row $bias |"
  done
done
