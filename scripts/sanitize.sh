#!/usr/bin/env bash
# microsim: the sanitizer gate. Builds the library and the CLI with AddressSanitizer and UBSan
# (-fsanitize=address,undefined, every report fatal) and the library's tests with ASan alone (UBSan there
# would check the tests' own code: CMakeLists.txt) in build-sanitize/ with g++, the library at -O1 -g1
# (ASan's stacks keep file and line; MICROSIM_SANITIZE_DEBUG=-g0, as CI runs it, compiles about 11% faster:
# UBSan's reports still name file and line, ASan's stacks name functions), the library's tests at -Og (their
# own loops call the microfacet functions millions of times: at -O0 they ran 5-14 times slower under ASan,
# e.g. ValidateFilePdf.EachDensityPassesItsOwnSamplesAndRejectsAnother 97 s against 7 s; -Og compiles them in
# 40% less time than -O1 and runs them as fast: docs/records/reliability.md), the command line
# (apps/) at -O0 (it only parses, checks and reports; -O0 compiles it 2-3 times faster), and runs the ctest
# suite there; any sanitizer report fails a
# test and so this script. The tests that drive the command line are not compiled again: the Release
# build's microsim_cli_tests (built here if missing) runs against the instrumented `microsim`
# (MICROSIM_CLI_TESTS_EXECUTABLE, CMakeLists.txt), one ctest test per TEST as in the Release suite. (clang 14 builds this
# configuration about 30% faster, but its seeded outputs are not the bits the regression pins recorded
# with g++: 6 pin and streaming tests fail there; not investigated yet, so the gate stays on g++.)
# MICROSIM_SANITIZE_UBSAN=trap (CI) makes UBSan's checks traps: a failed check aborts with ASan's stack of
# function names instead of UBSan's report, GCC leaves out the vptr check, and each instrumented process starts
# in about half the time (no 53 MB of check data to scan and fault in); the default, report, keeps both.
#   scripts/sanitize.sh            configure, build, run every test
#   scripts/sanitize.sh -R REGEX   only the tests matching REGEX (passed to ctest)
#   scripts/sanitize.sh -LE sanitize-skip   the CI gate: all but the tests labelled sanitize-skip (tests/labels.cmake)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
bash "$here/scripts/setup.sh" --deps
build="$here/build-sanitize"
launcher=()
command -v ccache > /dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
[[ -f "$here/build/CMakeCache.txt" ]] || cmake -S "$here" -B "$here/build" -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build "$here/build" -j"$(nproc)" --target microsim_cli_tests
debug=${MICROSIM_SANITIZE_DEBUG:--g1}
[[ "$debug" == -g0 || "$debug" == -g1 ]] || { echo "sanitize.sh: MICROSIM_SANITIZE_DEBUG=$debug (-g0 or -g1)" >&2; exit 2; }
ubsan=${MICROSIM_SANITIZE_UBSAN:-report}
case "$ubsan" in
  report) trap_checks=OFF ;;
  trap) trap_checks=ON ;;
  *) echo "sanitize.sh: MICROSIM_SANITIZE_UBSAN=$ubsan (report or trap)" >&2; exit 2 ;;
esac
cmake -S "$here" -B "$build" -DCMAKE_CXX_COMPILER=g++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 $debug -DNDEBUG" -DMICROSIM_FRONT_END_OPT=-O0 -DMICROSIM_LIBRARY_TESTS_OPT=-Og \
  -DMICROSIM_SANITIZE=ON -DMICROSIM_SANITIZE_UBSAN_TRAP=$trap_checks \
  -DMICROSIM_BUILD_BENCHMARKS=OFF -DMICROSIM_CLI_TESTS_EXECUTABLE="$here/build/microsim_cli_tests" \
  "${launcher[@]}" > /dev/null
cmake --build "$build" -j"$(nproc)"
# halt_on_error + abort: a report ends the process with a non-zero status, never a silent warning;
# handle_sigill: a trapped UBSan check (MICROSIM_SANITIZE_UBSAN=trap) is reported with its stack.
# detect_leaks stays on (the default); UBSan prints a stack for each report. Stack use after return (fake
# stack frames for every call; off by default in GCC's ASan) made the gate's tests about 1.5 times slower
# (SmithWalkEval.MatchesTheBinnedWalkPerOrderAndInTotal 16.9 s with it, 11.7 s without): CI leaves it off
# to stay in its time budget; MICROSIM_SANITIZE_STACK_AFTER_RETURN=1 turns it on (docs/records/reliability.md:
# the whole gate passed with it on 2026-12-03).
after_return=0
[[ "${MICROSIM_SANITIZE_STACK_AFTER_RETURN:-0}" == 1 ]] && after_return=1
export ASAN_OPTIONS=halt_on_error=1:abort_on_error=1:detect_stack_use_after_return=$after_return:strict_string_checks=1:handle_sigill=1
export UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
ctest --test-dir "$build" --output-on-failure -j"$(nproc)" --timeout 1800 "$@"
