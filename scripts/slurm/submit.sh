#!/usr/bin/env bash
# Runs `egopd batch` over a manifest as a Slurm job array, then an aggregation job that writes the tables.
#
# usage: scripts/slurm/submit.sh --manifest M.jsonl --out DIR [options] [-- extra `egopd batch` options]
#   --model DIR        model directory (default: egopd's built-in tiny synthetic model)
#   --tasks N          array size: the manifest is split into N shards, clip k in shard k % N (default: one task
#                      per 4 clips still to do, at most 64)
#   --max-parallel K   at most K tasks at once (--array=0-(N-1)%K; default 8)
#   --cpus C           CPUs per task (default 4; egopd takes its threads from SLURM_CPUS_PER_TASK)
#   --mem MB           memory per task in MB (default: estimated, see below)
#   --low-mem          pass --low-mem to egopd (and estimate memory for it)
#   --size S --frames F  passed to egopd (and used by the estimate; defaults 256 and 16)
#   --time T           time limit per task (sbatch syntax, default 24:00:00)
#   --partition P      partition (default: the cluster's default)
#   --name RUN         row label of the tables (default: DIR's name)
#   --egopd PATH       the egopd executable, visible from the compute nodes (default: egopd on PATH, else this
#                      checkout's build/bin/egopd)
#   --dry-run          print the sbatch commands instead of running them
#
# Outputs: DIR/<id>/ per clip and DIR/<id>.failed for a clip that failed (see `egopd batch --help`), task logs in
# DIR/logs/<array job>_<task>.out, and from the aggregation job DIR/results.md, DIR/results.json and
# DIR/per_clip.csv (`egopd evaluate --manifest`; a run with missing or failed clips names them and the job fails).
#
# Preemption and time limits: tasks are submitted with --requeue; on SIGTERM egopd abandons the current clip with
# nothing half-written and exits 143, and a requeued or re-submitted task skips every finished clip. Submitting
# the same command again after failures or cancellations runs only what is missing (when nothing is missing only
# the aggregation job is submitted).
#
# Memory estimate per task (MB): weights are memory-mapped and touched once per clip, so the resident set holds
# them: model_MB (the size of the model folder's safetensors as stored: F16/BF16/q8 weigh less) plus activations
# of about 1200 MB x (F / 16) x (S / 256)^2, plus 512 MB for the runtime. With --low-mem components are loaded one
# at a time and paged out layer by layer: model_MB / 4 + 400 MB x (F / 16) x (S / 256)^2 + 512 MB. (Measured on
# the real-size synthetic model, F16, 16 x 256x256: 3.8 GB peak, 1.0 GB with --low-mem.) Override with --mem.
set -euo pipefail

repo=$(cd "$(dirname "$0")/../.." && pwd)
manifest="" out="" model="" tasks="" parallel=8 cpus=4 mem="" low_mem=0 size=256 frames=16 time_limit=24:00:00
partition="" name="" egopd="" dry_run=0
extra=()
usage() { sed -n '2,/^set -euo/p' "$0" | sed '$d' | sed 's/^# \{0,1\}//'; }
die() { echo "submit.sh: $*" >&2; exit 1; }
while [ $# -gt 0 ]; do
  case "$1" in
    --manifest) manifest=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --model) model=$2; shift 2 ;;
    --tasks) tasks=$2; shift 2 ;;
    --max-parallel) parallel=$2; shift 2 ;;
    --cpus) cpus=$2; shift 2 ;;
    --mem) mem=$2; shift 2 ;;
    --low-mem) low_mem=1; shift ;;
    --size) size=$2; shift 2 ;;
    --frames) frames=$2; shift 2 ;;
    --time) time_limit=$2; shift 2 ;;
    --partition) partition=$2; shift 2 ;;
    --name) name=$2; shift 2 ;;
    --egopd) egopd=$2; shift 2 ;;
    --dry-run) dry_run=1; shift ;;
    --help|-h) usage; exit 0 ;;
    --) shift; extra=("$@"); break ;;
    *) die "unknown option $1 (see --help)" ;;
  esac
