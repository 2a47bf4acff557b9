// egopd: command-line entry point. Every failure is a one-line "egopd: <message>" on stderr and exit code 1.
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "core/block_pool.h"
#include "core/cpu.h"
#include "core/error.h"
#include "core/kernels/conv.h"
#include "core/kernels/gemm.h"
#include "core/memory.h"
#include "core/threading.h"
#include "egopd/version.h"

namespace egopd {
namespace {

struct Command {
  const char* name;
  int (*run)(const Args&);
  const char* usage;
};

struct BenchTarget {
  const char* name;
  int (*run)(const Args&);
  const char* usage;
};

const BenchTarget kBenchTargets[] = {
    {"pipeline", bench_pipeline,
     "[--config svd-xt|tiny] [--steps 25|8|4] [--frames 16] [--size 256] [--dtype f16|f32|bf16|q8] [--low-mem]\n"
     "      [--decode-chunk N] [--model DIR]   one whole prediction (25 steps: Euler teacher, else AnimateLCM student)\n"
     "      [--save-result FILE] [--compare-to FILE]   save latents, decoded clip and taxels / report their rel_l2\n"
     "      and max_abs error against a saved run (e.g. --precision bf16 against an fp32 run)"},
    {"unet", bench_unet,
     "[--config svd-xt] [--frames 16] [--size 256] [--dtype f16|f32|bf16] [--evals 1] [--warmup 1] [--pifr]\n"
     "      [--weights DIR] [--kernel-profile]   the profile: time, calls and GFLOP/s per GEMM, convolution and\n"
     "      attention shape\n"
     "      [--precisions fp32,bf16,int8]   alternate: each round one evaluation per precision, in this order; the\n"
     "      report gives each one's seconds and the first one's time over each other's, per round and their median,\n"
     "      and per stage; with --kernel-profile each one's profile and that ratio per kind of kernel call"},
    {"clip_image", bench_clip_image, "[--config svd-xt] [--dtype f16|f32|bf16] [--repeat 1]"},
    {"clip_text", bench_clip_text, "[--config svd-xt] [--dtype f16|f32|bf16] [--repeat 1]"},
    {"vae_encode", bench_vae_encode,
     "[--config svd-xt] [--frames 16] [--size 256] [--dtype f16|f32|bf16] [--repeat 1] [--warmup 0]\n"
     "      [--kernel-profile]"},
    {"vae_decode", bench_vae_decode,
     "[--config svd-xt] [--frames 16] [--size 256] [--dtype f16|f32|bf16] [--decode-chunk N] [--repeat 1]\n"
     "      [--warmup 0] [--kernel-profile]   --warmup: untimed calls first (clip_*: always one)"},
    {"gemm", bench_gemm, "--m M --n N --k K [--dtype f32|f16|bf16] [--trans-b] [--geglu] [--repeat R]"},
    {"conv2d", bench_conv2d,
     "--frames N --cin C --cout C --h H --w W --kernel 3 [--stride 1] [--dtype f32|f16|bf16] [--repeat R]\n"
     "      (GFLOP per call 2*outputs*cin*kh*kw also for Winograd: direct-equivalent GFLOP/s)"},
};

int cmd_bench(const Args& a);

const Command kCommands[] = {
    {"forward", cmd_forward,
     "egopd forward --case DIR --output FILE [--check]\n"
     "  Runs a golden case folder (case.json, model/, inputs.safetensors) and writes every output tensor to FILE\n"
     "  (safetensors, written atomically). --check also compares with the case's expected.safetensors."},
    {"evaluate", cmd_evaluate,
     "egopd evaluate --pred taxels.csv|DIR --gt GT.csv|DIR [--template FILE] [--json FILE] [--stabilize-predictions]\n"
     "       egopd evaluate --manifest MANIFEST.jsonl --pred DIR [--name RUN] [--json F] [--markdown F] [--csv F]\n"
     "  Temporal accuracy, contact IoU, volumetric IoU, MAE (N) and part-wise CoP error of predicted taxels (CSV\n"
     "  frame,p0..p161 in N) against raw glove readings (stabilised and normalised here). Directories: clips are\n"
     "  matched by file name and the sums pooled over all frames of the split. --json writes the results\n"
     "  (atomically). Default template: the shipped synthetic one (EGOPD_TEMPLATE overrides).\n"
     "  --manifest: a batch run's outputs (DIR/ID/taxels.csv) against each clip's gt, pooled per split in the\n"
     "  paper's main-table layout (one row, five columns per split, then 'all'); --csv per-clip rows. Clips that are\n"
     "  missing or failed are listed by name and the exit status is 1 (the tables are still written). Ground-truth\n"
     "  heatmaps are read out to taxels with the predictions' template and operator, then taken as glove readings."},
    {"tokenize", cmd_tokenize,
     "egopd tokenize TEXT... [--tokenizer DIR] [--pad-id N] [--json]\n"
     "  Prints the 77 CLIP BPE ids of each TEXT (BOS, content, EOS, padding). DIR holds vocab.json + merges.txt\n"
     "  (+ tokenizer_config.json, whose pad_token sets the padding id; default 49407), e.g. a model's tokenizer/.\n"
     "  Default DIR: the CLIP tokenizer shipped with egopd (EGOPD_TOKENIZER_DIR, else share/egopd/tokenizer next\n"
     "  to the executable, else the source tree's data/tokenizer). Longer prompts are truncated to 77 ids (EOS kept\n"
     "  last) with a warning on stderr."},
    {"predict", cmd_predict,
     "egopd predict [--model DIR --video CLIP.mp4|FRAMES_DIR] [--masks DIR] [--meta META.json | --prompt TEXT]\n"
     "              [--sampler euler|lcm] [--steps N] [--seed 0] [--frames 16] [--size 256] [--guidance MIN,MAX]\n"
     "              [--decode-chunk N] [--low-mem] [--template FILE] --out DIR\n"
     "  Bounds: --seed 0..2^64-1, --frames 1..1024, --steps 1..1000, --size 64..4096 (a multiple of 64),\n"
     "  --decode-chunk 1..1024, --threads 1..1024; anything else (and any argument without --name) is an error.\n"
     "  Frame folders are read in frame-number order (2.png before 10.png); a folder of the data release's\n"
     "  NNNNN_rgb.png / NNNNN_mask.png / NNNNN_pressure.png files uses the *_rgb (frames) and *_mask (masks) images.\n"
     "  --meta: a JSON object of the prompt fields obj_name, weight, material, gender, age, subj_weight, bodyfat;\n"
     "  any other key (a dataset's category, hand length, ... or a misspelt field) gets a warning naming it.\n"
     "  Grasp pressure of a clip: F frames sampled uniformly, squashed to SIZE x SIZE; masks: one image per sampled\n"
     "  frame (> 127 = hand). Prompt: --prompt verbatim, or built from --meta fields; neither: no-text mode.\n"
     "  Sampler/steps default to the model's scheduler (--sampler lcm on an Euler model: 4 steps). Writes into DIR:\n"
     "  heatmap_NNN.png, side_by_side.mp4 (RGB | heatmap, 5 fps), taxels.csv (N), summary.json.\n"
     "  Without --model / --video: a built-in tiny SYNTHETIC model (random weights, cached in $XDG_CACHE_HOME/egopd\n"
     "  or ~/.cache/egopd) and a synthetic sample clip (saved as DIR/sample_clip.mp4): a demo, not real pressures.\n"
     "  --low-mem: load one component at a time and release it after use, page CLIP, U-Net and VAE-decoder weights\n"
     "  out layer by layer, run the VAE's temporal layers in small tiles: the same results in a fraction of the\n"
     "  memory, a little slower (real-size 16 x 256x256 with F16 weights: about 1 GB peak instead of 3.8 GB).\n"
     "  --decode-chunk N: decode N frames per VAE call (diffusers' decode_chunk_size; changes the decoded frames)."},
    {"counterfactual", cmd_counterfactual,
     "egopd counterfactual --vary FIELD=v1,v2,...,omit [predict options] --out DIR\n"
     "  The same clip and seed under prompt variants of one field (obj_name, weight, material, gender, age,\n"
     "  subj_weight, bodyfat; base values from --meta; a bare number gets the field's unit, `omit` drops the field).\n"
     "  Encodes the clip once and denoises once per variant. Writes DIR/<field>_<value>/ (predict's outputs),\n"
     "  comparison.png (rows = variants, 4 frames) and forces.csv (mean / peak total force in N per variant)."},
    {"manifest", cmd_manifest,
     "egopd manifest --root DIR [--list motion_list.txt] [--attributes FILE] --out MANIFEST.jsonl\n"
     "  One JSON line per clip of a dataset tree: sequence folders (from --list, else ROOT/motion_list.txt, else\n"
     "  every sub-folder) named <subject>-<object>-<take> holding NNNNN_rgb.png frames, optional NNNNN_mask.png\n"
     "  hint masks and NNNNN_pressure.png ground-truth heatmaps (or one video file / a taxels.csv). --attributes: a\n"
     "  JSON file of prompt fields per object and per subject and held-out splits (see README, \"Running a\n"
     "  benchmark split\"). Fields of a line: id, frames, masks, meta | prompt, gt, split; paths relative to the\n"
     "  manifest's folder. Manifests may also be written by hand."},
    {"batch", cmd_batch,
     "egopd batch --manifest MANIFEST.jsonl --out DIR [--shard I/N] [predict options]\n"
     "  (predict's options except --video, --masks, --meta and --prompt, which each manifest line gives)\n"
     "  Every clip of the manifest with the model loaded once; outputs of clip ID in DIR/ID/ (as predict writes\n"
     "  them), each folder appearing whole. A clip whose folder exists is skipped, so running the same command again\n"
     "  resumes. A clip that fails is recorded in DIR/ID.failed (its error) and the batch goes on; exit status 1 if\n"
     "  any failed (a re-run retries them). --shard I/N runs clips k with k % N == I; without it, a Slurm array task\n"
     "  takes its shard from SLURM_ARRAY_TASK_ID / SLURM_ARRAY_TASK_COUNT (arrays must be 0-based), else every clip.\n"
     "  Threads: --threads, else EGOPD_THREADS, else SLURM_CPUS_PER_TASK, else the physical cores.\n"
     "  SIGINT/SIGTERM: the current clip is abandoned with nothing half-written; exit 130/143; re-run to resume.\n"
     "  Every clip uses the same --seed. Progress: [k/n ID] lines per clip and step, clips/hour at the end."},
    {"bench", cmd_bench,
     "egopd bench TARGET [options] [--threads T] [--conv direct|winograd|auto] [--json]\n"
     "  Measures one target and prints seconds (median per call), GFLOP/s, % of peak and peak RSS.\n"
     "  Targets: pipeline, unet, vae_encode, vae_decode, clip_image, clip_text, gemm, conv2d.\n"
     "  --conv: the convolution algorithm (see egopd --help); the report records it.\n"
     "  pipeline, unet and clip_* write their synthetic weights once into $XDG_CACHE_HOME/egopd (else\n"
     "  ~/.cache/egopd) and reuse them (up to 6 GB each at real size: delete the bench-* entries to free the space)."},
};

int cmd_bench(const Args& a) {
  if (a.positional().empty()) throw Error("bench: name a target (see egopd bench --help)");
  const std::string t = a.positional()[0];
  for (const auto& b : kBenchTargets)
    if (t == b.name) {
      peak_gflops(num_threads());  // the first probe, before the run; the report probes again after it
      return b.run(a);
    }
  throw Error("bench: unknown target '" + t + "' (see egopd bench --help)");
}

void print_help() {
  std::printf(
      "egopd %s - CPU runtime for EgoPressureDiff (grasp pressure from egocentric video)\n\n"
      "usage: egopd COMMAND [options]   (egopd COMMAND --help for details)\n\n"
      "commands:\n",
      EGOPD_VERSION);
  for (const auto& c : kCommands) {
    std::string first(c.usage, std::strchr(c.usage, '\n') ? std::strchr(c.usage, '\n') : c.usage + std::strlen(c.usage));
    std::printf("  %s\n", first.c_str());
  }
  std::printf(
      "\ncommon options:\n"
      "  --threads N   worker threads (default: EGOPD_THREADS, else the number of physical cores)\n"
      "  --conv direct|winograd|auto   3x3 stride-1 and temporal (3,1,1) convolutions (predict, counterfactual,\n"
      "                batch, bench; default auto): direct, Winograd (F(4x4,3x3), F(2x2,3x3) on frames under 8\n"
      "                pixels; F(2,3) or F(4,3) along time), or auto: Winograd on layers with 16+ channels, 4x4+\n"
      "                frames and 512+ pixels over all frames (1024+ under 8x8; temporal: 32+ pixels per frame),\n"
      "                else direct.\n"
      "  --precision fp32|bf16|int8   arithmetic of the linear layers and convolutions (predict, counterfactual,\n"
      "                batch, bench, forward; default fp32). bf16: operands rounded to bfloat16, float32 sums;\n"
      "                vdpbf16ps on CPUs with AVX512-BF16, an exact but slower emulation elsewhere. int8: operands\n"
      "                quantised to int8 with a dynamic scale per row/column and K block of 512, exact int32 sums;\n"
      "                vpdpbusd on AVX512-VNNI, vpmaddubsw on AVX2 (there weights, and a convolution's inputs,\n"
      "                take 63 levels instead of 127: about twice their rounding), an exact but slower emulation\n"
      "                elsewhere. On AVX2, 3x3 convolutions on frames of 16+ pixels that auto sends to Winograd\n"
      "                run it in float32 on quantised operands (inputs per pixel, 127 levels); --conv winograd\n"
      "                does so on every path. Norms, the softmax and the sampler stay float32; attention's\n"
      "                products are bfloat16 under bf16 (softmax weights rounded too), float32 under int8. Check\n"
      "                the error on your model against an fp32 run (egopd bench pipeline --save-result /\n"
      "                --compare-to).\n"
      "  --block-cache-mb N   MiB of freed activation blocks (of 1 MiB and more) kept for reuse instead of being\n"
      "                given back to the system (predict, counterfactual, batch, bench, forward; default 1024):\n"
      "                memory fresh from the system costs a page fault per 4 KiB on first use. 0 keeps none (less\n"
      "                memory, slower on some machines); --low-mem keeps none either.\n"
      "environment:\n"
      "  EGOPD_THREADS   default thread count\n"
      "  EGOPD_CONV      default of --conv\n"
      "  EGOPD_BLOCK_CACHE_MB   default of --block-cache-mb\n"
      "  EGOPD_HUGE_PAGES   0: no transparent huge pages for buffers of 4 MiB and more (default 1)\n"
      "  EGOPD_KERNELS   kernel path: avx512, avx2 or portable (default: the best this CPU supports;\n"
      "                  EGOPD_PORTABLE=1 is the same as EGOPD_KERNELS=portable)\n");
}

int run(int argc, char** argv) {
  std::vector<std::string> rest(argv + 1, argv + argc);
  if (rest.empty() || rest[0] == "--help" || rest[0] == "-h" || rest[0] == "help") {
    print_help();
    return rest.empty() ? 2 : 0;
  }
  if (rest[0] == "--version") {
    const CpuInfo& ci = cpu_info();
    // What --precision bf16 and int8 run on this path (int8's numbers depend on it: 63 levels for B on AVX2).
    std::printf("egopd %s (kernels: %s, %s; conv: %s; bf16: %s; int8: %s; cpu: %s)\n", EGOPD_VERSION,
                kernel_path_name(kernel_path()), kernel_path_features(kernel_path()).c_str(),
                conv_algo_name(conv_algo()), bf16_native() ? "vdpbf16ps" : "emulated", int8_kernel(),
                ci.description().c_str());
    return 0;
  }
  const std::string name = rest[0];
  rest.erase(rest.begin());
  for (const auto& c : kCommands) {
    if (name != c.name) continue;
    for (const auto& r : rest)
      if (r == "--help" || r == "-h") {
        std::printf("%s\n", c.usage);
        if (name == "bench")
          for (const auto& b : kBenchTargets) std::printf("  egopd bench %s %s\n", b.name, b.usage);
        return 0;
      }
    Args a(name, rest);
    init_threads_from_env();
    huge_pages_enabled();  // a malformed EGOPD_HUGE_PAGES is an error before any work
    if (a.has("threads")) {
      set_num_threads(int(a.get_int("threads", 0, 1, 1024)));
    }
    const bool runs_models = name == "predict" || name == "counterfactual" || name == "bench" || name == "batch";
    if (runs_models && a.has("conv")) {
      const std::string v = a.get("conv", "auto");
      ConvAlgo algo;
      if (!conv_algo_from_name(v, &algo)) throw Error(name + ": --conv '" + v + "': expected direct, winograd or auto");
      set_conv_algo(algo);
    }
    // Reduced-precision arithmetic: the commands that run models (forward: to measure its error on the golden cases,
    // whose tolerances are float32's).
    if ((runs_models || name == "forward") && a.has("precision")) {
      const std::string v = a.get("precision", "fp32");
      Precision p;
      if (!parse_precision(v.c_str(), &p)) throw Error(name + ": --precision '" + v + "': expected fp32, bf16 or int8");
      set_precision(p);
    }
    if (runs_models || name == "forward")
      set_block_cache_limit(a.has("block-cache-mb") ? size_t(a.get_int("block-cache-mb", 0, 0, kMaxBlockCacheMb)) << 20
                                                    : block_cache_limit_from_env());
    return c.run(a);
  }
  throw Error("unknown command '" + name + "' (see egopd --help)");
}

}  // namespace
}  // namespace egopd

int main(int argc, char** argv) {
  return egopd::run_reporting_errors("egopd", [&] { return egopd::run(argc, argv); });
}
