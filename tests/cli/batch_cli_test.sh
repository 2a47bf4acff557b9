#!/usr/bin/env bash
# End to end on the built-in tiny model: `egopd manifest` over a dataset tree laid out like the data release,
# `egopd batch` (failures recorded and counted, resume, shards from the Slurm environment, SIGTERM leaving nothing
# half-written, then resuming), and `egopd evaluate --manifest` writing the tables and naming the failed clip.
# usage: batch_cli_test.sh EGOPD_BINARY WORK_DIR
set -uo pipefail
egopd=$1
work=$2
[ -n "${KEEP:-}" ] || rm -rf "$work"
mkdir -p "$work"
export XDG_CACHE_HOME="$work/cache"
unset SLURM_ARRAY_TASK_ID SLURM_ARRAY_TASK_COUNT SLURM_ARRAY_TASK_MIN SLURM_CPUS_PER_TASK EGOPD_THREADS
source "$(dirname "$0")/common.sh"
opts=(--size 64 --frames 2 --steps 1 --threads 1)

# A dataset tree: three sequences of four frames (any image serves as a frame; the demo's heatmaps do).
"$egopd" predict --out "$work/demo" --frames 4 --size 64 --threads 1 2>"$work/demo.log" || fail "demo: $(tail -1 "$work/demo.log")"
for seq in p001-Apple-repeat0000 p001-Mug-repeat0001 p002-Apple-repeat0000; do
  mkdir -p "$work/data/$seq"
  for i in 0 1 2 3; do
    for role in rgb mask pressure; do cp "$work/demo/heatmap_00$i.png" "$work/data/$seq/0000$((i + 5))_$role.png"; done
  done
  echo "$seq" >>"$work/data/motion_list.txt"
done
cat >"$work/attributes.json" <<'EOF'
{"objects": {"Apple": {"obj_name": "an apple", "weight": 180}, "Mug": {"obj_name": "a mug", "weight": 355}},
 "subjects": {"p001": {"gender": "female"}, "p002": {"gender": "male", "age": 30}},
 "splits": {"object_held_out": {"objects": ["Mug"]}}}
EOF
"$egopd" manifest --root "$work/data" --attributes "$work/attributes.json" --out "$work/m.jsonl" 2>"$work/manifest.log" \
  || fail "manifest: $(tail -1 "$work/manifest.log")"
[ "$(wc -l <"$work/m.jsonl")" -eq 3 ] || fail "manifest has $(wc -l <"$work/m.jsonl") lines"
grep -q '"split":"object_held_out"' "$work/m.jsonl" || fail "no split in the manifest"
grep -q '"weight":"355g"' "$work/m.jsonl" || fail "no object attributes in the manifest"

# A fourth clip that cannot be read: recorded, counted, and the exit status says so.
cp "$work/m.jsonl" "$work/m4.jsonl"
echo '{"id": "broken", "frames": "data/nowhere.mp4"}' >>"$work/m4.jsonl"
"$egopd" batch --manifest "$work/m4.jsonl" --out "$work/out" "${opts[@]}" 2>"$work/batch.log"
code=$?
[ "$code" -eq 1 ] || fail "exit $code with a failed clip (want 1)"
[ "$(grep -c '^egopd batch: done ' "$work/batch.log")" -eq 3 ] || fail "not 3 clips done: $(cat "$work/batch.log")"
grep -q "nowhere.mp4" "$work/out/broken.failed" || fail "broken.failed lacks the error"
tail -1 "$work/batch.log" | grep -q "^egopd: batch: 1 of 4 clips failed" || fail "last line: $(tail -1 "$work/batch.log")"
grep -q "clips/hour" "$work/batch.log" || fail "no throughput line"

# The split tables, with the failed clip named and exit status 1.
"$egopd" evaluate --manifest "$work/m4.jsonl" --pred "$work/out" --json "$work/r.json" --markdown "$work/r.md" \
  --csv "$work/r.csv" >"$work/eval.out" 2>"$work/eval.log"
