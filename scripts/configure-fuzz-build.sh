#!/usr/bin/env bash
# Configures a clang ASan + UBSan build that also holds the libFuzzer targets (-DEGOPD_FUZZ=ON), installing clang-14
# and its runtimes if missing: the test command's sanitizer build (build-asan/) and scripts/fuzz.sh's own build.
# usage: scripts/configure-fuzz-build.sh DIR [CMAKE_ARGS...]
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -ge 1 ] || { echo "usage: scripts/configure-fuzz-build.sh DIR [CMAKE_ARGS...]" >&2; exit 2; }
dir=$1
shift
./scripts/install-packages.sh clang-14 libclang-rt-14-dev libomp-14-dev
cmake -S . -B "$dir" -G Ninja -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_BUILD_TYPE=Release \
  -DEGOPD_FUZZ=ON "$@" >/dev/null
