#!/usr/bin/env bash
# The main job on the built-in default: builds egopd if needed, then runs it.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/build.sh
mkdir -p out
./build/bin/egopd forward --case tests/data/golden/unet --output out/unet_golden.safetensors --check
echo "outputs written to out/unet_golden.safetensors"
