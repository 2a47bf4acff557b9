#include "convert/graft.h"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "clip_text/clip_text.h"
#include "convert/model_check.h"
#include "core/error.h"
#include "core/json_text.h"
#include "core/synthetic_weights.h"
#include "pipeline/synthetic_model.h"

namespace egopd {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

json read_json_file(const fs::path& p) {
  std::ifstream in(p);
  if (!in) throw Error(p.string() + ": cannot open");
  try {
    return parse_json(in);
  } catch (const std::exception&) {
    throw Error(p.string() + ": not valid JSON");
  }
}

// Copies every regular file of a folder (configs, weights, tokenizer files) atomically.
void copy_folder(const fs::path& from, const fs::path& to) {
  if (!fs::is_directory(from)) throw Error(from.string() + ": folder does not exist");
  fs::create_directories(to);
  for (const auto& e : fs::directory_iterator(from))
    if (e.is_regular_file() && e.path().filename().string().find(".tmp.") == std::string::npos)
      copy_file_atomic(e.path().string(), (to / e.path().filename()).string());
}

// Values in the dtype of the stored tensor (float types only).
void store_values(const float* v, int64_t n, DType dt, uint8_t* dst) {
  for (int64_t i = 0; i < n; ++i) {
    if (dt == DType::F32) {
      std::memcpy(dst + 4 * i, &v[i], 4);
    } else {
      const uint16_t h = dt == DType::F16 ? float_to_half(v[i]) : float_to_bf16(v[i]);
      std::memcpy(dst + 2 * i, &h, 2);
    }
  }
}

// The mask encoder needs one stride-2 step per VAE downsampling (egopressurediff.md §2).
json mask_config_for(const json& vae_cfg) {
  const size_t levels = vae_cfg.contains("block_out_channels") ? vae_cfg["block_out_channels"].size() : 4;
  const int64_t widths[] = {16, 32, 96, 256};
  json bo = json::array();
  for (size_t i = 0; i < levels; ++i) bo.push_back(widths[std::min<size_t>(i, 3)]);
  json j = preset_config("svd-xt", "mask_encoder");
  j["block_out_channels"] = bo;
  return j;
}

}  // namespace

void graft_pifr_values(const std::string& key, const Shape& shape, const WeightMap& stock, uint64_t seed, float* out) {
  const size_t at = key.find("pifr.");
  if (at == std::string::npos) throw Error("graft: " + key + " is not a PIFR tensor");
  const std::string block = key.substr(0, at), suffix = key.substr(at + 5);
  auto copy_from = [&](const std::string& src_key) {
    const StoredTensor* s = stock.find(block + src_key);
    if (!s) throw Error("unet: missing tensor " + block + src_key + " (needed to initialise " + key + ")");
    if (s->shape != shape.vec())
      throw Error("unet: tensor " + block + src_key + " has shape " + s->shape_str() + ", expected " + shape.str());
    const Tensor t = s->to_f32();
    std::memcpy(out, t.data(), size_t(shape.numel()) * 4);
  };
  if (suffix == "attn_text.to_q.weight") return copy_from("attn2.to_q.weight");
  if (suffix == "attn_text.to_out.0.weight") return copy_from("attn2.to_out.0.weight");
  if (suffix == "attn_text.to_out.0.bias") return copy_from("attn2.to_out.0.bias");
  if (suffix == "mod.1.weight" || suffix == "mod.1.bias") {
    std::fill(out, out + shape.numel(), 0.0f);
    return;
  }
  if (suffix == "attn_text.to_k.weight" || suffix == "attn_text.to_v.weight") {
    // synthetic_values draws U(-1/sqrt(fan_in), 1/sqrt(fan_in)); rescale to Xavier's sqrt(6/(fan_in+fan_out)).
    const double fan_out = double(shape[0]), fan_in = double(shape[1]);
    synthetic_values(key, shape, seed, out);
    const float k = float(std::sqrt(6.0 / (fan_in + fan_out)) * std::sqrt(fan_in));
    for (int64_t i = 0; i < shape.numel(); ++i) out[i] *= k;
    return;
  }
  throw Error("graft: no initialisation rule for " + key);
}

