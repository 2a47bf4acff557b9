#!/usr/bin/env bash
# A real Slurm run on a one-node local cluster: scripts/slurm/submit.sh runs a 3-task array over 6 tiny clips;
# one task is cancelled (scancel) in the middle of a clip; the same command is submitted again. Checks: every clip
# was done exactly once (counted in the task logs) and none failed or was left half-written; the outputs equal a
# single-process `egopd batch` byte for byte (summary.json without its timings and peak RSS, which differ from
# run to run); the aggregation job's table equals `egopd evaluate --manifest` on the same outputs.
# usage: tests/slurm/slurm_test.sh [EGOPD_BINARY] [WORK_DIR]   (root: it starts slurmctld, slurmd and munged)
set -uo pipefail
repo=$(cd "$(dirname "$0")/../.." && pwd)
egopd=$(realpath "${1:-$repo/build/bin/egopd}")
work=${2:-$repo/build/slurm_test_work}
source "$repo/tests/cli/common.sh"
rm -rf "$work"
mkdir -p "$work"
work=$(realpath "$work")
export XDG_CACHE_HOME=$work/cache OMP_WAIT_POLICY=passive
unset SLURM_ARRAY_TASK_ID SLURM_ARRAY_TASK_COUNT SLURM_CPUS_PER_TASK EGOPD_THREADS
start=$(date +%s)
"$repo/scripts/install-packages.sh" python3  # compares summary.json files

# The cluster's state in a short /tmp path (munge's socket path has a length limit); always taken down.
export EGOPD_SLURM_DIR
EGOPD_SLURM_DIR=$(mktemp -d /tmp/egopd-slurm.XXXXXX)
trap '"$repo/scripts/slurm/local-cluster.sh" down >/dev/null 2>&1' EXIT
"$repo/scripts/slurm/local-cluster.sh" up || fail "the local cluster did not start"
eval "$("$repo/scripts/slurm/local-cluster.sh" env)"

