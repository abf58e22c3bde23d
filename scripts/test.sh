#!/usr/bin/env bash
# microsim: installs what is missing, builds in Release and runs the whole test suite with ctest.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
bash "$here/scripts/setup.sh"
ctest --test-dir "$here/build" --output-on-failure -j"$(nproc)" --timeout 900
