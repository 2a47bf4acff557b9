#!/usr/bin/env bash
# Runs Google Benchmark binaries alternately, ROUNDS times each, and prints per benchmark and binary the minimum and
# the median of its real times. On shared hosts whose speed drifts by tens of percent within minutes, ratios taken
# this way (same filter, binaries interleaved) are stable where runs minutes apart are not.
# usage: bench/alternate.sh ROUNDS FILTER BINARY... (environment passed through, e.g. EGOPD_CONV=direct, and
#        `env -u OPENBLAS_CORETYPE` where the shell pins OpenBLAS to a core type)
# example: bench/alternate.sh 5 'conv3x3/n:2/.*v:1/' build/bin/kernels_bench /tmp/kernels_bench_before
set -euo pipefail
if [ $# -lt 3 ]; then
  sed -n '2,7p' "$0" >&2
  exit 1
fi
rounds=$1 filter=$2
shift 2
times=$(mktemp)
trap 'rm -f "$times"' EXIT
for ((r = 0; r < rounds; ++r)); do
  for b in "$@"; do
    "$b" --benchmark_filter="$filter" --benchmark_min_time=0.3 2>/dev/null |
      awk -v bin="$b" '$1 ~ /^BM_/ && $3 ~ /^(ns|us|ms|s)$/ {print bin, $1, $2, $3}' >>"$times"
  done
done
/usr/bin/python3 - "$times" <<'PY'
import collections, statistics, sys
runs = collections.defaultdict(list)
for line in open(sys.argv[1]):
    binary, name, time, unit = line.split()
    runs[(name, binary)].append((float(time), unit))
for (name, binary), ts in sorted(runs.items()):
    values = [t for t, _ in ts]
    print(f"{name:70s} {binary:30s} min {min(values):9.3f} median {statistics.median(values):9.3f} {ts[0][1]} (n={len(values)})")
PY
