#!/usr/bin/env bash
# AArch64 (64-bit ARM) cross-build and test run on an x86-64 Debian machine: installs the cross compiler, the arm64
# libraries (multiarch) and qemu-user, builds into build-arm64/ with cmake/toolchain-aarch64-linux-gnu.cmake, and runs
# every unit and golden test under user-mode emulation twice: on the NEON kernel path, then on the portable one.
#
# OpenCV's arm64 development packages cannot be installed beside the amd64 ones (they conflict file by file), so
# libopencv-dev:arm64 and its dependencies are extracted (not installed) into build-arm64/opencv-root/ with
# mmdebstrap, from the machine's own Debian sources; nothing is left out of the full build (--quick builds only the
# tests it runs and the egopd command).
#
# usage: scripts/test-arm64.sh [--quick] [ctest arguments...]
#   --quick (what the test command runs): every kernel, model-component and golden test and the command-line basics,
#   on both paths; the pipeline, batch, converter and API tests (end-to-end runs, several minutes each under
#   emulation, and the same code on every CPU) and the Winograd accuracy check on the models' real layer shapes
#   (~20 minutes emulated; the same transforms are checked on awkward shapes) run only without --quick.
# Batch.MemoryStaysFlatOverFiftyClips never runs here: under qemu-user the resident set includes the emulator's
# growing translation cache (and 50 clips take ~20 minutes); it runs natively in the x86-64 test run.
set -euo pipefail
quick=0
if [ "${1:-}" = "--quick" ]; then
  quick=1
  shift
fi
cd "$(dirname "$0")/.."
start=$(date +%s)
jobs=$(nproc 2>/dev/null || echo 2)
build=build-arm64

sudo=""
[ "$(id -u)" -ne 0 ] && sudo="sudo"
if ! dpkg --print-foreign-architectures | grep -qx arm64; then
  echo "adding the arm64 architecture to dpkg (multiarch)"
  $sudo dpkg --add-architecture arm64
  $sudo apt-get update -qq
fi
./scripts/install-packages.sh cmake ninja-build g++-aarch64-linux-gnu qemu-user mmdebstrap nlohmann-json3-dev \
  libeigen3-dev libstb-dev libicu-dev:arm64 libgomp1:arm64 libgtest-dev:arm64 libgmock-dev:arm64

opencv_root=$build/opencv-root
if [ ! -e "$opencv_root/.complete" ]; then
  echo "extracting libopencv-dev:arm64 and its dependencies into $opencv_root (takes a few minutes)"
  rm -rf "$opencv_root"
  mkdir -p "$build"
  suite=$(. /etc/os-release && echo "$VERSION_CODENAME")
  $sudo mmdebstrap --quiet --variant=extract --architectures=arm64 --include=libopencv-dev \
    --skip=check/empty "$suite" "$opencv_root"
  touch "$opencv_root/.complete"
fi
# Libraries the extraction brought along that multiarch has installed too (libgomp, ICU): the installed ones are
# used, so that no directory of the build's run paths shadows the system's (CMake warns of each such conflict).
for lib in "$opencv_root"/usr/lib/aarch64-linux-gnu/*.so.*; do
  if [ ! -d "$lib" ] && [ -e "/usr/lib/aarch64-linux-gnu/$(basename "$lib")" ]; then rm -f "$lib"; fi
done

cmake -S . -B $build -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_TOOLCHAIN_FILE="$PWD/cmake/toolchain-aarch64-linux-gnu.cmake" \
  -DEGOPD_ARM64_EXTRA_ROOT="$PWD/$opencv_root" -DEGOPD_BUILD_BENCH=OFF >/dev/null
targets=()
if [ $quick = 1 ]; then  # only what the quick run runs: the tests of these labels and the egopd command
  targets=(--target egopd tests_core tests_scheduler tests_pressure tests_unet3d tests_vae tests_clip tests_golden)
fi
cmake --build $build -j"$jobs" "${targets[@]}"
built=$(date +%s)

# The emulated CPU: qemu's default ("max") has every ARMv8.x extension; the kernels use only ARMv8.0-A but for the
# int8 kernel's ARMv8.2 dot product (sdot), taken where the CPU reports it: the neon run tests it, the portable run
# the scalar emulation CPUs without it use. The binaries run through the wrappers the build generates (qemu-aarch64
# with the extracted libraries on its library path).
export OMP_WAIT_POLICY=passive
version=$($build/tests/emulated/egopd --version)
echo "== $version =="
case "$version" in
  *"kernels: neon"*) ;;
  *) echo "test-arm64: egopd --version under qemu-aarch64 does not name the neon path" >&2; exit 1 ;;
esac
exclude="Batch.MemoryStaysFlatOverFiftyClips"
# The kernel and golden tests run every path the CPU has whatever EGOPD_KERNELS says: once is enough.
every_path="^Paths/|GoldenCaseTest"
status=0
for path in neon portable; do
  select=()
  if [ $quick = 1 ]; then
    select=(-L "^(core|scheduler|pressure|unet3d|vae|clip|golden)$")
    [ $path = portable ] && select=(-L "^(core|scheduler|pressure|unet3d|vae|clip)$")
  fi
  skip="$exclude"
  [ $quick = 1 ] && skip="$skip|^WinogradRealShapes"
  [ $path = portable ] && skip="$skip|$every_path"
  echo "== unit and golden tests under qemu-aarch64, EGOPD_KERNELS=$path$([ $quick = 1 ] && echo ' (quick)') =="
  t0=$(date +%s)
  EGOPD_KERNELS=$path ctest --test-dir $build --output-on-failure -j"$jobs" "${select[@]}" -E "$skip" "$@" || status=1
  if [ $quick = 1 ]; then
    EGOPD_KERNELS=$path ctest --test-dir $build --output-on-failure -R '^cli_(version|unknown_option|missing_case_json)$' \
      "$@" || status=1
  fi
  echo "   ($path: $(( $(date +%s) - t0 )) s)"
done
echo "arm64: build $(( built - start )) s, tests $(( $(date +%s) - built )) s, total $(( $(date +%s) - start )) s"
exit $status
