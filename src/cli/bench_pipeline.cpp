// `egopd bench pipeline`: one whole prediction — frame decode + resize, the encoders, every sampler step, the
// temporal VAE decode and the taxel read-out — on a synthetic model and the built-in synthetic clip, with a
// per-stage breakdown, FPS and peak RSS (the figures of BENCHMARKS.md). Synthetic model directories are written
// once into the cache folder and reused: writing a real-size one takes longer than running it.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <system_error>

#include <opencv2/imgproc.hpp>

#include "cli/commands.h"
#include "convert/dtype_convert.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/safetensors.h"
#include "core/threading.h"
#include "core/timing.h"
#include "pipeline/egopressurediff.h"
#include "pipeline/media.h"
#include "pipeline/predict_run.h"
#include "pipeline/synthetic_model.h"
#include "scheduler/guidance.h"

namespace egopd {
namespace fs = std::filesystem;

namespace {

constexpr uint64_t kModelSeed = 0;
// The source clip is bigger than the model input so the decode + resize stage does real down-scaling work, as on
// a camera clip (the built-in sample clip is square; predict squashes any aspect ratio the same way).
constexpr int kSourceSize = 640;
constexpr double kSourceFps = 5;

// bench-<config>-<dtype>-<synthetic_model_id> in the benchmarks' cache folder (cached_bench_folder); q8 is named by the
// F16 model it quantises. One folder per dtype serves every step count: the teacher and its AnimateLCM students
// have the same architecture, and the run picks the sampler.
fs::path ensure_model(const std::string& config, const std::string& dtype) {
  const DType weights = parse_weight_dtype(dtype == "q8" ? "f16" : dtype, "dtype");
  const std::string name =
      "bench-" + config + "-" + dtype + "-" + synthetic_model_id(config, kModelSeed, weights, /*lcm_steps=*/0);
  return cached_bench_folder(name, "model_index.json", [&](const std::string& tmp) {
    if (dtype == "q8") {
      // q8 is the converter's per-channel int8 quantisation of a float model (the F16 one, reused by f16 runs).
      const fs::path base = ensure_model(config, "f16");
      std::fprintf(stderr, "bench pipeline: quantising %s to q8 (%s)\n", base.c_str(), name.c_str());
      convert_dtype(base.string(), tmp, TargetDType::Q8, WriteOptions{});
    } else {
      std::fprintf(stderr, "bench pipeline: writing a synthetic %s model (%s) as %s\n", config.c_str(), dtype.c_str(),
                   name.c_str());
      write_synthetic_model(tmp, config, kModelSeed, weights, /*lcm_steps=*/0);
    }
  });
}

uint64_t weight_file_bytes(const fs::path& dir) {
  uint64_t n = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file() && e.path().extension() == ".safetensors") n += e.file_size();
  return n;
}

// The synthetic clip as an MP4 of kSourceSize frames in a private temporary folder (removed on exit).
struct SourceClip {
  fs::path dir, file;
  explicit SourceClip(int frames) {
    dir = fs::temp_directory_path() / ("egopd-bench-pipeline-" + std::to_string(::getpid()));
    fs::create_directories(dir);
    file = dir / "clip.mp4";
    std::vector<cv::Mat> bgr;
    for (const cv::Mat& m : synthetic_sample_clip(frames, kSourceSize)) {
      cv::Mat b;
      cv::cvtColor(m, b, cv::COLOR_RGB2BGR);
      bgr.push_back(b);
    }
    write_video_atomic(file.string(), bgr, kSourceFps);
  }
  ~SourceClip() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

}  // namespace

int bench_pipeline(const Args& a) {
  const std::string config = a.get("config", "svd-xt");
  const int64_t steps = a.get_int("steps", 25);
  const int64_t frames = a.get_int("frames", 16);
  const int64_t size = a.get_int("size", 256);
  const std::string dtype = a.get("dtype", "f16");
  const bool low_mem = a.flag("low-mem");
  const int64_t decode_chunk = a.get_int("decode-chunk", 0);
  const std::string model_arg = a.get("model", "");
  const std::string save_result = a.get("save-result", "");
  const std::string compare_to = a.get("compare-to", "");
  const bool json = a.flag("json");
  a.finish();
  if (config != "svd-xt" && config != "tiny") throw Error("bench pipeline: --config must be svd-xt or tiny");
  if (dtype != "q8") parse_weight_dtype(dtype, "dtype");  // f32 | f16 | bf16, else the error names the option
  if (steps < 1 || steps > 40) throw Error("bench pipeline: --steps must be 25 (Euler) or 1..40 (AnimateLCM)");
  if (frames < 1 || frames > 1024 || size < 64 || size % 64 || decode_chunk < 0)
    throw Error("bench pipeline: need --frames 1..1024, --size a multiple of 64, --decode-chunk >= 0");

  const fs::path model = model_arg.empty() ? ensure_model(config, dtype) : fs::path(model_arg);
  const SourceClip source{int(frames)};

  StageTimes times;
  times.track_memory(true);
  std::vector<double> step_seconds;
  const auto t0 = std::chrono::steady_clock::now();
  Tensor rgb;
  {
    ScopedStage st(&times, "frame_decode_resize");
    rgb = frames_to_tensor(load_clip(source.file.string(), frames, int(size)).rgb);
  }
  std::unique_ptr<EgoPressureDiffPipeline> pipe;
  {
    ScopedStage st(&times, "load");
    pipe = std::make_unique<EgoPressureDiffPipeline>(model.string(), size, "", low_mem);
  }
  PipelineSettings s = pipe->settings_from_defaults();
  s.frames = frames;
  s.steps = int(steps);
  // 25 steps is the teacher (Euler, as trained); any other count is an AnimateLCM student distilled for it.
  s.sampler = steps == 25 ? "euler" : "lcm";
  s.seed = 0;
  s.decode_chunk = decode_chunk;
  // A full prompt, so the text encoder and the PIFR layers run as in a real prediction with metadata.
  const PromptFields fields{{"obj_name", "a mug"}, {"weight", "355g"},      {"material", "ceramic"},
                            {"gender", "female"},  {"age", "30"},           {"subj_weight", "60kg"},
                            {"bodyfat", "25%"}};
  const std::optional<std::string> prompt =
      pipe->has_text_encoder() ? pipe->prompt_for(fields) : std::optional<std::string>();
  const Tensor text = pipe->encode_text(prompt, nullptr, &times);
  const EgoPressureDiffPipeline::Shared sh = pipe->encode(rgb, nullptr, s, &times);
  const std::string sampler = sh.sampler->name();
  const EgoPressureDiffPipeline::Result r =
      pipe->run(sh, text, s, [&](int, int, double sec) { step_seconds.push_back(sec); }, &times);
  const double total = seconds_since(t0);
  if (!std::isfinite(r.latents[0])) throw Error("bench pipeline: non-finite latents");
  pipe.reset();
  // Fingerprints of the result, so runs that should agree (thread counts, normal vs --low-mem) can be compared.
  double latents_sum_sq = 0, decoded_sum = 0, taxels_sum = 0;
  for (int64_t i = 0; i < r.latents.numel(); ++i) latents_sum_sq += double(r.latents[i]) * r.latents[i];
  for (int64_t i = 0; i < r.decoded.numel(); ++i) decoded_sum += r.decoded[i];
  for (const auto& f : r.frames)
    for (double p : f.p) taxels_sum += p;

  // The result itself (--save-result), and its error against a saved one (--compare-to: another precision, kernel
  // path or thread count on the same model, seed and sizes).
  const int64_t taxel_count = r.frames.empty() ? 0 : int64_t(r.frames[0].p.size());
  Tensor taxels({int64_t(r.frames.size()), taxel_count});  // [F, M] normalised taxels
  for (size_t f = 0; f < r.frames.size(); ++f)
    for (int64_t m = 0; m < taxel_count; ++m) taxels[int64_t(f) * taxel_count + m] = float(r.frames[f].p[size_t(m)]);
  const std::pair<const char*, const Tensor*> results[] = {{"latents", &r.latents}, {"decoded", &r.decoded},
                                                           {"taxels", &taxels}};
  if (!save_result.empty()) {
    std::vector<TensorToWrite> out;
    for (const auto& [name, t] : results) out.push_back(to_write(name, *t));
    write_safetensors(save_result, out);
  }
  nlohmann::ordered_json errors = nlohmann::ordered_json::object();
  if (!compare_to.empty()) {
    const SafeTensorsFile ref(compare_to);
    for (const auto& [name, t] : results) {
      const StoredTensor* st = ref.find(name);
      if (!st) throw Error(compare_to + ": no tensor '" + name + "' (not written by bench pipeline --save-result)");
      const Tensor want = st->to_f32();
      if (want.numel() != t->numel())
        throw Error(compare_to + ": tensor '" + name + "' has " + std::to_string(want.numel()) + " values, this run " +
                    std::to_string(t->numel()) + " (other frames, size or model?)");
      double diff2 = 0, ref2 = 0, max_abs = 0;
      for (int64_t i = 0; i < t->numel(); ++i) {
        const double d = double((*t)[i]) - want[i];
        diff2 += d * d;
        ref2 += double(want[i]) * want[i];
        max_abs = std::max(max_abs, std::fabs(d));
      }
      errors[name] = {{"rel_l2", ref2 > 0 ? std::sqrt(diff2 / ref2) : std::sqrt(diff2)}, {"max_abs", max_abs}};
    }
  }

  // Work of the sampler loop: U-Net FLOPs per evaluation (counted from the config) x evaluations.
  const UNetConfig ucfg = UNetConfig::load((model / "unet").string());
  auto recorder = std::make_shared<WeightMap>(WeightMap::recorder("unet"));
  const UNetSpatioTemporal shape_only(ucfg, recorder);
  const int64_t videos = guidance_enabled(s.max_guidance) ? 2 : 1, lat = size / 8;
  const auto fl = shape_only.flops(videos, frames, lat, lat, 1, text.empty() ? 0 : text.dim(1));

  nlohmann::ordered_json stages = nlohmann::ordered_json::object(), stage_rss = nlohmann::ordered_json::object();
  for (const auto& [k, v] : times.entries()) {
    stages[k] = v;
    if (k == "denoise") stages["denoise_steps"] = step_seconds;
  }
  for (const auto& [k, v] : times.stage_peaks()) stage_rss[k] = v;
  BenchReport rep;
  rep.target = "pipeline";
  rep.seconds = total;
  rep.gflop = fl.executed * double(step_seconds.size()) / 1e9;
  rep.threads = num_threads();
  rep.extra["config"] = config;
  rep.extra["dtype"] = dtype;
  rep.extra["steps"] = int64_t(step_seconds.size());
  rep.extra["sampler"] = sampler;
  rep.extra["frames"] = frames;
  rep.extra["size"] = size;
  rep.extra["low_mem"] = low_mem;
  rep.extra["decode_chunk"] = decode_chunk > 0 ? decode_chunk : frames;
  rep.extra["model_dir"] = model.string();
  rep.extra["weights_bytes"] = weight_file_bytes(model);
  rep.extra["total_seconds"] = total;
  rep.extra["fps"] = double(frames) / total;
  rep.extra["stages"] = stages;
  rep.extra["peak_rss_bytes"] = times.peak_rss();  // VmHWM restarts per stage: the run's peak is the maximum
  rep.extra["stage_peak_rss_bytes"] = stage_rss;
  rep.extra["result"] = {{"latents_sum_sq", latents_sum_sq}, {"decoded_sum", decoded_sum}, {"taxels_sum", taxels_sum}};
  if (!compare_to.empty()) rep.extra["error_vs"] = {{"file", compare_to}, {"tensors", errors}};
  print_bench_report(rep, json);
  return 0;
}

}  // namespace egopd
