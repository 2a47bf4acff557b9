#include "api/api_options.h"

#include <cmath>
#include <cstring>
#include <vector>

#include "core/block_pool.h"
#include "core/json_text.h"
#include "pipeline/prompt.h"

namespace egopd::api {
namespace {

template <class T>
T read_struct(const T* given, void (*init)(T*), const char* name, const char* init_name) {
  T out;
  init(&out);
  if (!given) return out;
  const size_t n = given->struct_size;
  if (n < sizeof(size_t) || n > sizeof(T))
    throw ArgumentError(std::string(name) + ": struct_size is " + std::to_string(n) + ", expected at most " +
                        std::to_string(sizeof(T)) + " (initialise the struct with " + init_name + ")");
  std::memcpy(static_cast<void*>(&out), given, n);
  out.struct_size = sizeof(T);
  return out;
}

std::string str(const char* s) { return s ? s : ""; }

// 0 (the default) or lo..hi, in the wording of the egopd command's options.
int64_t bounded(int64_t v, int64_t lo, int64_t hi, const char* flag) {
  if (v != 0 && (v < lo || v > hi))
    throw ArgumentError(std::string(flag) + " must be between " + std::to_string(lo) + " and " + std::to_string(hi) +
                        ", got " + std::to_string(v));
  return v;
}

// Errors of the shared option check are the caller's mistakes.
void check_options(const PredictOptions& po) {
  try {
    check_predict_options(po);
  } catch (const ArgumentError&) {
    throw;
  } catch (const Error& e) {
    throw ArgumentError(e.what());
  }
}

// count x height x width x channels bytes, each dimension at least 1, equal to `bytes`.
void check_buffer(const void* data, size_t bytes, int64_t count, int64_t height, int64_t width, int64_t channels,
                  const char* name) {
  const std::string n = name;
  if (!data) {
    if (count != 0 || bytes != 0)
      throw ArgumentError(n + ": null buffer but " + n + "_count " + std::to_string(count) + " and " + n +
                          "_bytes " + std::to_string(bytes));
    return;
  }
  if (count < 1 || height < 1 || width < 1 || count > (int64_t(1) << 20) || height > (int64_t(1) << 16) ||
      width > (int64_t(1) << 16))
    throw ArgumentError(n + ": count, height and width must be positive (got " + std::to_string(count) + " x " +
                        std::to_string(height) + " x " + std::to_string(width) + ")");
  unsigned __int128 want = (unsigned __int128)count * (unsigned __int128)height * (unsigned __int128)width *
                           (unsigned __int128)channels;
  if (want != (unsigned __int128)bytes)
    throw ArgumentError(n + ": buffer of " + std::to_string(bytes) + " bytes, but " + std::to_string(count) + " x " +
                        std::to_string(height) + " x " + std::to_string(width) +
                        (channels > 1 ? " x " + std::to_string(channels) : std::string()) + " = " +
                        std::to_string((unsigned long long)want) + " bytes");
}

// Views of a caller's buffer (not copied; only read).
std::vector<cv::Mat> image_views(const uint8_t* data, int64_t count, int64_t height, int64_t width, int type) {
  std::vector<cv::Mat> out;
  const size_t plane = size_t(height * width * CV_ELEM_SIZE(type));
  for (int64_t i = 0; i < count; ++i)
    out.emplace_back(int(height), int(width), type, const_cast<uint8_t*>(data) + size_t(i) * plane);
  return out;
}

}  // namespace

egopd_load_options read_load_options(const egopd_load_options* o) {
  return read_struct(o, egopd_load_options_init, "load options", "egopd_load_options_init");
}

egopd_predict_options read_predict_options(const egopd_predict_options* o) {
  return read_struct(o, egopd_predict_options_init, "predict options", "egopd_predict_options_init");
}

Precision load_precision(const egopd_load_options& o) {
  const std::string name = str(o.precision);
  Precision p = Precision::Fp32;
  if (!name.empty() && !parse_precision(name.c_str(), &p))
    throw ArgumentError("precision '" + name + "': expected fp32, bf16 or int8");
  return p;
}

ConvAlgo load_conv(const egopd_load_options& o) {
  const std::string name = str(o.conv);
  if (name.empty()) return conv_algo_from_env();
  ConvAlgo a = ConvAlgo::Auto;
  if (!conv_algo_from_name(name, &a)) throw ArgumentError("conv '" + name + "': expected direct, winograd or auto");
  return a;
}

size_t load_block_cache_bytes(const egopd_load_options& o) {
  if (o.block_cache_mb == -1) return block_cache_limit_from_env();
  if (o.block_cache_mb < 0 || o.block_cache_mb > kMaxBlockCacheMb)
    throw ArgumentError("--block-cache-mb must be between 0 and " + std::to_string(kMaxBlockCacheMb) +
                        " (or -1: the default), got " + std::to_string(o.block_cache_mb));
  return size_t(o.block_cache_mb) << 20;
}

PredictOptions load_predict_options(const char* model_dir, const egopd_load_options& o) {
  if (o.threads < 0 || o.threads > 1024)
    throw ArgumentError("--threads must be between 1 and 1024 (or 0: the default), got " + std::to_string(o.threads));
  load_precision(o);
  load_conv(o);
  load_block_cache_bytes(o);
  PredictOptions po;
  po.model_dir = str(model_dir);
  po.size = bounded(o.size, 64, 4096, "--size");
  if (po.size == 0) po.size = 256;
  po.low_mem = o.low_mem != 0;
  po.template_path = str(o.template_path);
  check_options(po);
  return po;
}

PredictOptions call_predict_options(const PredictOptions& load, const egopd_predict_options& o) {
  PredictOptions po = load;
  po.video = str(o.video);
  po.masks_dir = str(o.masks_dir);
  po.meta_path = str(o.meta_path);
  if (o.prompt) po.prompt = std::string(o.prompt);
  if (o.prompt && o.meta_json) throw ArgumentError("give either --prompt or --meta, not both");
  if (o.meta_path && o.meta_json) throw ArgumentError("give either meta_path or meta_json, not both");
  if (o.video && o.frames) throw ArgumentError("give either a video (--video) or frames, not both");
  if (o.masks_dir && o.masks) throw ArgumentError("give either a mask folder (--masks) or masks, not both");
  po.sampler = str(o.sampler);
  po.steps = int(bounded(o.steps, 1, 1000, "--steps"));
  po.seed = o.seed;
  po.frames = bounded(o.num_frames, 1, 1024, "--frames");
  if (o.size != 0) po.size = bounded(o.size, 64, 4096, "--size");
  if (o.has_guidance) po.guidance = std::make_pair(o.guidance_min, o.guidance_max);
  po.decode_chunk = bounded(o.decode_chunk, 1, 1024, "--decode-chunk");
  po.out_dir = str(o.out_dir);
  check_options(po);
  return po;
}

ClipSource call_clip_source(const egopd_predict_options& o, const PredictOptions& po, const RunHooks& log) {
  check_buffer(o.frames, o.frames_bytes, o.frames_count, o.frames_height, o.frames_width, 3, "frames");
  check_buffer(o.masks, o.masks_bytes, o.masks_count, o.masks_height, o.masks_width, 1, "masks");
  ClipSource src = clip_source(po);
  if (o.frames) src.frames = image_views(o.frames, o.frames_count, o.frames_height, o.frames_width, CV_8UC3);
  if (o.masks) src.masks = image_views(o.masks, o.masks_count, o.masks_height, o.masks_width, CV_8UC1);
  if (o.meta_json) {
    nlohmann::json j;
    try {
      j = parse_json(o.meta_json);
    } catch (const std::exception&) {
      throw ArgumentError("meta_json: metadata is not valid JSON");
    }
    std::vector<std::string> unknown;
    src.meta = prompt_fields_from_json(j, "meta_json", &unknown);
    for (const std::string& k : unknown)
      if (log.log)
        log.log("warning: meta_json: field '" + k + "' is not a prompt field and is ignored (fields: obj_name, "
                "weight, material, gender, age, subj_weight, bodyfat)");
  }
  return src;
}

VarySpec call_vary_spec(const char* field, const char* const* values, size_t num_values) {
  if (!field) throw ArgumentError("field: null (a prompt field: obj_name, weight, material, gender, age, subj_weight, "
                                  "bodyfat)");
  if (!values && num_values > 0) throw ArgumentError("values: null array of " + std::to_string(num_values) + " values");
  std::vector<std::string> v;
  for (size_t i = 0; i < num_values; ++i) {
    if (!values[i]) throw ArgumentError("values[" + std::to_string(i) + "]: null");
    v.emplace_back(values[i]);
  }
  try {
    return make_vary(field, std::move(v));
  } catch (const Error& e) {
    throw ArgumentError(e.what());
  }
}

}  // namespace egopd::api
