#!/bin/bash
# microsim: the fuzzing gate (docs/records/reliability.md). Configures and builds the libFuzzer targets of
# tests/fuzz with clang (ASan + UBSan, build folder build-fuzz), then runs each for SECONDS seconds from its
# seed corpus in tests/fuzz/corpus/<target> (new inputs go to a scratch corpus, the repository is not
# touched), MICROSIM_FUZZ_JOBS (default 2) at a time, and prints executions per target. Exit 1 on any
# crash, leak, timeout, out-of-memory or failed property (a single allocation over 256 MB from an input of
# a few KB counts as out-of-memory); the input that triggered it is left in build-fuzz/findings/<target>/.
#   scripts/fuzz.sh [SECONDS_PER_TARGET]   (default 300; CI: scripts/fuzz.sh 10)
set -euo pipefail
seconds=${1:-300}
root=$(cd "$(dirname "$0")/.." && pwd)
build=${MICROSIM_FUZZ_BUILD:-$root/build-fuzz}
jobs=${MICROSIM_FUZZ_JOBS:-2}

# New build folders use Ninja, as in scripts/setup.sh.
command -v ninja > /dev/null && export CMAKE_GENERATOR=${CMAKE_GENERATOR:-Ninja}
launcher=()
if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
CXX=clang++ cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMICROSIM_FUZZ=ON \
  -DMICROSIM_BUILD_TESTS=OFF -DMICROSIM_BUILD_BENCHMARKS=OFF "${launcher[@]}" >/dev/null
cmake --build "$build" --target fuzz_all -j"$jobs" >/dev/null

# Inputs up to these many bytes: enough for every seed and for what each format can say.
declare -A max_len=([npy]=4096 [text]=4096 [histogram_exr]=16384 [heightmap_exr]=16384 [scatter_exr]=16384 [numbers]=256)
# The targets run $jobs at a time (each is one single-threaded process); the verdicts print in a fixed order.
targets=(npy text histogram_exr heightmap_exr scatter_exr numbers)
run_target() {
  local target=$1 work="$build/fuzz-corpus/$1" findings="$build/findings/$1"
  mkdir -p "$work" "$findings"
  local status=0
  "$build/fuzz_$target" -max_total_time="$seconds" -max_len="${max_len[$target]}" -rss_limit_mb=2048 \
    -malloc_limit_mb=256 -timeout=10 -print_final_stats=1 -artifact_prefix="$findings/" "$work" \
    "$root/tests/fuzz/corpus/$target" >"$build/findings/$target.log" 2>&1 || status=$?
  echo "$status" >"$build/findings/$target.status"
}
for ((i = 0; i < ${#targets[@]}; i += jobs)); do
  for target in "${targets[@]:i:jobs}"; do run_target "$target" & done
  wait
done
status=0
for target in "${targets[@]}"; do
  log="$build/findings/$target.log"
  if [[ "$(cat "$build/findings/$target.status")" == 0 ]]; then
    verdict="0 crashes"
  else
    verdict="FAILED (see $log and $build/findings/$target/)"
    status=1
  fi
  execs=$(grep -m1 '^stat::number_of_executed_units' "$log" | awk '{print $2}' || true)
  printf 'fuzz_%-14s %10s executions in %ss: %s\n' "$target" "${execs:-?}" "$seconds" "$verdict"
done
exit $status
