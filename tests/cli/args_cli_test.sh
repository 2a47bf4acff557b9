#!/usr/bin/env bash
# Arguments and metadata are taken exactly: each malformed invocation below exits 1 with exactly one line on stderr
# that names the flag, field, file or variable at fault (and never runs the model on something else).
# usage: args_cli_test.sh EGOPD_BINARY EGOPD_CONVERT_BINARY WORK_DIR
set -uo pipefail
egopd=$1
convert=$2
work=$3
source "$(dirname "$0")/common.sh"
rm -rf "$work"
mkdir -p "$work"
export XDG_CACHE_HOME="$work/cache"
unset EGOPD_THREADS EGOPD_TEMPLATE EGOPD_TOKENIZER_DIR
out=$work/out
echo '{"obj_name": "a cup", "weight": true}' >"$work/wrong_type.json"
echo '{"obj_name": "a cup", ' >"$work/not_json.json"
echo '{"obj_name": "a cup", "weight": 355, "category": "mug"}' >"$work/extra.json"
cases=0

# expect_error KEYWORD COMMAND...: exit status 1, one stderr line, containing KEYWORD. With REPORT=1 every case is
# run and reported (for comparing builds) instead of stopping at the first failure.
expect_error() {
  local keyword=$1
  shift
  rm -rf "$out"
  "$@" >"$work/stdout" 2>"$work/stderr"
  local code=$? problem=""
  local lines
  lines=$(wc -l <"$work/stderr")
  if [ "$code" -ne 1 ]; then problem="exit $code (want 1)"
  elif [ "$lines" -ne 1 ]; then problem="$lines stderr lines (want 1)"
  elif ! grep -qF -- "$keyword" "$work/stderr"; then problem="'$keyword' not in the message"
  elif [ -e "$out" ]; then problem="an output folder was written"
  fi
  cases=$((cases + 1))
  if [ -n "${REPORT:-}" ]; then
    echo "${problem:-ok} | ${*:2} | $(tail -1 "$work/stderr")"
  elif [ -n "$problem" ]; then
    fail "$problem: $* -> $(cat "$work/stderr")"
  fi
}

p=("$egopd" predict --out "$out" --size 64 --frames 2)
expect_error "--seed must be between 0 and 18446744073709551615" "${p[@]}" --seed 18446744073709551616
expect_error "--seed expects an integer" "${p[@]}" --seed -1
expect_error "--seed expects an integer" "${p[@]}" --seed 1e3
expect_error "--seed expects an integer" "${p[@]}" --seed 12abc
expect_error "--seed expects an integer" "${p[@]}" --seed ""
expect_error "--seed expects an integer" "${p[@]}" --seed " 7"
expect_error "--seed needs a value" "${p[@]}" --seed
expect_error "--size must be between 64 and 4096" "${p[@]}" --size 8192
expect_error "predict: --size must be a multiple of 64 (64..4096), got 100" "${p[@]}" --size 100
expect_error "counterfactual: --size must be a multiple of 64" "$egopd" counterfactual --out "$out" --size 96
expect_error "--frames must be between 1 and 1024" "${p[@]}" --frames 0
expect_error "--frames must be between 1 and 1024" "${p[@]}" --frames 99999999999999999999
expect_error "--frames expects an integer" "${p[@]}" --frames 2.5
expect_error "--steps must be between 1 and 1000" "${p[@]}" --steps 0
expect_error "--steps must be between 1 and 1000" "${p[@]}" --steps 1001
expect_error "--threads must be between 1 and 1024" "${p[@]}" --threads 0
expect_error "--threads expects an integer" "${p[@]}" --threads two
expect_error "--decode-chunk must be between 1 and 1024" "${p[@]}" --decode-chunk 0
expect_error "--guidance" "${p[@]}" --guidance abc
expect_error "--sampler must be euler or lcm" "${p[@]}" --sampler ddim
expect_error "--precision 'int4': expected fp32, bf16 or int8" "${p[@]}" --precision int4
expect_error "--precision needs a value" "${p[@]}" --precision
expect_error "--conv 'fft': expected direct, winograd or auto" "${p[@]}" --conv fft
expect_error "--block-cache-mb must be between 0 and 1048576" "${p[@]}" --block-cache-mb 1048577
expect_error "--block-cache-mb expects an integer" "${p[@]}" --block-cache-mb 1.5
expect_error "EGOPD_BLOCK_CACHE_MB='64M' is not a size in MiB" env EGOPD_BLOCK_CACHE_MB=64M "${p[@]}"
expect_error "EGOPD_BLOCK_CACHE_MB='-1' is not a size in MiB" env EGOPD_BLOCK_CACHE_MB=-1 "${p[@]}"
expect_error "unknown option --precision" "$egopd" evaluate --pred a.csv --gt b.csv --precision bf16
# Positional arguments where a command takes them: the text of tokenize (77 ids per text).
ids=$("$egopd" tokenize "a cup" "of tea" --json 2>"$work/tok.log") || fail "tokenize TEXT: $(tail -1 "$work/tok.log")"
[ "$(printf '%s\n' "$ids" | grep -c '"ids"')" = 2 ] || fail "tokenize: expected two lines of ids, got: $ids"
expect_error "unexpected argument 'clip.mp4'" "$egopd" predict clip.mp4 --out "$out"
expect_error "unknown option --bogus" "${p[@]}" --bogus 1
expect_error "--prompt is not valid UTF-8" "${p[@]}" --prompt $'a \xff cup'
expect_error "--video: the path is not valid UTF-8" "${p[@]}" --video $'clip\xc3.mp4'
expect_error "either --prompt or --meta" "${p[@]}" --prompt "x" --meta "$work/extra.json"
expect_error "wrong_type.json: field 'weight'" "${p[@]}" --meta "$work/wrong_type.json"
expect_error "not_json.json: metadata is not valid JSON" "${p[@]}" --meta "$work/not_json.json"
expect_error "missing.json: metadata file does not exist" "${p[@]}" --meta "$work/missing.json"
expect_error "nowhere.mp4: video file or frame folder does not exist" "${p[@]}" --video "$work/nowhere.mp4"
expect_error "EGOPD_TEMPLATE: no such file" env EGOPD_TEMPLATE="$work/none.json" "${p[@]}"
expect_error "EGOPD_THREADS='abc'" env EGOPD_THREADS=abc "${p[@]}"
expect_error "EGOPD_HUGE_PAGES='2': expected 0 or 1" env EGOPD_HUGE_PAGES=2 "${p[@]}"
expect_error "EGOPD_TOKENIZER_DIR=$work/none: no vocab.json and merges.txt" \
  env EGOPD_TOKENIZER_DIR="$work/none" "$egopd" tokenize hello
