// `egopd predict`: grasp pressure of one clip (heatmap PNGs, side-by-side MP4, taxels.csv, summary.json).
#include "cli/commands.h"
#include "cli/predict_options.h"
#include "core/error.h"

namespace egopd {

PredictOptions read_predict_options(const Args& a) {
  PredictOptions o;
  o.model_dir = a.get("model", "");
  o.video = a.get("video", "");
  o.masks_dir = a.get("masks", "");
  o.meta_path = a.get("meta", "");
  if (a.has("prompt")) o.prompt = a.get("prompt", "");
  o.sampler = a.get("sampler", "");
  // Bounds as documented in `egopd predict --help`.
  o.steps = int(a.get_int("steps", 0, 1, 1000));
  o.seed = a.get_uint64("seed", 0);
  o.frames = a.get_int("frames", 0, 1, 1024);
  o.size = a.get_int("size", 256, 64, 4096);
  if (o.size % 64)
    throw Error(a.command() + ": --size must be a multiple of 64 (64..4096), got " + std::to_string(o.size));
  if (a.has("guidance")) o.guidance = parse_guidance(a.get("guidance", ""));
  o.decode_chunk = a.get_int("decode-chunk", 0, 1, 1024);
  o.low_mem = a.flag("low-mem");
  o.template_path = a.get("template", "");
  o.out_dir = a.require("out");
  return o;
}

int cmd_predict(const Args& a) {
  const PredictOptions o = read_predict_options(a);
  a.finish();
  return run_with_library(o, nullptr);
}

}  // namespace egopd
