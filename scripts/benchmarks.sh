#!/usr/bin/env bash
# Produces BENCHMARKS.md: whole-pipeline figures (seconds per stage, total, FPS, peak RSS) of `egopd bench pipeline
# --json`, the 1 -> 2 thread speed-up per stage, and the machine, date and commit they were measured on. Re-run it on
# any machine; the file is rewritten after every run, so an interrupted script keeps the rows it finished.
#
#   ./scripts/benchmarks.sh            the standard table on the real-size (svd-xt) synthetic model (~1.5 h on 2 cores)
#   ./scripts/benchmarks.sh --quick    tiny preset, small sizes: a smoke test of the script and the bench (~1 min)
#   ./scripts/benchmarks.sh --matrix --sizes "256" --steps "4" --dtypes "f16 q8" --out b.md    a cross product
#
# The standard table covers every dimension without the full cross product (which takes a day: a 25-step run at
# 512x512 alone is ~45 min on 2 cores), in this order: 256x256 at 4 steps, F16 and q8, normal and --low-mem; 256x256
# at 25 and 8 steps; 128x128 at 4/8/25 steps and --low-mem; 512x512 at 4 steps; 4 steps on 1 thread (speed-up per
# stage); BF16 and F32; 25 steps --low-mem; 512x512 --low-mem.
#
# Options (lists are space-separated, quoted; --matrix runs threads x sizes x frames x steps x dtypes x modes):
#   --config svd-xt|tiny   model preset (default svd-xt; --quick: tiny)
#   --matrix               the cross product of the lists below instead of the standard table
#   --threads LIST         thread counts (default: the number of physical cores; the standard table adds 1)
#   --sizes LIST           resolutions (default "128 256 512")
#   --frames LIST          frames per clip (default "16")
#   --steps LIST           25 = Euler teacher, other counts = AnimateLCM student (default "25 8 4")
#   --dtypes LIST          f32 f16 bf16 q8 (default "f32 f16 bf16 q8")
#   --modes LIST           normal low-mem (default both)
#   --egopd PATH           the binary (default build/bin/egopd, built with scripts/build.sh if missing)
#   --out FILE             output (default BENCHMARKS.md)
# Synthetic models are written once per dtype into $XDG_CACHE_HOME/egopd (or ~/.cache/egopd) and reused: about
# 3 GB (F16, BF16), 6 GB (F32) and 1.6 GB (q8) of disk for the real-size model.
set -euo pipefail
cd "$(dirname "$0")/.."

quick=0 matrix=0
config=""
threads=""
sizes="128 256 512"
frames="16"
steps="25 8 4"
dtypes="f32 f16 bf16 q8"
modes="normal low-mem"
egopd=""
out="BENCHMARKS.md"
while [ $# -gt 0 ]; do
  case "$1" in
    --quick) quick=1; matrix=1; shift ;;
    --matrix) matrix=1; shift ;;
    --config) config="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    --sizes) sizes="$2"; shift 2 ;;
    --frames) frames="$2"; shift 2 ;;
    --steps) steps="$2"; shift 2 ;;
    --dtypes) dtypes="$2"; shift 2 ;;
    --modes) modes="$2"; shift 2 ;;
    --egopd) egopd="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    -h|--help) sed -n '2,28p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
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

physical_cores() {
  local c
  c=$(lscpu -p=CORE,SOCKET 2>/dev/null | grep -v '^#' | sort -u | wc -l)
  [ "${c:-0}" -gt 0 ] && echo "$c" || nproc
}
cores=$(physical_cores)
threads="${threads:-$cores}"

# The runs: "threads size frames steps dtype mode" per line.
runs=()
if [ "$matrix" = 1 ]; then
  for t in $threads; do for s in $sizes; do for f in $frames; do for n in $steps; do for d in $dtypes; do
    for m in $modes; do runs+=("$t $s $f $n $d $m"); done
  done; done; done; done; done
else
  t="${threads%% *}"  # the standard table runs at one thread count (plus 1 thread for the speed-up rows)
  # The headline rows first (an interrupted run still has them): 256x256 F16 and q8, normal and low-mem, 25 steps.
  runs=(
    "$t 256 16 4 f16 normal" "$t 256 16 4 f16 low-mem" "$t 256 16 4 q8 normal" "$t 256 16 4 q8 low-mem"
    "$t 256 16 25 f16 normal" "$t 256 16 8 f16 normal"
    "$t 128 16 4 f16 normal" "$t 128 16 8 f16 normal" "$t 128 16 25 f16 normal" "$t 128 16 4 f16 low-mem"
    "$t 512 16 4 f16 normal"
  )
  [ "$t" != 1 ] && runs+=("1 256 16 4 f16 normal")
  runs+=("$t 256 16 4 bf16 normal" "$t 256 16 4 f32 normal" "$t 256 16 25 f16 low-mem" "$t 512 16 4 f16 low-mem")
fi

if [ -z "$egopd" ]; then
  egopd=build/bin/egopd
  [ -x "$egopd" ] || ./scripts/build.sh
