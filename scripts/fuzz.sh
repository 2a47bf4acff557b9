#!/usr/bin/env bash
# Fuzzes every parser of user files with libFuzzer (clang-14, ASan + UBSan): safetensors (header and every tensor
# read), sharded index JSON, every config reader and the hand template, the tokenizer files and text, taxel CSVs,
# --meta files and manifests, and golden case.json files.
#
#   scripts/fuzz.sh [--build DIR] [SECONDS_PER_TARGET] [TARGET...]     (default: 30 s each, every target)
#
# Without --build, the fuzz targets alone are built in build-fuzz/; --build DIR uses a build configured by
# scripts/configure-fuzz-build.sh (the test command's sanitizer build, whose tests ran under the same instrumentation).
# Seeds: tests/fuzz/corpus/<target>/ (in the repository); inputs found along the way go to DIR/corpus/<target>/.
# A crash, a sanitizer report, a hang (> 10 s for one input) or an exception other than egopd's one-line Error fails
# the script and leaves the reproducer in DIR/findings/ with the command that replays it.
set -euo pipefail
cd "$(dirname "$0")/.."
build=""
if [ "${1:-}" = "--build" ]; then
  [ -n "${2:-}" ] || { echo "fuzz.sh: --build needs a build directory" >&2; exit 2; }
  build=$2
  shift 2
fi
seconds=${1:-30}
shift || true
[[ "$seconds" =~ ^[1-9][0-9]*$ ]] || { echo "fuzz.sh: SECONDS_PER_TARGET must be a positive integer" >&2; exit 2; }
all=(safetensors sharded_index configs tokenizer taxel_csv meta case_json)
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=("${all[@]}")

jobs=$(nproc 2>/dev/null || echo 2)
if [ -z "$build" ]; then
  build=build-fuzz
  ./scripts/configure-fuzz-build.sh "$build" -DEGOPD_BUILD_TESTS=OFF -DEGOPD_BUILD_BENCH=OFF
elif ! grep -qx "EGOPD_FUZZ:BOOL=ON" "$build/CMakeCache.txt" 2>/dev/null; then
  echo "fuzz.sh: $build is not a build configured with -DEGOPD_FUZZ=ON" >&2
  exit 2
fi
cmake --build "$build" -j"$jobs" --target fuzz_all

mkdir -p "$build/findings"
failed=()
for t in "${targets[@]}"; do
  [ -x "$build/fuzz/fuzz_$t" ] || { echo "fuzz.sh: unknown target '$t' (${all[*]})" >&2; exit 2; }
  mkdir -p "$build/corpus/$t"
  echo "== fuzz_$t: ${seconds} s"
  # -fork=0: one process; findings stop the target. Seeds are read, never written (new inputs go to $build/).
  if ! ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=1 UBSAN_OPTIONS=print_stacktrace=1 \
      "$build/fuzz/fuzz_$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
      -print_final_stats=1 -artifact_prefix="$build/findings/$t-" "$build/corpus/$t" \
      "tests/fuzz/corpus/$t" >"$build/findings/$t.log" 2>&1; then
    failed+=("$t")
    echo "fuzz_$t FOUND A PROBLEM (log: $build/findings/$t.log):"
    grep -E "^(==[0-9]+==ERROR|SUMMARY|finding:|.*runtime error)" "$build/findings/$t.log" | head -5 || true
    for r in "$build/findings/$t"-*; do
      [ -f "$r" ] && echo "  reproducer: $r   replay: $build/fuzz/fuzz_$t $r"
    done
  else
    grep -E "^stat::number_of_executed_units|^#[0-9]+.*DONE" "$build/findings/$t.log" | tail -1 || true
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzzing found problems in: ${failed[*]}"
  exit 1
fi
echo "fuzzing: ${#targets[@]} targets x ${seconds} s, no findings"