code=$?
[ "$code" -eq 1 ] || fail "evaluate exit $code with a failed clip (want 1)"
grep -q "FAILED: broken" "$work/r.md" || fail "the table does not name the failed clip"
grep -q "| object_held_out Temp Acc (%) |" "$work/r.md" || fail "no split column: $(head -1 "$work/r.md")"
[ "$(wc -l <"$work/r.csv")" -eq 5 ] || fail "per-clip CSV: $(wc -l <"$work/r.csv") lines"
cmp -s "$work/eval.out" "$work/r.md" || fail "printed table differs from --markdown"
grep -q '"complete": false' "$work/r.json" || fail "JSON does not say incomplete"
"$egopd" evaluate --manifest "$work/m.jsonl" --pred "$work/out" >/dev/null 2>&1 || fail "complete run: evaluate failed"

# Resume: nothing is redone; a Slurm array task takes its shard from the environment.
"$egopd" batch --manifest "$work/m.jsonl" --out "$work/out" "${opts[@]}" 2>"$work/resume.log" || fail "resume: $(tail -1 "$work/resume.log")"
grep -q "3 already done" "$work/resume.log" || fail "resume did not skip: $(head -1 "$work/resume.log")"
SLURM_ARRAY_TASK_ID=1 SLURM_ARRAY_TASK_COUNT=2 "$egopd" batch --manifest "$work/m.jsonl" --out "$work/shard" "${opts[@]}" \
  2>"$work/shard.log" || fail "shard: $(tail -1 "$work/shard.log")"
[ "$(ls "$work/shard")" = "p001-Mug-repeat0001" ] || fail "task 1 of 2 ran: $(ls "$work/shard")"
cmp -s "$work/shard/p001-Mug-repeat0001/taxels.csv" "$work/out/p001-Mug-repeat0001/taxels.csv" || fail "shard output differs"

# Bad options: one line each, exit 1.
for bad in "--shard 2/2" "--shard x" "--video v.mp4" "--manifest $work/none.jsonl"; do
  # shellcheck disable=SC2086
  "$egopd" batch --manifest "$work/m.jsonl" --out "$work/bad" $bad "${opts[@]}" 2>"$work/bad.log"
  code=$?
  [ "$code" -eq 1 ] && [ "$(wc -l <"$work/bad.log")" -eq 1 ] || fail "'$bad': exit $code, $(cat "$work/bad.log")"
done

# SIGTERM in the middle of the second clip: exit 143, the first clip whole, no temporaries; a re-run resumes.
rm -rf "$work/out"
"$egopd" batch --manifest "$work/m.jsonl" --out "$work/out" --size 128 --frames 4 --sampler euler --steps 25 \
  --threads 1 2>"$work/term.log" &
pid=$!
wait_for_log "$work/term.log" "^\[2/3 .*step 1/25" $pid
kill -TERM $pid
wait $pid
code=$?
[ "$code" -eq 143 ] || fail "exit $code after SIGTERM (want 143): $(tail -1 "$work/term.log")"
[ "$(ls -A "$work/out")" = "p001-Apple-repeat0000" ] || fail "after SIGTERM the folder holds: $(ls -A "$work/out")"
"$egopd" batch --manifest "$work/m.jsonl" --out "$work/out" --size 128 --frames 4 --sampler euler --steps 2 \
  --threads 1 2>"$work/after.log" || fail "after SIGTERM: $(tail -1 "$work/after.log")"
grep -q "1 already done" "$work/after.log" || fail "re-run did not resume: $(head -1 "$work/after.log")"
[ "$(grep -c '^egopd batch: done ' "$work/after.log")" -eq 2 ] || fail "re-run did not finish the other two"
[ -n "${KEEP:-}" ] || rm -rf "$work"
echo "manifest, batch and split evaluation from the command line: ok"