fi
[ -x "$egopd" ] || { echo "benchmarks.sh: $egopd is not an executable" >&2; exit 1; }

# One number / string from the one-line JSON of `egopd bench --json`: the first occurrence of the key, so stage
# names must be looked up inside the object they belong to (see section).
jnum() { grep -o "\"$1\":[-0-9.eE+]*" <<<"$2" | head -n1 | cut -d: -f2; }
jstr() { grep -o "\"$1\":\"[^\"]*\"" <<<"$2" | head -n1 | cut -d: -f2 | tr -d '"'; }
section() { grep -o "\"$1\":{[^}]*}" <<<"$2" | head -n1; }
# Mean of the per-step seconds list.
jsteps() { grep -o '"denoise_steps":\[[^]]*\]' <<<"$1" | sed 's/.*\[//; s/\]//' | tr ',' '\n' |
           awk '{ s += $1; n++ } END { if (n) printf "%.2f", s / n; else printf "-" }'; }
f2() { [ -n "$1" ] && awk -v x="$1" 'BEGIN { printf (x < 10 ? "%.2f" : "%.1f"), x }' || printf -- "-"; }
mib() { awk -v b="$1" 'BEGIN { printf "%.0f", b / 1048576 }'; }
# The stage with the highest peak RSS, as "MiB (stage)".
peak_stage() {
  grep -o '"[a-z_]*":[0-9]*' <<<"$1" | tr -d '"' |
    awk -F: '$2 > m { m = $2; s = $1 } END { if (s != "") printf "%s", s; else printf "-" }'
}

stage_names=(load frame_decode_resize text_encoder vae_encode clip_image denoise vae_decode postprocess)
declare -A stage_of  # "threads|size|frames|steps|dtype|mode|stage" -> seconds
rows=""
raw=""
load_before=$(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo unknown)
cpu=$(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -n1)
sockets=$(lscpu -p=SOCKET 2>/dev/null | grep -v '^#' | sort -u | wc -l)
commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
git diff --quiet HEAD -- src 2>/dev/null || commit="$commit (with uncommitted changes in src/)"
mem=$(awk '/MemTotal/ { printf "%.1f GiB", $2 / 1048576 }' /proc/meminfo 2>/dev/null || echo unknown)
started=$(date -u '+%Y-%m-%d %H:%M UTC')

speedup_table() {
  local key1 key2 r t s f n d m any=0 line
  for r in "${runs[@]}"; do
    read -r t s f n d m <<<"$r"
    [ "$t" = 1 ] || continue
    key1="1|$s|$f|$n|$d|$m"
    for t2 in $(printf '%s\n' "${runs[@]}" | awk '{ print $1 }' | sort -un); do
      [ "$t2" = 1 ] && continue
      key2="$t2|$s|$f|$n|$d|$m"
      [ -n "${stage_of[$key1|total]:-}" ] && [ -n "${stage_of[$key2|total]:-}" ] || continue
      if [ "$any" = 0 ]; then
        echo "### Thread scaling: speed-up from 1 thread to more (time at 1 thread / time at T threads)"
        echo
        echo "| run | T | $(printf '%s | ' "${stage_names[@]}")s/step | total |"
        echo "| --- | ---: | $(printf -- '---: | %.0s' "${stage_names[@]}")---: | ---: |"
        any=1
      fi
      line="| ${s}x${s}, $f frames, $n steps, $d, $m | $t2 |"
      for st in "${stage_names[@]}" step total; do
        line+=" $(awk -v a="${stage_of[$key1|$st]:-}" -v b="${stage_of[$key2|$st]:-}" \
                  'BEGIN { if (a != "" && b != "" && b + 0 > 0) printf "%.2f", a / b; else printf "-" }') |"
      done
      echo "$line"
    done
  done
  [ "$any" = 1 ] && echo
  return 0
}

