#!/usr/bin/env bash
# Produces BENCHMARKS.md: the whole-pipeline figures (seconds per stage, total, FPS, peak RSS) of `egopd bench
# pipeline --json` over a matrix of threads x resolution x steps x dtype x normal / --low-mem, plus the machine,
# date and commit they were measured on. Re-run it on any machine; every run writes a fresh file.
#
#   ./scripts/benchmarks.sh                 the full matrix on the real-size (svd-xt) synthetic model: hours
#   ./scripts/benchmarks.sh --quick         tiny preset, small sizes: a smoke test of the script and the bench (~1 min)
#   ./scripts/benchmarks.sh --sizes "256" --steps "4" --dtypes "f16 q8" --threads "2" --out /tmp/b.md
#
# Options (lists are space-separated, quoted):
#   --config svd-xt|tiny   model preset (default svd-xt; --quick: tiny)
#   --threads LIST         thread counts (default: the number of physical cores)
#   --sizes LIST           resolutions (default "128 256 512")
#   --frames LIST          frames per clip (default "16")
#   --steps LIST           25 = Euler teacher, other counts = AnimateLCM student (default "25 8 4")
#   --dtypes LIST          f32 f16 bf16 q8 (default "f32 f16 bf16 q8")
#   --modes LIST           normal low-mem (default both)
#   --egopd PATH           the binary (default build/bin/egopd, built with scripts/build.sh if missing)
#   --out FILE             output (default BENCHMARKS.md)
# Synthetic models are written once into $XDG_CACHE_HOME/egopd (or ~/.cache/egopd) and reused; a real-size model
# takes a few GB of disk per dtype and step count.
set -euo pipefail
cd "$(dirname "$0")/.."

quick=0
config=""
threads=""
sizes="128 256 512"
frames="16"
steps="25 8 4"
dtypes="f32 f16 bf16 q8"
modes="normal low-mem"
egopd=""
out="BENCHMARKS.md"
user_sizes="" user_frames="" user_dtypes=""
while [ $# -gt 0 ]; do
  case "$1" in
    --quick) quick=1; shift ;;
    --config) config="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    --sizes) user_sizes="$2"; shift 2 ;;
    --frames) user_frames="$2"; shift 2 ;;
    --steps) steps="$2"; shift 2 ;;
    --dtypes) user_dtypes="$2"; shift 2 ;;
    --modes) modes="$2"; shift 2 ;;
    --egopd) egopd="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    -h|--help) sed -n '2,24p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "benchmarks.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
  esac
done
if [ "$quick" = 1 ]; then
  # Small enough to finish in about a minute on two cores, still covering every sampler, a float and the q8 path.
  config="${config:-tiny}"
  sizes="128"
  frames="4"
  dtypes="f32 q8"
fi
config="${config:-svd-xt}"
sizes="${user_sizes:-$sizes}"
frames="${user_frames:-$frames}"
dtypes="${user_dtypes:-$dtypes}"

physical_cores() {
  local c
  c=$(lscpu -p=CORE,SOCKET 2>/dev/null | grep -v '^#' | sort -u | wc -l)
  [ "${c:-0}" -gt 0 ] && echo "$c" || nproc
}
threads="${threads:-$(physical_cores)}"

if [ -z "$egopd" ]; then
  egopd=build/bin/egopd
  [ -x "$egopd" ] || ./scripts/build.sh
fi
[ -x "$egopd" ] || { echo "benchmarks.sh: $egopd is not an executable" >&2; exit 1; }

# One number from the flat one-line JSON of `egopd bench --json` (keys are unique in it).
jnum() { grep -o "\"$1\":[-0-9.eE+]*" <<<"$2" | head -n1 | cut -d: -f2; }
jstr() { grep -o "\"$1\":\"[^\"]*\"" <<<"$2" | head -n1 | cut -d: -f2 | tr -d '"'; }
# Mean of the per-step seconds list.
jsteps() { grep -o '"denoise_steps":\[[^]]*\]' <<<"$2" | sed 's/.*\[//; s/\]//' | tr ',' '\n' |
           awk '{ s += $1; n++ } END { if (n) printf "%.3f", s / n; else printf "-" }'; }
f2() { [ -n "$1" ] && awk -v x="$1" 'BEGIN { printf (x < 10 ? "%.3f" : "%.1f"), x }' || printf -- "-"; }

rows=""
raw=""
total_runs=0
for t in $threads; do for s in $sizes; do for f in $frames; do for n in $steps; do for d in $dtypes; do
  for m in $modes; do total_runs=$((total_runs + 1)); done
done; done; done; done; done
echo "benchmarks.sh: $total_runs runs of egopd bench pipeline (config $config) -> $out" >&2

