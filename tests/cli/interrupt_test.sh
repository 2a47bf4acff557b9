#!/usr/bin/env bash
# End to end: SIGTERM during `egopd predict` stops it at a safe point with exit 143 and one line, leaving the earlier
# output folder untouched and no temporary files; a full disk (emulated by a file-size limit) while writing the
# outputs fails with one line naming the file, again leaving the earlier folder and no temporaries.
# usage: interrupt_test.sh EGOPD_BINARY WORK_DIR
set -uo pipefail
egopd=$1
work=$2
rm -rf "$work"
mkdir -p "$work"
export XDG_CACHE_HOME="$work/cache"
source "$(dirname "$0")/common.sh"

"$egopd" predict --out "$work/out" --frames 4 --size 64 --threads 1 2>"$work/first.log" || fail "first run: $(tail -1 "$work/first.log")"
before=$(sha256sum "$work/out/taxels.csv")

# SIGTERM while the 25-step Euler run denoises (the built-in model is a 4-step student: --sampler euler --steps 25
# makes the run long enough to be caught mid-way).
"$egopd" predict --out "$work/out" --frames 8 --size 128 --sampler euler --steps 25 --seed 9 --threads 1 \
  2>"$work/term.log" &
pid=$!
wait_for_log "$work/term.log" "step 1/25" $pid
kill -TERM $pid
wait $pid
code=$?
[ "$code" -eq 143 ] || fail "exit code $code after SIGTERM (want 143): $(tail -2 "$work/term.log")"
last=$(tail -1 "$work/term.log")
[[ "$last" == "egopd: interrupted by SIGTERM after step "* ]] || fail "last line: $last"
[ "$(sha256sum "$work/out/taxels.csv")" = "$before" ] || fail "the earlier taxels.csv changed"
[ -z "$(find "$work" -maxdepth 2 -name '*.tmp*' -not -path "$work/cache/*")" ] || fail "temporaries left: $(find "$work" -name '*.tmp*')"

# Full disk: no file may grow beyond 8 KiB (the heatmaps, the sample clip and the video fit; taxels.csv does not).
(ulimit -f 8; exec "$egopd" predict --out "$work/out" --frames 4 --size 64 --seed 5 --threads 1) 2>"$work/full.log"
code=$?
[ "$code" -eq 1 ] || fail "exit code $code on a full disk (want 1)"
last=$(tail -1 "$work/full.log")
[[ "$last" == "egopd: $work/out/taxels.csv: write failed: "* ]] || fail "full-disk message: $last"
[ "$(sha256sum "$work/out/taxels.csv")" = "$before" ] || fail "the earlier taxels.csv changed on a full disk"
[ -z "$(find "$work" -maxdepth 2 -name '*.tmp*' -not -path "$work/cache/*")" ] || fail "temporaries left: $(find "$work" -name '*.tmp*')"
rm -rf "$work"
echo "interrupt and full-disk behaviour: ok"