write_report() {
  {
    echo "# Benchmarks"
    echo
    echo "Generated by \`./scripts/benchmarks.sh$([ "$quick" = 1 ] && echo " --quick")$([ "$matrix" = 1 ] && [ "$quick" = 0 ] && echo " --matrix ...")\`: one whole \`egopd bench pipeline\`"
    echo "prediction per row (decoding a 640x640 MP4 of the built-in synthetic clip and resizing it to the model size,"
    echo "a full prompt through the text encoder, VAE encode, CLIP image, every sampler step with the PIFR layers,"
    echo "temporal VAE decode of the whole clip, taxel read-out) on a synthetic model with random weights of the real"
    echo "sizes (speed and memory do not depend on the weight values)."
    echo
    if [ "$config" = tiny ]; then
      echo "> **Tiny preset smoke run.** These rows use the *tiny* synthetic preset (U-Net widths 32/32/64), not the"
      echo "> real-size SVD-xt model: they show that the benchmark and the script work, not what a real prediction"
      echo "> costs. Run \`./scripts/benchmarks.sh\` on the target machine for those figures."
      echo
    fi
    if awk -v l="${load_before%% *}" -v n="$(nproc)" 'BEGIN { exit !(l + 0 > n + 0) }'; then
      echo "> **Busy machine.** The load average exceeded the number of logical CPUs: other jobs shared the cores, so"
      echo "> the times below are not representative (peak RSS is unaffected)."
      echo
    fi
    echo "| | |"
    echo "| --- | --- |"
    echo "| CPU | ${cpu:-unknown} ($cores physical cores, $(nproc) logical, ${sockets:-1} socket(s)) |"
    echo "| memory | $mem |"
    echo "| egopd | $("$egopd" --version) |"
    echo "| commit | $commit |"
    echo "| date | $started (started) |"
    echo "| load average (1/5/15 min) | before: $load_before; now: $(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo unknown) |"
    echo "| model | $config synthetic |"
    echo
    echo "Times in seconds. *load*: model loading (in low-mem mode each component is loaded when its stage runs, so"
    echo "this sums every load); *s/step*: mean seconds per sampler step (U-Net with PIFR + sampler update); *denoise*:"
    echo "all steps; *total*: decode of the clip to the last taxel, loading included; FPS = frames / total; peak RSS in"
    echo "MiB over the whole run, with the stage where it occurred. Steps: 25 = Euler teacher, 8 and 4 = AnimateLCM"
    echo "students. *low-mem* (\`--low-mem\`) loads one component at a time, pages CLIP, U-Net and VAE-decoder weights out"
    echo "after each layer, and runs the VAE decoder's temporal layers in small tiles without a whole-clip temporary: the same"
    echo "numbers as normal mode (checked by the tests), in less memory. *Σ latents²* and *Σ video*: fingerprints of"
    echo "the final latents and the decoded clip; runs of one size, step count and dtype should agree in about 5"
    echo "significant digits across thread counts and modes (float summation order differs)."
    echo
    echo "| threads | size | frames | steps | dtype | mode | load | decode+resize | text_encoder | vae_encode | clip_image | s/step | denoise | vae_decode | postprocess | total | FPS | peak RSS MiB | Σ latents² | Σ video |"
    echo "| ---: | --- | ---: | --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: | ---: |"
    printf '%s' "$rows"
    echo
    speedup_table
    echo "<details><summary>Raw <code>egopd bench pipeline --json</code> output</summary>"
    echo
    echo '```json'
    printf '%s' "$raw"
    echo '```'
    echo
    echo "</details>"
  } >"$out.tmp"
  mv "$out.tmp" "$out"
}

total_runs=${#runs[@]}
echo "benchmarks.sh: $total_runs runs of egopd bench pipeline (config $config) -> $out" >&2
run=0
for r in "${runs[@]}"; do
  read -r t s f n d m <<<"$r"
  run=$((run + 1))
  flag=()
  [ "$m" = "low-mem" ] && flag=(--low-mem)
  args=(bench pipeline --config "$config" --threads "$t" --size "$s" --frames "$f" --steps "$n" --dtype "$d" "${flag[@]}" --json)
  echo "[$run/$total_runs] $(date -u '+%H:%M:%S') egopd ${args[*]}" >&2
  if j=$("$egopd" "${args[@]}" | tail -n1) && [ -n "$j" ]; then
    raw+="$(sed 's/"model_dir":"[^"]*",//' <<<"$j")"$'\n'  # the cache path is this machine's, not a result
    st=$(section stages "$j")
    key="$t|$s|$f|$n|$d|$m"
    for name in "${stage_names[@]}"; do stage_of[$key|$name]=$(jnum "$name" "$st"); done
    stage_of[$key|step]=$(jsteps "$st")
    stage_of[$key|total]=$(jnum total_seconds "$j")
    rows+="| $t | ${s}x${s} | $f | $n ($(jstr sampler "$j")) | $d | $m | $(f2 "$(jnum load "$st")") | "
    rows+="$(f2 "$(jnum frame_decode_resize "$st")") | $(f2 "$(jnum text_encoder "$st")") | "
    rows+="$(f2 "$(jnum vae_encode "$st")") | $(f2 "$(jnum clip_image "$st")") | $(jsteps "$st") | "
    rows+="$(f2 "$(jnum denoise "$st")") | $(f2 "$(jnum vae_decode "$st")") | $(f2 "$(jnum postprocess "$st")") | "
    rows+="$(f2 "$(jnum total_seconds "$j")") | $(awk -v x="$(jnum fps "$j")" 'BEGIN { printf "%.3f", x }') | "
    rows+="$(mib "$(jnum peak_rss_bytes "$j")") ($(peak_stage "$(section stage_peak_rss_bytes "$j")")) | "
    res=$(section result "$j")
    rows+="$(awk -v x="$(jnum latents_sum_sq "$res")" 'BEGIN { printf "%.6g", x }') | "
    rows+="$(awk -v x="$(jnum decoded_sum "$res")" 'BEGIN { printf "%.6g", x }') |"$'\n'
  else
    rows+="| $t | ${s}x${s} | $f | $n | $d | $m | failed (see the script's stderr) |||||||||||||"$'\n'
  fi
  write_report
done
echo "benchmarks.sh: wrote $out" >&2
