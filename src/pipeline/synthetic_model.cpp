#include "pipeline/synthetic_model.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>

#include "core/atomic_file.h"
#include "clip_image/clip_vision.h"
#include "clip_text/clip_text.h"
#include "core/error.h"
#include "core/hash.h"
#include "core/install_dirs.h"
#include "core/json_text.h"
#include "core/safetensors.h"
#include "core/synthetic_weights.h"
#include "core/weights.h"
#include "mask_encoder/mask_encoder.h"
#include "unet3d/unet.h"
#include "vae/temporal_vae.h"

namespace egopd {
namespace fs = std::filesystem;
using nlohmann::json;

const std::vector<ModelComponent>& model_components() {
  static const std::vector<ModelComponent> k = {
      {"unet", "diffusion_pytorch_model", "diffusers", "UNetSpatioTemporalConditionModel"},
      {"vae", "diffusion_pytorch_model", "diffusers", "AutoencoderKLTemporalDecoder"},
      {"image_encoder", "model", "transformers", "CLIPVisionModelWithProjection"},
      {"text_encoder", "model", "transformers", "CLIPTextModel"},
      {"mask_encoder", "diffusion_pytorch_model", "egopressurediff", "MaskEncoder"},
  };
  return k;
}

const ModelComponent& model_component(const std::string& folder) {
  for (const auto& c : model_components())
    if (folder == c.folder) return c;
  throw Error("unknown model component '" + folder + "'");
}

namespace {

json unet_config(bool tiny) {
  json j = {{"_class_name", "UNetSpatioTemporalConditionModel"},
            {"in_channels", 8},
            {"out_channels", 4},
            {"layers_per_block", tiny ? 1 : 2},
            {"transformer_layers_per_block", 1},
            {"num_frames", tiny ? 16 : 25}};
  if (tiny) {
    // Three levels so every block kind and index rule of the original layout occurs (plain last level, plain first
    // up level, width change with conv_shortcut); head dim 16. About 20 GFLOP per step at 16 x 32 x 32 latents.
    j["sample_size"] = 32;
    j["down_block_types"] = {"CrossAttnDownBlockSpatioTemporal", "CrossAttnDownBlockSpatioTemporal",
                             "DownBlockSpatioTemporal"};
    j["up_block_types"] = {"UpBlockSpatioTemporal", "CrossAttnUpBlockSpatioTemporal", "CrossAttnUpBlockSpatioTemporal"};
    j["block_out_channels"] = {32, 32, 64};
    j["num_attention_heads"] = {2, 2, 4};
    j["cross_attention_dim"] = 32;  // = image encoder projection_dim
    j["addition_time_embed_dim"] = 32;
    j["projection_class_embeddings_input_dim"] = 96;
    j["pifr"] = {{"text_dim", 32}, {"enabled", true}};  // = text encoder hidden_size
  } else {
    j["sample_size"] = 96;
    j["down_block_types"] = {"CrossAttnDownBlockSpatioTemporal", "CrossAttnDownBlockSpatioTemporal",
                             "CrossAttnDownBlockSpatioTemporal", "DownBlockSpatioTemporal"};
    j["up_block_types"] = {"UpBlockSpatioTemporal", "CrossAttnUpBlockSpatioTemporal", "CrossAttnUpBlockSpatioTemporal",
                           "CrossAttnUpBlockSpatioTemporal"};
    j["block_out_channels"] = {320, 640, 1280, 1280};
    j["num_attention_heads"] = {5, 10, 20, 20};
    j["cross_attention_dim"] = 1024;
    j["addition_time_embed_dim"] = 256;
    j["projection_class_embeddings_input_dim"] = 768;
    j["pifr"] = {{"text_dim", 1024}, {"enabled", true}};
  }
  return j;
}

json vae_config(bool tiny) {
  VaeConfig v = VaeConfig::svd_xt();
  // Tiny keeps SVD's structure (3 downsamplings, 2 res-blocks per level, so the original single-file layout maps
  // onto it) at the smallest GroupNorm-compatible width.
  if (tiny) v.block_out_channels = {32, 32, 32, 32};
  json j = v.to_json();
  j["sample_size"] = tiny ? 256 : 768;
  return j;
}

json vision_config(bool tiny) {
  return {{"architectures", {"CLIPVisionModelWithProjection"}},
          {"model_type", "clip_vision_model"},
          {"hidden_size", tiny ? 32 : 1280},
          {"intermediate_size", tiny ? 64 : 5120},
          {"num_attention_heads", tiny ? 2 : 16},
          {"num_hidden_layers", tiny ? 2 : 32},
          {"patch_size", 14},
          {"image_size", 224},
          {"num_channels", 3},
          {"projection_dim", tiny ? 32 : 1024},
          {"hidden_act", "gelu"},
          {"layer_norm_eps", 1e-05}};
}

json text_config(bool tiny) {
  return {{"architectures", {"CLIPTextModel"}},
          {"model_type", "clip_text_model"},
          {"hidden_size", tiny ? 32 : 1024},
          {"intermediate_size", tiny ? 64 : 4096},
          {"num_attention_heads", tiny ? 2 : 16},
          {"num_hidden_layers", tiny ? 2 : 24},
          {"max_position_embeddings", 77},
          {"vocab_size", 49408},
          {"projection_dim", tiny ? 32 : 1024},
          {"hidden_act", "gelu"},
          {"layer_norm_eps", 1e-05},
          {"bos_token_id", 49406},
          {"eos_token_id", 49407},
          {"pad_token_id", 49407}};
}

json mask_config(bool tiny) {
  return {{"_class_name", "MaskEncoder"},
          {"conditioning_channels", 1},
          {"block_out_channels", tiny ? json{8, 16, 16, 32} : json{16, 32, 96, 256}},
          {"conditioning_embedding_channels", 8}};
}

std::vector<std::pair<std::string, Shape>> dedupe(const std::vector<std::pair<std::string, Shape>>& in) {
  std::vector<std::pair<std::string, Shape>> out;
  std::set<std::string> seen;
  for (const auto& p : in)
    if (seen.insert(p.first).second) out.push_back(p);
  return out;
}

}  // namespace

json preset_config(const std::string& preset, const std::string& folder) {
  if (preset != "tiny" && preset != "svd-xt") throw Error("unknown model preset '" + preset + "' (tiny or svd-xt)");
  const bool tiny = preset == "tiny";
  if (folder == "unet") return unet_config(tiny);
  if (folder == "vae") return vae_config(tiny);
  if (folder == "image_encoder") return vision_config(tiny);
  if (folder == "text_encoder") return text_config(tiny);
  if (folder == "mask_encoder") return mask_config(tiny);
  throw Error("unknown model component '" + folder + "'");
}

json scheduler_config_json(int lcm_steps) {
  if (lcm_steps == 0)
    return {{"_class_name", "EulerDiscreteScheduler"},
            {"beta_start", 0.00085},
            {"beta_end", 0.012},
            {"beta_schedule", "scaled_linear"},
            {"clip_sample", false},
            {"interpolation_type", "linear"},
            {"num_train_timesteps", 1000},
            {"prediction_type", "v_prediction"},
            {"set_alpha_to_one", false},
            {"sigma_max", 700.0},
            {"sigma_min", 0.002},
            {"skip_prk_steps", true},
            {"steps_offset", 1},
            {"timestep_spacing", "leading"},
            {"timestep_type", "continuous"},
            {"trained_betas", nullptr},
            {"use_karras_sigmas", true}};
  if (lcm_steps < 1 || lcm_steps > 40) throw Error("--lcm-steps must be 0 (Euler) or 1..40, got " + std::to_string(lcm_steps));
  return {{"_class_name", "AnimateLCMSVDStochasticIterativeScheduler"},
          {"num_train_timesteps", 40},
          {"sigma_min", 0.002},
          {"sigma_max", 700.0},
          {"sigma_data", 1.0},
          {"s_noise", 1.0},
          {"rho", 7},
          {"clip_denoised", false}};
}

json preprocessor_config_json() {
  return {{"crop_size", {{"height", 224}, {"width", 224}}},
          {"do_center_crop", true},
          {"do_convert_rgb", true},
          {"do_normalize", true},
          {"do_rescale", true},
          {"do_resize", true},
          {"image_mean", {0.48145466, 0.4578275, 0.40821073}},
          {"image_processor_type", "CLIPImageProcessor"},
          {"image_std", {0.26862954, 0.26130258, 0.27577711}},
          {"resample", 3},
          {"rescale_factor", 0.00392156862745098},
          {"size", {{"shortest_edge", 224}}}};
}

json model_index_json(int lcm_steps, bool has_text, bool has_mask_encoder) {
  json j = {{"_class_name", "EgoPressureDiffPipeline"}};
  for (const auto& c : model_components()) {
    const std::string f = c.folder;
    if ((f == "text_encoder" && !has_text) || (f == "mask_encoder" && !has_mask_encoder)) continue;
    j[f] = {c.library, c.class_name};
  }
  if (has_text) j["tokenizer"] = {"transformers", "CLIPTokenizer"};
  j["scheduler"] = {"diffusers", scheduler_config_json(lcm_steps)["_class_name"]};
  j["feature_extractor"] = {"transformers", "CLIPImageProcessor"};
  j["egopd_defaults"] = {
      {"num_inference_steps", lcm_steps == 0 ? 25 : lcm_steps},
      {"num_frames", 16},
      {"resolution", 256},
      {"fps", 5},
      {"motion_bucket_id", 127},
      {"noise_aug_strength", 0.02},
      {"min_guidance_scale", 1.0},
      {"max_guidance_scale", 1.0},
      {"prompt_template",
       "This video shows the action of picking up {obj_name}. The weight of {obj_name} is {weight}, and its surface "
       "material is {material}. The person performing the action is {gender}, {age} years of age, weighing "
       "{subj_weight} and having {bodyfat} body fat."}};
  return j;
}

std::vector<std::pair<std::string, Shape>> component_parameters(const std::string& folder, const Config& config) {
  auto rec = std::make_shared<WeightMap>(WeightMap::recorder(folder));
  if (folder == "unet") {
    UNetSpatioTemporal m(UNetConfig::from(config), rec);
  } else if (folder == "vae") {
    const VaeConfig cfg = VaeConfig::from(config);
    VaeEncoder enc(rec->root(), cfg);
    TemporalDecoder dec(rec->root().sub("decoder"), cfg);
  } else if (folder == "image_encoder") {
    ClipVisionModelWithProjection m(ClipVisionConfig::from_config(config), rec);
  } else if (folder == "text_encoder") {
    ClipTextModel m(ClipTextConfig::from_config(config), rec);
  } else if (folder == "mask_encoder") {
    MaskEncoder m(MaskEncoderConfig::from(config), rec);
  } else {
    throw Error("unknown model component '" + folder + "'");
  }
  return dedupe(rec->recorded());
}

std::string shipped_tokenizer_dir() {
  std::vector<fs::path> candidates;
  std::error_code ec;
  if (const char* env = std::getenv("EGOPD_TOKENIZER_DIR"); env && *env) {  // named explicitly: no fallback
    if (!fs::is_regular_file(fs::path(env) / "vocab.json", ec) || !fs::is_regular_file(fs::path(env) / "merges.txt", ec))
      throw Error(std::string("EGOPD_TOKENIZER_DIR=") + env + ": no vocab.json and merges.txt there");
    return env;
  }
  candidates = installed_data_candidates("tokenizer");
#ifdef EGOPD_DATA_DIR
  candidates.push_back(fs::path(EGOPD_DATA_DIR) / "tokenizer");
#endif
  std::string looked;
  for (const auto& c : candidates) {
    if (fs::is_regular_file(c / "vocab.json", ec) && fs::is_regular_file(c / "merges.txt", ec)) return c.string();
    looked += (looked.empty() ? "" : ", ") + c.string();
  }
  throw Error("CLIP tokenizer files (vocab.json, merges.txt) not found (looked in: " + looked +
              "); set EGOPD_TOKENIZER_DIR");
}

void write_json_atomic(const std::string& path, const json& j) { write_file_atomic(path, dump_json(j, 2) + "\n"); }

namespace {

void copy_file_atomic_simple(const fs::path& from, const fs::path& to) {
  std::ifstream in(from, std::ios::binary);
  if (!in) throw Error(from.string() + ": cannot open");
  std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  write_file_atomic(to.string(), data);
}

// Distinct seeds per component (index i of model_components()), so components with equal key names do not get
// equal values.
uint64_t component_seed(uint64_t seed, size_t i) { return (seed + i) * 0x9e3779b97f4a7c15ull + 1; }

// Remove weight files of another layout (sharded index, variants) that would shadow or confuse the new file.
void remove_stale_weights(const fs::path& dir, const std::string& stem) {
  std::error_code ec;
  for (const char* suffix : {".safetensors.index.json", ".fp16.safetensors", ".bf16.safetensors"})
    fs::remove(dir / (stem + suffix), ec);
}

}  // namespace

std::string synthetic_model_id(const std::string& preset, uint64_t seed, DType dtype, int lcm_steps) {
  uint64_t h = fnv1a(dump_json(scheduler_config_json(lcm_steps)));
  h = fnv1a(dump_json(preprocessor_config_json()), h);
  h = fnv1a(dump_json(model_index_json(lcm_steps, true, true)), h);
  for (size_t i = 0; i < model_components().size(); ++i) {
    const ModelComponent& c = model_components()[i];
    const json cfg = preset_config(preset, c.folder);
    h = fnv1a(dump_json(cfg), h);
    const auto params = component_parameters(c.folder, Config(cfg, std::string(c.folder) + "/config.json"));
    h = fnv1a(synthetic_weights_id(params, dtype, component_seed(seed, i)), h);
  }
  return hex16(h);
}

void write_synthetic_model(const std::string& dir, const std::string& preset, uint64_t seed, DType dtype,
                           int lcm_steps) {
  if (!is_float_weight(dtype)) throw Error(std::string("synthetic weights must be f32, f16 or bf16, not ") + dtype_name(dtype));
  const json sched = scheduler_config_json(lcm_steps);  // validates lcm_steps before anything is written
  const fs::path root(dir);
  fs::create_directories(root);
  for (size_t i = 0; i < model_components().size(); ++i) {
    const ModelComponent& c = model_components()[i];
    const fs::path d = root / c.folder;
    fs::create_directories(d);
    const json cfg = preset_config(preset, c.folder);
    const auto params = component_parameters(c.folder, Config(cfg, (d / "config.json").string()));
    remove_stale_weights(d, c.stem);
    write_synthetic_safetensors((d / (std::string(c.stem) + ".safetensors")).string(), params, dtype,
                                component_seed(seed, i));
    write_json_atomic((d / "config.json").string(), cfg);
  }
  const fs::path tok = root / "tokenizer";
  fs::create_directories(tok);
  const fs::path shipped(shipped_tokenizer_dir());
  for (const char* f : {"vocab.json", "merges.txt", "tokenizer_config.json"})
    if (fs::exists(shipped / f)) copy_file_atomic_simple(shipped / f, tok / f);
  fs::create_directories(root / "scheduler");
  write_json_atomic((root / "scheduler" / "scheduler_config.json").string(), sched);
  fs::create_directories(root / "feature_extractor");
  write_json_atomic((root / "feature_extractor" / "preprocessor_config.json").string(), preprocessor_config_json());
  // Written last: a directory with model_index.json is complete.
  write_json_atomic((root / "model_index.json").string(), model_index_json(lcm_steps, true, true));
}

}  // namespace egopd
