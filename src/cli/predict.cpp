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
  const int64_t steps = a.get_int("steps", 0);
  if (a.has("steps") && (steps < 1 || steps > 1000)) throw Error(a.command() + ": --steps must be between 1 and 1000");
  o.steps = int(steps);
  const int64_t seed = a.get_int("seed", 0);
  if (seed < 0) throw Error(a.command() + ": --seed must be >= 0");
  o.seed = uint64_t(seed);
  o.frames = a.get_int("frames", 0);
  if (a.has("frames") && (o.frames < 1 || o.frames > 1024))
    throw Error(a.command() + ": --frames must be between 1 and 1024");
  o.size = a.get_int("size", 256);
  if (a.has("guidance")) o.guidance = parse_guidance(a.get("guidance", ""));
  o.decode_chunk = a.get_int("decode-chunk", 0);
  if (a.has("decode-chunk") && o.decode_chunk < 1) throw Error(a.command() + ": --decode-chunk must be at least 1");
  o.low_mem = a.flag("low-mem");
  o.template_path = a.get("template", "");
  o.out_dir = a.require("out");
  return o;
}

int cmd_predict(const Args& a) {
  const PredictOptions o = read_predict_options(a);
  a.finish();
  return run_predict(o);
}

}  // namespace egopd
