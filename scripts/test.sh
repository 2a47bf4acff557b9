#!/usr/bin/env bash
# The test command: install what is missing, build (Release), run every unit and golden test; install the build into
# a temporary prefix and build and run the C example and the Python module's tests against it
# (tests/install/install_test.sh); then build the tests again with clang, AddressSanitizer and
# UndefinedBehaviorSanitizer in build-asan/ (on a CPU without AVX-512, with the avx512 path emulated), run them there
# too and fuzz every parser for a bounded time with the same build (scripts/fuzz.sh); then run a Slurm job array on a
# one-node local cluster (tests/slurm/slurm_test.sh); last, cross-build for AArch64 and run the kernel,
# model-component and golden tests under qemu-aarch64 on the neon and portable paths (scripts/test-arm64.sh --quick).
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc 2>/dev/null || echo 2)
# Tests run in parallel, each with up to 2 OpenMP threads: sleeping (not spinning) idle workers keeps the
# oversubscribed cores busy with real work.
export OMP_WAIT_POLICY=passive

./scripts/build.sh
ctest --test-dir build --output-on-failure -j"$jobs"

echo "== install: the C example against an installed prefix (pkg-config, find_package), the Python module =="
./scripts/install-packages.sh python3 python3-numpy python3-pytest python3-matplotlib python3-pip python3-setuptools
tests/install/install_test.sh build build/install_test_work

echo "== sanitizer build (ASan + UBSan, clang) and its tests =="
# One clang build serves the sanitizer test run and the fuzzers (libFuzzer is clang's): every test runs under ASan +
# UBSan, then every fuzz target. On a CPU without AVX-512 this build emulates the avx512 path (SIMDe; README,
# "Commands"), so that its code, BF16 and VNNI micro-kernels included, runs under every kernel and golden test (they
# run every available path) on every machine, and under the sanitizers; where the CPU has AVX-512 the native path
# runs here instead. egopd's own CPU check decides (AVX-512 F, BW, VL and DQ, enabled by the OS), not one flag of
# /proc/cpuinfo.
emulate_avx512=ON
case "$(env -u EGOPD_KERNELS build/bin/egopd --version)" in
  *"kernels: avx512"*) emulate_avx512=OFF ;;
esac
if [ $emulate_avx512 = ON ]; then ./scripts/install-packages.sh libsimde-dev; fi
./scripts/configure-fuzz-build.sh build-asan -DEGOPD_BUILD_BENCH=OFF -DEGOPD_EMULATE_AVX512=$emulate_avx512
cmake --build build-asan -j"$jobs"
if [ $emulate_avx512 = ON ]; then EGOPD_KERNELS=avx512 build-asan/bin/egopd --version; fi
# Not under the sanitizers: the Winograd accuracy test on the real layer shapes (pure arithmetic on large buffers, 166 s
# there and the run's long pole; its small-shape siblings run under them, and it runs in the Release pass above).
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build-asan --output-on-failure -j"$jobs" -E 'WinogradRealShapes'

echo "== fuzzing: every parser of user files, 20 s each (libFuzzer, ASan + UBSan) =="
./scripts/fuzz.sh --build build-asan 20

echo "== Slurm: a job array on a one-node local cluster =="
if [ "$(id -u)" -eq 0 ]; then
  tests/slurm/slurm_test.sh build/bin/egopd build/slurm_test_work
elif [ "${CI:-}" = "true" ]; then
  sudo -E tests/slurm/slurm_test.sh build/bin/egopd build/slurm_test_work
else
  echo "skipped: the local Slurm cluster needs root (run: sudo tests/slurm/slurm_test.sh)"
fi

echo "== AArch64: cross-build, kernel, component and golden tests under qemu-aarch64 (neon and portable paths) =="
./scripts/test-arm64.sh --quick