expect_error "unexpected argument 'x.csv'" "$egopd" evaluate x.csv --pred a --gt b
expect_error "unexpected argument 'case'" "$egopd" forward case --case a --output b
expect_error "--vary" "$egopd" counterfactual --out "$out" --vary ""
expect_error "--shard 1/1: needs 0 <= I < N" "$egopd" batch --manifest "$work/m.jsonl" --out "$out" --shard 1/1
expect_error "unknown command 'predcit'" "$egopd" predcit --out "$out"
expect_error "--seed expects an integer" "$convert" synth --out "$out" --seed -5
expect_error "--lcm-steps" "$convert" synth --out "$out" --lcm-steps x
expect_error "--geglu needs an even --n" "$egopd" bench gemm --m 4 --n 5 --k 4 --geglu
expect_error "bench vae_decode: --warmup must be between 0 and 100" "$egopd" bench vae_decode --warmup -1
# bench unet --precisions (alternating rounds) is checked before any weights are written or loaded.
expect_error "--precisions: 'int4' is not fp32, bf16 or int8" "$egopd" bench unet --precisions fp32,int4
expect_error "--precisions needs two or more" "$egopd" bench unet --precisions bf16
expect_error "--precisions names bf16 twice" "$egopd" bench unet --precisions bf16,fp32,bf16
expect_error "give --precision or --precisions, not both" "$egopd" bench unet --precision bf16 --precisions fp32,bf16

# Extra metadata fields (a dataset's category, say) are reported by name, and the run goes on.
"${p[@]}" --meta "$work/extra.json" --threads 1 2>"$work/extra.log" || fail "extra field: $(tail -1 "$work/extra.log")"
grep -q "warning: $work/extra.json: field 'category' is not a prompt field" "$work/extra.log" \
  || fail "no warning for the extra field: $(head -3 "$work/extra.log")"
# A bench report says when its "% of peak" counts direct float32 work that Winograd or bf16/int8 do not run.
for conv in direct auto; do
  "$egopd" bench gemm --m 64 --n 64 --k 64 --threads 1 --conv "$conv" --json >"$work/bench_$conv.json" 2>/dev/null \
    || fail "bench gemm --conv $conv"
done
"$egopd" bench gemm --m 64 --n 128 --k 64 --threads 1 --geglu --json >"$work/bench_geglu.json" 2>/dev/null \
  || fail "bench gemm --geglu"
grep -q '"geglu":true' "$work/bench_geglu.json" || fail "bench gemm --geglu: $(cat "$work/bench_geglu.json")"
grep -q '"percent_of_peak_is"' "$work/bench_direct.json" && fail "direct fp32 report qualifies its % of peak"
grep -q '"percent_of_peak_is":"direct-fp32-equivalent' "$work/bench_auto.json" \
  || fail "--conv auto report does not qualify its % of peak: $(cat "$work/bench_auto.json")"
# The block cache limit a bench report names: the flag's, over the environment's.
for setting in "7|--block-cache-mb 7" "5|env EGOPD_BLOCK_CACHE_MB=5" "9|env EGOPD_BLOCK_CACHE_MB=5 --block-cache-mb 9" \
  "0|--block-cache-mb 0"; do
  want=${setting%%|*}
  read -r -a how <<<"${setting#*|}"
  if [ "${how[0]}" = env ]; then cmd=(env "${how[1]}" "$egopd" bench gemm "${how[@]:2}")
  else cmd=("$egopd" bench gemm "${how[@]}"); fi
  "${cmd[@]}" --m 8 --n 8 --k 8 --threads 1 --json >"$work/bench_cache.json" 2>/dev/null || fail "${cmd[*]}"
  grep -q "\"block_cache_mb\":$want," "$work/bench_cache.json" || fail "${cmd[*]}: $(cat "$work/bench_cache.json")"
done
rm -rf "$work"
echo "arguments and metadata: $cases malformed invocations rejected with one line each; extra metadata reported"
