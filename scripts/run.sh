#!/usr/bin/env bash
# microsim: installs what is missing, builds in Release and runs the main job: the statistical
# validation of the whole sampler zoo (`microsim validate --all`), with its report in out/.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
bash "$here/scripts/setup.sh" --target microsim  # the command line only: not the tests and benchmarks
mkdir -p "$here/out"
"$here/build/microsim" validate --all --json "$here/out/validate-all.json" "$@"
