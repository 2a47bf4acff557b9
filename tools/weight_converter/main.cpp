// egopd-convert: builds, converts and checks EgoPressureDiff model directories (weights.md). Every failure is one
// line "egopd-convert: <message>" on stderr and exit status 1; every output file is written atomically.
#include <cstdio>
#include <cstring>
#include <iostream>
#include <string>
#include <vector>

#include <filesystem>
#include <functional>

#include "cli/args.h"
#include "convert/dtype_convert.h"
#include "convert/from_original.h"
#include "convert/graft.h"
#include "convert/inspect.h"
#include "convert/tensor_io.h"
#include "core/error.h"
#include "pipeline/synthetic_model.h"

namespace egopd {
namespace {

WriteOptions write_options(const Args& a) {
  WriteOptions w;
  w.shard_bytes = shard_bytes_from_mb(a.get_int("shard-size", 0));
  return w;
}

std::string single_positional(const Args& a, const char* what) {
  if (a.positional().size() != 1) throw Error(a.command() + ": expected exactly one " + what);
  return a.positional()[0];
}

int cmd_synth(const Args& a) {
  const std::string preset = a.get("config", "tiny");
  const std::string out = a.require("out");
  const uint64_t seed = a.get_uint64("seed", 0);
  const std::string d = a.get("dtype", preset == "svd-xt" ? "f16" : "f32");
  const int64_t lcm = a.get_int("lcm-steps", 0);
  a.finish();
  const TargetDType t = parse_target_dtype(d);
  if (t == TargetDType::Q8) throw Error("synth: --dtype must be f16, f32 or bf16 (quantise afterwards with dtype --to q8)");
  const DType dtype = t == TargetDType::F16 ? DType::F16 : t == TargetDType::BF16 ? DType::BF16 : DType::F32;
  write_model_folder(out, "model_index.json", [&](const std::string& dir) {
    write_synthetic_model(dir, preset, uint64_t(seed), dtype, int(lcm));
  });
  std::string sampler = "Euler 25 steps";
  if (lcm) sampler = "AnimateLCM " + std::to_string(lcm) + " steps";
  std::printf("wrote %s model (%s, seed %llu, %s) to %s\n", preset.c_str(), dtype_name(dtype),
              static_cast<unsigned long long>(seed), sampler.c_str(), out.c_str());
  return 0;
}

int cmd_from_original(const Args& a) {
  FromOriginalOptions o;
  o.preset = a.get("config", "svd-xt");
  o.write = write_options(a);
  const std::string out = a.require("out");
  const std::string src = single_positional(a, "checkpoint (.safetensors or .safetensors.index.json)");
  a.finish();
  FromOriginalReport r;
  write_model_folder(out, "model_index.json", [&](const std::string& dir) { r = convert_from_original(src, dir, o); });
  std::printf("mapped %zu source tensors (%zu dropped) to %zu tensors in %s\n", r.mapped, r.dropped, r.written,
              out.c_str());
  return 0;
}

int cmd_graft(const Args& a) {
  GraftOptions o;
  o.svd_dir = a.require("svd");
  o.text_encoder_dir = a.require("text-encoder");
  o.tokenizer_dir = a.require("tokenizer");
  o.out_dir = a.require("out");
  o.seed = a.get_uint64("seed", o.seed);
  o.write = write_options(a);
  a.finish();
  write_model_folder(o.out_dir, "model_index.json", [&](const std::string& dir) {
    GraftOptions into = o;
    into.out_dir = dir;
    graft_model(into);
  });
  std::printf("wrote EgoPressureDiff model (zero-initialised PIFR, mask encoder with zero conv_out) to %s\n",
              o.out_dir.c_str());
  return 0;
}

int cmd_dtype(const Args& a) {
  const TargetDType to = parse_target_dtype(a.require("to"));
  const std::string out = a.require("out");
  const WriteOptions w = write_options(a);
  const std::string in = single_positional(a, "model directory or weight file");
  a.finish();
  DTypeReport r;
  if (std::filesystem::is_directory(in)) {  // a model or component folder: written whole
    const bool model = std::filesystem::exists(std::filesystem::path(in) / "model_index.json");
    write_model_folder(out, model ? "model_index.json" : "config.json",
                       [&](const std::string& dir) { r = convert_dtype(in, dir, to, w); });
  } else {  // one weight file or index: its files are written atomically
    r = convert_dtype(in, out, to, w);
  }
  std::printf("converted %zu weight files (%zu tensors, %zu quantised; %zu other files copied): %.1f MiB -> %.1f MiB\n",
              r.files, r.tensors, r.quantized, r.copied_files, double(r.bytes_in) / 1048576.0,
              double(r.bytes_out) / 1048576.0);
  return 0;
}

int cmd_inspect(const Args& a) {
  InspectOptions o;
  o.list_tensors = !a.flag("summary");
  const std::string path = single_positional(a, "model directory, component folder or weight file");
  a.finish();
  return inspect_path(path, std::cout, o) ? 1 : 0;
}

struct Command {
  const char* name;
  int (*run)(const Args&);
  const char* usage;
};

const Command kCommands[] = {
    {"synth", cmd_synth,
     "egopd-convert synth --out DIR [--config tiny|svd-xt] [--seed S] [--dtype f32|f16|bf16] [--lcm-steps 0|4|8]\n"
     "  A complete model directory with deterministic random weights (tiny: small and fast, default f32;\n"
     "  svd-xt: real sizes, default f16). --lcm-steps N > 0 writes an AnimateLCM student (N default steps)."},
    {"from-original", cmd_from_original,
     "egopd-convert from-original SVD_XT.safetensors --out DIR [--config svd-xt|tiny] [--shard-size MB]\n"
     "  Stability's single-file SVD checkpoint -> unet/, vae/, image_encoder/ (+ configs, scheduler,\n"
     "  feature_extractor, model_index.json). Unmapped, missing or mis-shaped keys are listed and are an error."},
    {"graft", cmd_graft,
     "egopd-convert graft --svd DIR --text-encoder DIR --tokenizer DIR --out DIR [--seed S] [--shard-size MB]\n"
     "  Stock SVD-xt directory -> EgoPressureDiff directory: zero-initialised PIFR (identical output to the stock\n"
     "  U-Net for any prompt), mask encoder with zero conv_out, text encoder and tokenizer copied."},
    {"dtype", cmd_dtype,
     "egopd-convert dtype --to f32|f16|bf16|q8 IN --out OUT [--shard-size MB]\n"
     "  Converts every weight file of a model directory (or one weight file). q8: int8 linear/conv weights with\n"
     "  one F32 scale per output channel (<key>_scale); norms, embeddings and biases stay float."},
    {"inspect", cmd_inspect,
     "egopd-convert inspect DIR|FILE [--summary]\n"
     "  Tensors (name, dtype, shape, bytes), configs and totals; checks each component's keys and shapes against\n"
     "  the model built from its config. Exit status 1 if a problem is found. --summary omits the tensor list."},
};

void print_help() {
  std::printf("egopd-convert - EgoPressureDiff model-directory tools\n\nusage: egopd-convert COMMAND [options]\n\n");
  for (const auto& c : kCommands) std::printf("%s\n\n", c.usage);
}

int run(int argc, char** argv) {
  if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h") || !std::strcmp(argv[1], "help")) {
    print_help();
    return argc < 2 ? 1 : 0;
  }
  const std::string name = argv[1];
  std::vector<std::string> rest(argv + 2, argv + argc);
  for (const auto& c : kCommands) {
    if (name != c.name) continue;
    for (const auto& r : rest)
      if (r == "--help" || r == "-h") {
        std::printf("%s\n", c.usage);
        return 0;
      }
    return c.run(Args(name, rest));
  }
  throw Error("unknown command '" + name + "' (see egopd-convert --help)");
}

}  // namespace
}  // namespace egopd

int main(int argc, char** argv) {
  return egopd::run_reporting_errors("egopd-convert", [&] { return egopd::run(argc, argv); });
}