# Other work on the machine distorts every figure: the load averages before and after go into the report.
load_before=$(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo unknown)
run=0
for t in $threads; do for s in $sizes; do for f in $frames; do for n in $steps; do for d in $dtypes; do
  for m in $modes; do
    run=$((run + 1))
    flag=""
    [ "$m" = "low-mem" ] && flag="--low-mem"
    args=(bench pipeline --config "$config" --threads "$t" --size "$s" --frames "$f" --steps "$n" --dtype "$d" $flag --json)
    echo "[$run/$total_runs] egopd ${args[*]}" >&2
    if j=$("$egopd" "${args[@]}" | tail -n1) && [ -n "$j" ]; then
      raw+="$(sed 's/"model_dir":"[^"]*",//' <<<"$j")"$'\n'  # the cache path is this machine's, not a result
      rss=$(jnum peak_rss_bytes "$j")
      rows+="| $t | ${s}x${s} | $f | $n ($(jstr sampler "$j")) | $d | $m | $(f2 "$(jnum load "$j")") | "
      rows+="$(f2 "$(jnum frame_decode_resize "$j")") | $(f2 "$(jnum vae_encode "$j")") | $(f2 "$(jnum clip_image "$j")") | "
      rows+="$(f2 "$(jnum text_encoder "$j")") | $(jsteps x "$j") | $(f2 "$(jnum denoise "$j")") | "
      rows+="$(f2 "$(jnum vae_decode "$j")") | $(f2 "$(jnum postprocess "$j")") | $(f2 "$(jnum total_seconds "$j")") | "
      rows+="$(awk -v x="$(jnum fps "$j")" 'BEGIN { printf "%.3f", x }') | $(awk -v b="$rss" 'BEGIN { printf "%.0f", b / 1048576 }') |"$'\n'
    else
      rows+="| $t | ${s}x${s} | $f | $n | $d | $m | failed (see the script's stderr) |||||||||||"$'\n'
    fi
  done
done; done; done; done; done

cpu=$(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -n1)
sockets=$(lscpu -p=SOCKET 2>/dev/null | grep -v '^#' | sort -u | wc -l)
commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
git diff --quiet HEAD -- src 2>/dev/null || commit="$commit (with uncommitted changes in src/)"
mem=$(awk '/MemTotal/ { printf "%.1f GiB", $2 / 1048576 }' /proc/meminfo 2>/dev/null || echo unknown)

{
  echo "# Benchmarks"
  echo
  echo "Generated by \`./scripts/benchmarks.sh$([ "$quick" = 1 ] && echo " --quick")\`: one whole \`egopd bench pipeline\` prediction"
  echo "per row (decoding a 640x640 MP4 of the built-in synthetic clip and resizing it to the model size, the encoders,"
  echo "every sampler step, temporal VAE decode, taxel read-out) on a synthetic model with random weights (speed and"
  echo "memory do not depend on the weight values)."
  echo
  if [ "$config" = tiny ]; then
    echo "> **Tiny preset smoke run.** These rows use the *tiny* synthetic preset (U-Net widths 32/32/64), not the"
    echo "> real-size SVD-xt model: they show that the benchmark and the script work, not what a real prediction"
    echo "> costs. Run \`./scripts/benchmarks.sh\` (real-size matrix) on the target machine for those figures."
    echo
  fi
  if awk -v l="${load_before%% *}" -v n="$(nproc)" 'BEGIN { exit !(l + 0 > n + 0) }'; then
    echo "> **Busy machine.** The load average exceeded the number of logical CPUs: other jobs shared the cores, so"
    echo "> the times below are not representative (peak RSS is unaffected)."
    echo
  fi
  echo "| | |"
  echo "| --- | --- |"
  echo "| CPU | ${cpu:-unknown} ($(physical_cores) physical cores, $(nproc) logical, ${sockets:-1} socket(s)) |"
  echo "| memory | $mem |"
  echo "| egopd | $("$egopd" --version) |"
  echo "| commit | $commit |"
  echo "| date | $(date -u '+%Y-%m-%d %H:%M UTC') |"
  echo "| load average (1/5/15 min) | before: $load_before; after: $(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo unknown) |"
  echo "| model | $config synthetic |"
  echo
  echo "Times in seconds. *load*: model loading (in low-mem mode each component is loaded when its stage runs, so"
  echo "this sums every load); *s/step*: mean seconds per sampler step; *denoise*: all steps; *total*: decode of the clip"
  echo "to the last taxel, loading included; FPS = frames / total; peak RSS in MiB (VmHWM of the whole run)."
  echo "Steps: 25 = Euler teacher, 8 and 4 = AnimateLCM students. *low-mem* (\`--low-mem\`) loads one component at a"
  echo "time, pages U-Net weights out after each block and decodes 2 frames per VAE call (normal mode: the whole clip"
  echo "in one call; chunked decoding changes the decoded frames slightly, as diffusers' \`decode_chunk_size\` does)."
  echo
  echo "| threads | size | frames | steps | dtype | mode | load | decode+resize | vae_encode | clip_image | text_encoder | s/step | denoise | vae_decode | postprocess | total | FPS | peak RSS MiB |"
  echo "| ---: | --- | ---: | --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
  printf '%s' "$rows"
  echo
  echo "<details><summary>Raw <code>egopd bench pipeline --json</code> output</summary>"
  echo
  echo '```json'
  printf '%s' "$raw"
  echo '```'
  echo
  echo "</details>"
} >"$out.tmp"
mv "$out.tmp" "$out"
echo "benchmarks.sh: wrote $out" >&2