void graft_model(const GraftOptions& o) {
  const fs::path svd(o.svd_dir), out(o.out_dir);
  const fs::path unet_dir = svd / "unet";
  json unet_cfg = read_json_file(unet_dir / "config.json");
  if (unet_cfg.contains("pifr") && unet_cfg["pifr"].value("enabled", true))
    throw Error((unet_dir / "config.json").string() + ": the U-Net already has PIFR layers");
  const WeightMap stock = open_weights_dir(unet_dir.string(), "diffusion_pytorch_model", "unet");
  std::map<std::string, StoredInfo> have;
  for (const auto& k : stock.keys()) {
    const StoredTensor* t = stock.find(k);
    if (!is_float_weight(t->dtype))
      throw Error("unet: tensor " + k + " has dtype " + dtype_name(t->dtype) + "; convert the U-Net to a float dtype first");
    have[k] = {t->dtype, t->shape};
  }
  unet_cfg.erase("pifr");
  const KeyCheck stock_check =
      check_keys("unet", component_parameters("unet", Config(unet_cfg, "unet/config.json")), have, false);
  if (!stock_check.ok()) throw Error(stock_check.summary((unet_dir / "diffusion_pytorch_model").string()));

  // Text encoder: its hidden size is PIFR's text_dim; check its weights before copying it.
  const fs::path te(o.text_encoder_dir);
  const Config te_cfg = Config::load((te / "config.json").string());
  const int64_t text_dim = ClipTextConfig::from_config(te_cfg).encoder.hidden;
  {
    const WeightMap tw = open_weights_dir(te.string(), "model", "text_encoder");
    std::map<std::string, StoredInfo> th;
    for (const auto& k : tw.keys()) th[k] = {tw.find(k)->dtype, tw.find(k)->shape};
    const KeyCheck c = check_keys("text_encoder", component_parameters("text_encoder", te_cfg), th, false);
    if (!c.ok()) throw Error(c.summary(te.string()));
  }
  const fs::path tok(o.tokenizer_dir);
  for (const char* f : {"vocab.json", "merges.txt"})
    if (!fs::is_regular_file(tok / f)) throw Error("tokenizer: " + (tok / f).string() + " does not exist");

  // U-Net: every stock tensor unchanged, plus the PIFR tensors.
  unet_cfg["pifr"] = {{"text_dim", text_dim}, {"enabled", true}};
  const auto params = component_parameters("unet", Config(unet_cfg, "unet/config.json"));
  const DType pifr_dtype = stock.find(params.front().first)->dtype;
  std::vector<OutTensor> tensors;
  for (const auto& [key, shape] : params) {
    if (const StoredTensor* s = stock.find(key)) {
      tensors.push_back({key, s->dtype, s->shape, [s](uint8_t* dst) { copy_stored(*s, dst); }});
      continue;
    }
    const std::string name = key;  // lambdas capture variables, not structured bindings (C++20, not in clang 14)
    const Shape sh = shape;
    const WeightMap* st = &stock;
    const uint64_t seed = o.seed;
    tensors.push_back({key, pifr_dtype, shape.vec(), [name, sh, st, seed, pifr_dtype](uint8_t* dst) {
                         std::vector<float> v(size_t(sh.numel()));
                         graft_pifr_values(name, sh, *st, seed, v.data());
                         store_values(v.data(), sh.numel(), pifr_dtype, dst);
                       }});
  }
  write_weights((out / "unet").string(), "diffusion_pytorch_model", tensors, o.write);
  write_json_atomic((out / "unet" / "config.json").string(), unet_cfg);

  // Mask encoder: random hidden convs, zero conv_out, so the mask features start at exactly 0.
  const json vae_cfg = read_json_file(svd / "vae" / "config.json");
  const json mask_cfg = mask_config_for(vae_cfg);
  std::vector<OutTensor> mask;
  for (const auto& [key, shape] : component_parameters("mask_encoder", Config(mask_cfg, "mask_encoder/config.json"))) {
    const std::string name = key;
    const Shape sh = shape;
    const bool zero = key.rfind("conv_out.", 0) == 0;
    const uint64_t seed = o.seed;
    mask.push_back({key, pifr_dtype, shape.vec(), [name, sh, zero, seed, pifr_dtype](uint8_t* dst) {
                      std::vector<float> v(size_t(sh.numel()), 0.0f);
                      if (!zero) synthetic_values(name, sh, seed, v.data());
                      store_values(v.data(), sh.numel(), pifr_dtype, dst);
                    }});
  }
  write_weights((out / "mask_encoder").string(), "diffusion_pytorch_model", mask, o.write);
  write_json_atomic((out / "mask_encoder" / "config.json").string(), mask_cfg);

  copy_folder(te, out / "text_encoder");
  fs::create_directories(out / "tokenizer");
  for (const char* f : {"vocab.json", "merges.txt", "tokenizer_config.json", "special_tokens_map.json"})
    if (fs::is_regular_file(tok / f)) copy_file_atomic((tok / f).string(), (out / "tokenizer" / f).string());
  for (const char* f : {"vae", "image_encoder", "scheduler", "feature_extractor"}) copy_folder(svd / f, out / f);

  const json sched = read_json_file(svd / "scheduler" / "scheduler_config.json");
  const bool euler = sched.value("_class_name", "") == "EulerDiscreteScheduler";
  json index = model_index_json(euler ? 0 : 8, true, true);
  index["scheduler"] = {"diffusers", sched.value("_class_name", "EulerDiscreteScheduler")};
  write_json_atomic((out / "model_index.json").string(), index);
}

}  // namespace egopd
