// `egopd bench clip_image` / `egopd bench clip_text`: the real-size SVD-xt CLIP towers (OpenCLIP ViT-H/14 image
// tower at 224x224; OpenCLIP-H text tower at 77 tokens) with deterministic random weights.
#include <cstdio>
#include <memory>
#include <vector>

#include "cli/commands.h"
#include "clip_image/clip_vision.h"
#include "clip_text/clip_text.h"
#include "core/error.h"
#include "core/threading.h"

namespace egopd {

namespace {

ClipVisionConfig svd_xt_image_encoder() {  // clip.md §2
  ClipVisionConfig c;
  c.encoder = ClipEncoderConfig{1280, 5120, 16, 32, 1e-5f, Act::GELU};
  c.image_size = 224;
  c.patch_size = 14;
  c.num_channels = 3;
  c.projection_dim = 1024;
  return c;
}

ClipTextConfig openclip_h_text_encoder() {  // clip.md §3, default text encoder
  ClipTextConfig c;
  c.encoder = ClipEncoderConfig{1024, 4096, 16, 24, 1e-5f, Act::GELU};
  c.vocab_size = 49408;
  c.max_position_embeddings = 77;
  c.eos_token_id = 49407;
  return c;
}

struct BenchOptions {
  DType dtype = DType::F16;
  int64_t repeat = 1;
  bool json = false;
};

BenchOptions read_options(const Args& a, const std::string& target) {
  BenchOptions o;
  const std::string config = a.get("config", "svd-xt");
  o.dtype = parse_weight_dtype(a.get("dtype", "f16"), "dtype");
  o.repeat = a.get_int("repeat", 1);
  o.json = a.flag("json");
  a.finish();
  if (config != "svd-xt") throw Error("bench " + target + ": --config must be svd-xt (got '" + config + "')");
  if (o.repeat < 1 || o.repeat > 1000) throw Error("bench " + target + ": --repeat must be between 1 and 1000");
  return o;
}

// Random weights for every parameter a model asks for (cached: bench_synthetic_weights).
template <class Model, class Config>
std::shared_ptr<const WeightMap> synthetic_weights(const Config& cfg, const std::string& bench,
                                                   const std::string& label, DType dtype) {
  auto recorder = std::make_shared<WeightMap>(WeightMap::recorder(label));
  Model shape_only(cfg, recorder);
  return bench_synthetic_weights(bench, label, recorder->recorded(), dtype);
}

}  // namespace

int bench_clip_image(const Args& a) {
  const BenchOptions o = read_options(a, "clip_image");
  const ClipVisionConfig cfg = svd_xt_image_encoder();
  const ClipVisionModelWithProjection model(
      cfg, synthetic_weights<ClipVisionModelWithProjection>(cfg, "clip_image", "image_encoder", o.dtype));
  Tensor pixels({1, 3, cfg.image_size, cfg.image_size});
  for (int64_t i = 0; i < pixels.numel(); ++i) pixels[i] = float((i * 7919) % 2001) / 1000.0f - 1.0f;
  float sink = 0;
  BenchReport r;
  r.target = "clip_image";
  r.threads = num_threads();
  // After one untimed call: the first touches of the mapped weights.
  const CallTimes t = median_call_times(o.repeat, true, [&] { sink += model.forward(pixels).image_embeds[0]; });
  r.seconds = t.wall, r.cpu_seconds = t.cpu;
  r.gflop = model.flops_per_image() * 1e-9;
  r.extra["config"] = "svd-xt";
  r.extra["dtype"] = dtype_name(o.dtype);
  r.extra["image_size"] = cfg.image_size;
  r.extra["repeat"] = o.repeat;
  r.extra["checksum"] = sink;
  print_bench_report(r, o.json);
  return 0;
}

int bench_clip_text(const Args& a) {
  const BenchOptions o = read_options(a, "clip_text");
  const ClipTextConfig cfg = openclip_h_text_encoder();
  const ClipTextModel model(cfg, synthetic_weights<ClipTextModel>(cfg, "clip_text", "text_encoder", o.dtype));
  const int64_t len = cfg.max_position_embeddings;
  // A 60-token prompt: BOS, content ids, EOS, then padding with 0 (every position is computed either way).
  IdTensor ids{Shape{1, len}, std::vector<int64_t>(size_t(len), 0)};
  ids.values[0] = 49406;
  for (int64_t j = 1; j < 59; ++j) ids.values[size_t(j)] = 300 + (j * 7919) % 40000;
  ids.values[59] = 49407;
  float sink = 0;
  BenchReport r;
  r.target = "clip_text";
  r.threads = num_threads();
  const CallTimes t = median_call_times(o.repeat, true, [&] { sink += model.forward(ids).last_hidden_state[0]; });
  r.seconds = t.wall, r.cpu_seconds = t.cpu;
  r.gflop = model.flops_per_sequence(len) * 1e-9;
  r.extra["config"] = "svd-xt";
  r.extra["dtype"] = dtype_name(o.dtype);
  r.extra["tokens"] = len;
  r.extra["repeat"] = o.repeat;
  r.extra["checksum"] = sink;
  print_bench_report(r, o.json);
  return 0;
}

}  // namespace egopd
