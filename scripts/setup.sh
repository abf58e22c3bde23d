#!/usr/bin/env bash
# microsim set-up: installs exactly the Debian packages the project needs (skipping those already
# present) and builds in Release into ./build. Safe to run again.
#   scripts/setup.sh            install + build
#   scripts/setup.sh --deps     install only
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)

packages=(
  build-essential cmake pkg-config
  libembree-dev libopenmesh-dev libeigen3-dev libopenexr-dev
  libtbb-dev libcli11-dev nlohmann-json3-dev libboost-math-dev libfmt-dev
  libfftw3-dev libhwy-dev     # libhwy-dev: Google Highway, portable SIMD (src/stats/direction_binner.cpp)
  libtomlplusplus-dev         # toml++: experiment specs (src/experiment/spec_toml.cpp)
  libgtest-dev libgmock-dev libbenchmark-dev
  clang libclang-rt-14-dev   # the fuzzing gate (scripts/fuzz.sh): libFuzzer
  python3-numpy              # scripts/hostile_inputs.py (/usr/bin/python3)
  chromium                   # the experiment report's real-browser test (tests/test_report_browser_cli.cpp)
  libopenmpi-dev openmpi-bin # MPI (optional in CMake): `mpirun -n P microsim run` (docs/guide/experiments-and-clusters.md)
  pybind11-dev python3-pybind11 python3-dev python3-pytest   # the Python module (src/python) and its tests
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}" >&2
  sudo_cmd=""
  [[ $(id -u) -ne 0 ]] && sudo_cmd="sudo"
  $sudo_cmd apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}"
else
  echo "setup: all Debian packages present" >&2
fi

[[ "${1:-}" == "--deps" ]] && exit 0

cmake -S "$here" -B "$here/build" -DCMAKE_BUILD_TYPE=Release
cmake --build "$here/build" -j"$(nproc)"
