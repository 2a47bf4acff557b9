#!/usr/bin/env bash
# Installs the Debian packages egopd needs (only those missing) and builds it (Release) into build/.
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(cmake ninja-build g++ pkg-config libgtest-dev libgmock-dev libbenchmark-dev libeigen3-dev
          libopencv-dev nlohmann-json3-dev libstb-dev libicu-dev qemu-user)
./scripts/install-packages.sh "${packages[@]}"

jobs=$(nproc 2>/dev/null || echo 2)
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
cmake --build build -j"$jobs"