done
[ -n "$manifest" ] || die "--manifest is required"
[ -n "$out" ] || die "--out is required"
[ -f "$manifest" ] || die "$manifest: manifest does not exist"
[ -z "$model" ] || [ -d "$model" ] || die "$model: model directory does not exist"
for v in "tasks:$tasks" "max-parallel:$parallel" "cpus:$cpus" "mem:$mem" "size:$size" "frames:$frames"; do
  [ -z "${v#*:}" ] || [[ "${v#*:}" =~ ^[1-9][0-9]*$ ]] || die "--${v%%:*} must be a positive integer (got '${v#*:}')"
done
if [ -z "$egopd" ]; then
  egopd=$(command -v egopd || true)
  [ -n "$egopd" ] || egopd=$repo/build/bin/egopd
fi
[ -x "$egopd" ] || die "$egopd: egopd executable not found (build it, or pass --egopd)"
command -v sbatch >/dev/null || die "sbatch not found: not on a Slurm cluster (try scripts/slurm/local-cluster.sh up)"

manifest=$(realpath "$manifest")
mkdir -p "$out/logs"
out=$(realpath "$out")
[ -n "$name" ] || name=$(basename "$out")

# Clips still to do: ids in the manifest without a finished folder (egopd batch decides again per clip).
mapfile -t ids < <(sed -n 's/.*"id" *: *"\([^"]*\)".*/\1/p' "$manifest")
[ ${#ids[@]} -gt 0 ] || die "$manifest: no clips"
todo=0
for id in "${ids[@]}"; do [ -d "$out/$id" ] || todo=$((todo + 1)); done
if [ -z "$tasks" ]; then
  tasks=$(((todo + 3) / 4))
  [ "$tasks" -le 64 ] || tasks=64
  [ "$tasks" -ge 1 ] || tasks=1
fi

if [ -z "$mem" ]; then
  model_mb=50  # the built-in tiny model
  if [ -n "$model" ]; then
    model_mb=$(find "$model" -name '*.safetensors' -printf '%s\n' | awk '{ s += $1 } END { printf "%d", s / 1048576 }')
  fi
  mem=$(awk -v m="$model_mb" -v f="$frames" -v s="$size" -v low="$low_mem" 'BEGIN {
    scale = (f / 16) * (s / 256) * (s / 256)
    if (low) printf "%d", m / 4 + 400 * scale + 512; else printf "%d", m + 1200 * scale + 512 }')
fi

batch_cmd=("$egopd" batch --manifest "$manifest" --out "$out" --size "$size" --frames "$frames")
[ -z "$model" ] || batch_cmd+=(--model "$(realpath "$model")")
[ "$low_mem" -eq 0 ] || batch_cmd+=(--low-mem)
batch_cmd+=("${extra[@]}")
eval_cmd=("$egopd" evaluate --manifest "$manifest" --pred "$out" --name "$name" --json "$out/results.json"
          --markdown "$out/results.md" --csv "$out/per_clip.csv")
common=(--parsable --time="$time_limit")
[ -z "$partition" ] || common+=(--partition="$partition")

quote() { printf '%q ' "$@"; }
run() {
  if [ "$dry_run" -eq 1 ]; then echo "$(quote "$@")" >&2; echo "DRYRUN"; else "$@"; fi
}

dependency=()
if [ "$todo" -gt 0 ]; then
  array_id=$(run sbatch "${common[@]}" --job-name="egopd-$name" --array="0-$((tasks - 1))%$parallel" \
    --cpus-per-task="$cpus" --mem="$mem" --requeue --output="$out/logs/%A_%a.out" \
    --wrap "exec $(quote "${batch_cmd[@]}")")
  array_id=${array_id%%;*}
  echo "array job $array_id: $todo of ${#ids[@]} clips to do in $tasks tasks (at most $parallel at once)," \
    "$cpus CPUs and $mem MB each"
  dependency=(--dependency="afterany:$array_id")
else
  echo "all ${#ids[@]} clips are done: no array job, only the tables"
fi
agg_id=$(run sbatch "${common[@]}" --job-name="egopd-$name-tables" "${dependency[@]}" --cpus-per-task=1 --mem=1024 \
  --output="$out/logs/%j-tables.out" --wrap "exec $(quote "${eval_cmd[@]}")")
agg_id=${agg_id%%;*}
echo "aggregation job $agg_id: tables in $out/results.md, results.json, per_clip.csv"
