#!/usr/bin/env bash
# The main job on the built-in default: builds egopd if needed, then predicts grasp pressure for a generated sample
# clip with a tiny synthetic EgoPressureDiff model (random weights: the numbers show the pipeline works, they are not
# meaningful pressures). Outputs go to out/demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/build.sh
./build/bin/egopd predict --out out/demo "$@"