# Six clips of the built-in sample clip under different prompts; ground truth: a taxel CSV per clip.
"$egopd" predict --out "$work/demo" --size 128 --frames 8 --threads 1 2>"$work/demo.log" || fail "demo: $(tail -1 "$work/demo.log")"
models=("$XDG_CACHE_HOME"/egopd/tiny-synthetic-f32-lcm4-seed0-*)  # named by synthetic_model_id
model=${models[0]}
[ ${#models[@]} -eq 1 ] && [ -f "$model/model_index.json" ] || fail "no single built-in model in $XDG_CACHE_HOME/egopd"
for i in 1 2 3 4 5 6; do
  echo "{\"id\": \"clip$i\", \"frames\": \"demo/sample_clip.mp4\", \"meta\": {\"obj_name\": \"a box\", \"weight\": $((i * 100))},"\
       "\"gt\": \"demo/taxels.csv\", \"split\": \"$([ $((i % 2)) -eq 0 ] && echo even || echo odd)\"}"
done >"$work/m.jsonl"
opts=(--size 128 --frames 8)
batch_opts=(--sampler euler --steps 25 --seed 4)
submit=("$repo/scripts/slurm/submit.sh" --manifest "$work/m.jsonl" --out "$work/out" --model "$model" --tasks 3
        --max-parallel 2 --cpus 1 --mem 1000 --time 10:00 --name tiny --egopd "$egopd" "${opts[@]}" -- "${batch_opts[@]}")

jobs_left() { [ -z "$(squeue -h -o %i 2>/dev/null)" ]; }
wait_all() {
  for _ in $(seq 1 600); do jobs_left && return 0; sleep 0.25; done
  squeue
  fail "jobs still queued or running after 150 s"
}

"${submit[@]}" >"$work/submit1.log" 2>&1 || fail "submit: $(cat "$work/submit1.log")"
array=$(sed -n 's/^array job \([0-9]*\):.*/\1/p' "$work/submit1.log")
[ -n "$array" ] || fail "no array job: $(cat "$work/submit1.log")"
# Cancel task 1 in the middle of its first clip.
log1=$work/out/logs/${array}_1.out
for _ in $(seq 1 600); do grep -q "step 1/25" "$log1" 2>/dev/null && break; sleep 0.1; done
grep -q "step 1/25" "$log1" || fail "task 1 never started a clip: $(cat "$log1" 2>/dev/null)"
scancel "${array}_1"
wait_all
grep -q "interrupted by SIGTERM" "$log1" || fail "task 1 was not interrupted mid-clip: $(tail -3 "$log1")"
missing=0
for i in 1 2 3 4 5 6; do [ -d "$work/out/clip$i" ] || missing=$((missing + 1)); done
[ "$missing" -gt 0 ] || fail "the cancelled task left nothing to do"
[ -z "$(find "$work/out" -maxdepth 1 -name '.*tmp*')" ] || fail "temporaries left after scancel: $(ls -A "$work/out")"

# The same command again: only what is missing runs.
"${submit[@]}" >"$work/submit2.log" 2>&1 || fail "re-submit: $(cat "$work/submit2.log")"
grep -q "^array job [0-9]*: $missing of 6 clips to do" "$work/submit2.log" || fail "re-submit: $(cat "$work/submit2.log")"
wait_all

for i in 1 2 3 4 5 6; do
  [ -f "$work/out/clip$i/taxels.csv" ] || fail "clip$i has no outputs"
  n=$(cat "$work"/out/logs/*_*.out | grep -c "^egopd batch: done clip$i ")
  [ "$n" -eq 1 ] || fail "clip$i was done $n times"
done
[ -z "$(ls "$work"/out/*.failed 2>/dev/null)" ] || fail "failed clips: $(ls "$work"/out/*.failed)"
[ -z "$(find "$work/out" -maxdepth 1 -name '.*tmp*')" ] || fail "temporaries left: $(ls -A "$work/out")"

# One process, same options: the same bytes.
"$egopd" batch --manifest "$work/m.jsonl" --out "$work/single" --model "$model" "${opts[@]}" "${batch_opts[@]}" \
  --threads 1 2>"$work/single.log" || fail "single-process batch: $(tail -1 "$work/single.log")"
without_timings() { python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); d.pop("timings_s"); d.pop("peak_rss_bytes"); print(json.dumps(d, sort_keys=True))' "$1"; }
for i in 1 2 3 4 5 6; do
  for f in "$work/single/clip$i"/*; do
    name=$(basename "$f")
    if [ "$name" = summary.json ]; then
      [ "$(without_timings "$f")" = "$(without_timings "$work/out/clip$i/$name")" ] || fail "clip$i/summary.json differs"
    else
      cmp -s "$f" "$work/out/clip$i/$name" || fail "clip$i/$name differs from the single-process run"
    fi
  done
done

# The aggregated table equals evaluate on the same outputs.
[ -f "$work/out/results.md" ] || fail "the aggregation job wrote no table: $(cat "$work"/out/logs/*-tables.out)"
"$egopd" evaluate --manifest "$work/m.jsonl" --pred "$work/out" --name tiny --markdown "$work/direct.md" \
  --json "$work/direct.json" >/dev/null || fail "evaluate on the outputs failed"
cmp -s "$work/out/results.md" "$work/direct.md" || fail "aggregated table differs: $(diff "$work/out/results.md" "$work/direct.md")"
cmp -s "$work/out/results.json" "$work/direct.json" || fail "aggregated JSON differs"
grep -q "| even Temp Acc (%) |" "$work/out/results.md" || fail "no per-split columns: $(head -1 "$work/out/results.md")"

echo "Slurm: 6 clips in a 3-task array, one task cancelled and re-submitted: each clip once, same bytes as one" \
  "process, same table ($(($(date +%s) - start)) s)"
rm -rf "$work"
