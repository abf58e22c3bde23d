#!/usr/bin/env bash
# microsim: the sanitizer gate. Builds the test suite and the CLI with AddressSanitizer and UBSan
# (-fsanitize=address,undefined, every report fatal) in build-sanitize/ with g++, the library at -O1 -g1
# (the reports keep file and line) and the front ends (apps/ and the tests that drive the command line,
# microsim_cli_tests) at -O0 (they only parse, check and report; -O0 compiles them 2-3 times faster), and
# runs the ctest suite there; any sanitizer report fails a test and so this script. (clang 14 builds this
# configuration about 30% faster, but its seeded outputs are not the bits the regression pins recorded
# with g++: 6 pin and streaming tests fail there; not investigated yet, so the gate stays on g++.)
#   scripts/sanitize.sh            configure, build, run every test
#   scripts/sanitize.sh -R REGEX   only the tests matching REGEX (passed to ctest)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
bash "$here/scripts/setup.sh" --deps
build="$here/build-sanitize"
launcher=()
command -v ccache > /dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
cmake -S "$here" -B "$build" -DCMAKE_CXX_COMPILER=g++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" -DMICROSIM_FRONT_END_OPT=-O0 -DMICROSIM_SANITIZE=ON \
  -DMICROSIM_BUILD_BENCHMARKS=OFF "${launcher[@]}" > /dev/null
cmake --build "$build" -j"$(nproc)"
# halt_on_error + abort: a report ends the process with a non-zero status, never a silent warning.
# detect_leaks stays on (the default); UBSan prints a stack for each report.
export ASAN_OPTIONS=halt_on_error=1:abort_on_error=1:detect_stack_use_after_return=1:strict_string_checks=1
export UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
ctest --test-dir "$build" --output-on-failure -j"$(nproc)" --timeout 1800 "$@"
