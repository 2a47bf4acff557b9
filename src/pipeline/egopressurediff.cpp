#include "pipeline/egopressurediff.h"

#include <chrono>
#include <cstring>
#include <filesystem>

#include "clip_image/svd_preprocess.h"
#include "core/block_pool.h"
#include "core/error.h"
#include "core/finite_check.h"
#include "core/rng.h"
#include "scheduler/animatelcm.h"
#include "scheduler/euler.h"
#include "scheduler/guidance.h"

namespace egopd {
namespace fs = std::filesystem;

ModelDefaults read_model_defaults(const Config& c) {
  ModelDefaults d;
  if (!c.has("egopd_defaults")) return d;
  Config e = c.sub("egopd_defaults");
  d.steps = int(e.get_int("num_inference_steps", 0, IntRange{0, 1000}));
  d.frames = e.get_int("num_frames", d.frames, IntRange{1, 1024});
  d.resolution = e.get_int("resolution", d.resolution, IntRange{64, 4096});
  d.fps = float(e.get_double("fps", d.fps, RealRange{0, 1000}));
  d.motion_bucket_id = float(e.get_double("motion_bucket_id", d.motion_bucket_id, RealRange{0, 10000}));
  d.noise_aug_strength = float(e.get_double("noise_aug_strength", d.noise_aug_strength, RealRange{0, 10}));
  d.min_guidance = float(e.get_double("min_guidance_scale", d.min_guidance, kGuidanceRange));
  d.max_guidance = float(e.get_double("max_guidance_scale", d.max_guidance, kGuidanceRange));
  d.prompt_template = e.get_string("prompt_template", "");
  return d;
}

static ModelDefaults load_defaults(const fs::path& dir) {
  const fs::path index = dir / "model_index.json";
  if (!fs::exists(index)) throw Error(dir.string() + ": not a model directory (no model_index.json)");
  return read_model_defaults(Config::load(index.string()));
}

static void require_dir(const fs::path& p, const std::string& what) {
  if (!fs::is_directory(p)) throw Error(p.parent_path().string() + ": model directory has no " + what + "/ folder");
}

EgoPressureDiffPipeline::EgoPressureDiffPipeline(const std::string& model_dir, int64_t size,
                                                 const std::string& template_path, bool low_mem)
    : dir_(model_dir), size_(size), low_mem_(low_mem) {
  const fs::path d(model_dir);
  if (!fs::is_directory(d)) throw Error(model_dir + ": model directory does not exist");
  if (size < 64 || size % 64) throw Error("--size must be a positive multiple of 64 (got " + std::to_string(size) + ")");
  defaults_ = load_defaults(d);
  for (const char* part : {"unet", "vae", "image_encoder", "scheduler"}) require_dir(d / part, part);
  template_ = HandTemplate::load(template_path.empty() ? default_template_path() : template_path);
  renderer_ = std::make_unique<PressureRenderer>(template_, int(size));
  unet_cfg_ = UNetConfig::load((d / "unet").string());
  // Process-wide: freed activations are not kept resident for reuse (each first touch then costs a page fault).
  if (low_mem) set_block_cache_limit(0);
  const fs::path pre = d / "feature_extractor" / "preprocessor_config.json";
  if (fs::exists(pre)) clip_norm_ = ClipImageNormalization::load(pre.string());
  has_text_ = fs::is_directory(d / "text_encoder") && fs::is_directory(d / "tokenizer");
  has_masks_ = fs::is_directory(d / "mask_encoder");
  if (low_mem_) return;  // each component is loaded (and checked) when its stage runs
  load_unet();
  load_vae();
  load_image_encoder();
  load_text();
  load_masks();
}

void EgoPressureDiffPipeline::load_unet() const {
  if (!unet_) unet_ = std::make_unique<UNetSpatioTemporal>((fs::path(dir_) / "unet").string());
  unet_->set_release_weights_after_use(low_mem_);
}

void EgoPressureDiffPipeline::load_vae() const {
  if (vae_) return;
  vae_ = std::make_unique<TemporalVAE>((fs::path(dir_) / "vae").string());
  if (!low_mem_) return;
  vae_->set_temporal_memory(kLowMemTemporal);
  vae_->set_release_weights_after_use(true);
}

void EgoPressureDiffPipeline::load_image_encoder() const {
  if (image_encoder_) return;
  image_encoder_ = std::make_unique<ClipVisionModelWithProjection>(
      ClipVisionModelWithProjection::load_dir((fs::path(dir_) / "image_encoder").string()));
  image_encoder_->set_release_weights_after_use(low_mem_);
  if (image_encoder_->config().projection_dim != unet_cfg_.cross_attention_dim[0])
    throw Error(dir_ + ": image_encoder projection_dim does not match the U-Net's cross_attention_dim");
}

void EgoPressureDiffPipeline::load_text() const {
  if (!has_text_ || text_) return;
  const fs::path d(dir_);
  text_ = std::make_unique<ClipTextModel>(ClipTextModel::load_dir((d / "text_encoder").string()));
  text_->set_release_weights_after_use(low_mem_);
  tokenizer_ = std::make_unique<ClipTokenizer>(ClipTokenizer::load_dir((d / "tokenizer").string()));
  if (unet_cfg_.pifr_enabled && text_->hidden_size() != unet_cfg_.pifr_text_dim)
    throw Error(dir_ + ": text_encoder hidden size " + std::to_string(text_->hidden_size()) +
                " does not match the U-Net's pifr.text_dim " + std::to_string(unet_cfg_.pifr_text_dim));
}

void EgoPressureDiffPipeline::load_masks() const {
  if (has_masks_ && !masks_) masks_ = std::make_unique<MaskEncoder>((fs::path(dir_) / "mask_encoder").string());
}

void EgoPressureDiffPipeline::drop() const {
  if (!low_mem_) return;
  unet_.reset();
  vae_.reset();
  image_encoder_.reset();
  text_.reset();
  tokenizer_.reset();
  masks_.reset();
}

PipelineSettings EgoPressureDiffPipeline::settings_from_defaults() const {
  PipelineSettings s;
  s.frames = defaults_.frames;
  s.steps = defaults_.steps;
  s.fps = defaults_.fps;
  s.motion_bucket_id = defaults_.motion_bucket_id;
  s.noise_aug_strength = defaults_.noise_aug_strength;
  s.min_guidance = defaults_.min_guidance;
  s.max_guidance = defaults_.max_guidance;
  return s;
}

static std::unique_ptr<Sampler> make_run_sampler(const fs::path& dir, const std::string& choice) {
  std::unique_ptr<Sampler> own = load_sampler((dir / "scheduler").string());
  if (choice.empty()) return own;
  if (choice == "euler") {
    if (std::string(own->name()) == "euler") return own;
    return std::make_unique<EulerSampler>(0.002, 700.0);
  }
  if (choice == "lcm") {
    if (std::string(own->name()) == "animatelcm") return own;
    return std::make_unique<AnimateLcmSampler>(AnimateLcmParams{});
  }
  throw Error("--sampler must be euler or lcm (got '" + choice + "')");
}

EgoPressureDiffPipeline::Shared EgoPressureDiffPipeline::encode(const Tensor& frames, const Tensor* masks,
                                                                const PipelineSettings& s, StageTimes* times) const {
  const int64_t F = frames.dim(0), S = size_;
  if (frames.ndim() != 4 || frames.dim(1) != 3 || frames.dim(2) != S || frames.dim(3) != S)
    throw Error("frames must be [F, 3, " + std::to_string(S) + ", " + std::to_string(S) + "], got " +
                frames.shape().str());
  if (masks) {
    if (!has_masks_) throw Error(dir_ + ": the model has no mask_encoder/, so --masks cannot be used");
    if (masks->dim(0) != F) throw Error("mask count " + std::to_string(masks->dim(0)) + " != frame count " + std::to_string(F));
  }
  StageTimes* load_times = low_mem_ ? times : nullptr;  // loading is a stage of its own only when it happens here
  Shared sh;
  sh.frames = F;
  {
    ScopedStage ld(load_times, "load");
    load_vae();
  }
  {
    ScopedStage st(times, "vae_encode");
    Tensor r = vae_->encode_mean(frames);  // [F, 4, h, w], mode(), unscaled
    require_finite(r, "the clip's latents (VAE encoder output)");
    sh.rgb_latents = r.reshaped({1, F, r.dim(1), r.dim(2), r.dim(3)});
  }
  drop();
  if (masks) {
    {
      ScopedStage ld(load_times, "load");
      load_masks();
    }
    ScopedStage st(times, "mask_encoder");
    sh.mask_features = masks_->forward(*masks);
    require_finite(sh.mask_features, "the mask features (mask encoder output)");
  }
  drop();
  {
    ScopedStage ld(load_times, "load");
    load_image_encoder();
  }
  {
    ScopedStage st(times, "clip_image");
    Tensor pix = svd_clip_preprocess(renderer_->prototype_image(), clip_norm_, image_encoder_->config().image_size);
    Tensor emb = image_encoder_->forward(pix).image_embeds;
    require_finite(emb, "the prototype embedding (CLIP image encoder output)");
    sh.prototype = emb.reshaped({1, 1, emb.dim(1)});
  }
  // The image tower is done for this run: let its mapped pages go (they are re-read if it runs again).
  if (!low_mem_) image_encoder_->weights()->release("");
  drop();
  sh.sampler = make_run_sampler(dir_, s.sampler);
  const int steps = s.steps > 0 ? s.steps : (s.sampler.empty() && defaults_.steps > 0 ? defaults_.steps
                                                                                      : sh.sampler->default_steps());
  sh.sampler->set_timesteps(steps);
  // Draw order (scheduler.md §5): initial latents, then one latent-shaped tensor per step that needs noise.
  const Shape lat = sh.rgb_latents.shape();
  TorchGenerator gen(s.seed);
  sh.init_noise = gen.randn(lat);
  sh.step_noises.resize(size_t(steps));
  for (int i = 0; i < steps; ++i)
    if (sh.sampler->step_needs_noise(i)) sh.step_noises[size_t(i)] = gen.randn(lat);
  return sh;
}

std::optional<std::string> EgoPressureDiffPipeline::prompt_for(const PromptFields& fields) const {
  std::optional<std::string> p = build_prompt(fields);
  if (!p || defaults_.prompt_template.empty()) return p;
  // A model directory that spells out the paper's template (as weights.md §1.1 shows) still gets the clause
  // dropping of §3.3; only a different template is filled verbatim. The paper's template is what build_prompt
  // produces with every field present, so placeholders as values reproduce it.
  PromptFields placeholders;
  for (const auto& k : {"obj_name", "weight", "material", "gender", "age", "subj_weight", "bodyfat"})
    placeholders[k] = std::string("{") + k + "}";
  if (defaults_.prompt_template == build_prompt(placeholders)) return p;
  return fill_template(defaults_.prompt_template, fields);
}

Tensor EgoPressureDiffPipeline::encode_text(const std::optional<std::string>& prompt, bool* truncated,
                                            StageTimes* times) const {
  if (truncated) *truncated = false;
  if (!prompt) return Tensor();
  if (!has_text_) throw Error(dir_ + ": the model has no text_encoder/ and tokenizer/, so a prompt cannot be used");
  if (!unet_cfg_.pifr_enabled) throw Error(dir_ + ": the U-Net has no PIFR layers, so a prompt has no effect");
  {
    ScopedStage ld(low_mem_ ? times : nullptr, "load");
    load_text();
  }
  Tensor out;
  {
    ScopedStage st(times, "text_encoder");
    TokenizedText t = tokenizer_->encode(*prompt);
    if (truncated) *truncated = t.truncated;
    IdTensor ids{Shape{1, int64_t(t.ids.size())}, t.ids};
    out = text_->forward(ids).last_hidden_state;  // [1, 77, T]
    require_finite(out, "the text embedding (CLIP text encoder output)");
  }
  if (!low_mem_) text_->weights()->release("");
  drop();
  return out;
}

EgoPressureDiffPipeline::Result EgoPressureDiffPipeline::run(const Shared& sh, const Tensor& text,
                                                             const PipelineSettings& s, const StepCallback& on_step,
                                                             StageTimes* times) {
  const int64_t F = sh.frames, lc = sh.rgb_latents.dim(2), h = sh.rgb_latents.dim(3), w = sh.rgb_latents.dim(4);
  const int64_t frame = lc * h * w, D = sh.prototype.dim(2);
  const bool cfg = guidance_enabled(s.max_guidance);
  const int64_t B = cfg ? 2 : 1;  // [uncond, cond]: zero prototype and zero RGB latents in the unconditional half
  const Sampler& sampler = *sh.sampler;
  const int steps = sampler.num_steps();
  StageTimes* load_times = low_mem_ ? times : nullptr;
  {
    ScopedStage ld(load_times, "load");
    load_unet();
  }

  Tensor ehs = Tensor::zeros({B, 1, D});
  std::memcpy(ehs.data() + (B - 1) * D, sh.prototype.data(), size_t(D) * sizeof(float));
  Tensor text_b;
  if (!text.empty()) {  // the same text in both halves
    const int64_t n = text.numel();
    text_b = Tensor({B, text.dim(1), text.dim(2)});
    for (int64_t b = 0; b < B; ++b) std::memcpy(text_b.data() + b * n, text.data(), size_t(n) * sizeof(float));
  }
  UNetConditioning cond = unet_->prepare(ehs, text.empty() ? nullptr : &text_b);
  Tensor ids({B, 3});
  for (int64_t b = 0; b < B; ++b)
    ids[b * 3] = s.fps - 1, ids[b * 3 + 1] = s.motion_bucket_id, ids[b * 3 + 2] = s.noise_aug_strength;
  const std::vector<float> g = frame_guidance_scales(s.min_guidance, s.max_guidance, F);

  Result res;
  Tensor x = sampler.init_latents(sh.init_noise);
  Tensor u = Tensor::zeros({B, F, 2 * lc, h, w});
  for (int i = 0; i < steps; ++i) {
    auto t0 = std::chrono::steady_clock::now();
    {
      ScopedStage st(times, "denoise");
      Tensor xs = sampler.scale_model_input(x, i);
      // u[b, f] = [x_scaled[f], R[f] (0 in the unconditional half)] (+ Mf[f] on all 8 channels)
      for (int64_t b = 0; b < B; ++b)
        for (int64_t f = 0; f < F; ++f) {
          float* dst = u.data() + (b * F + f) * 2 * frame;
          std::memcpy(dst, xs.data() + f * frame, size_t(frame) * sizeof(float));
          if (b == B - 1) std::memcpy(dst + frame, sh.rgb_latents.data() + f * frame, size_t(frame) * sizeof(float));
          else std::memset(dst + frame, 0, size_t(frame) * sizeof(float));
          if (!sh.mask_features.empty()) {
            const float* mf = sh.mask_features.data() + f * 2 * frame;
            for (int64_t k = 0; k < 2 * frame; ++k) dst[k] += mf[k];
          }
        }
      Tensor v = unet_->forward(u, float(sampler.timesteps()[size_t(i)]), ids, cond);
      if (cfg) {
        Tensor vu = Tensor::view({1, F, lc, h, w}, v.data()), vc = Tensor::view({1, F, lc, h, w}, v.data() + F * frame);
        v = cfg_combine(vu, vc, g);
      }
      const std::string after = "the latents after step " + std::to_string(i + 1) + " of " + std::to_string(steps);
      require_finite(v, after + " (U-Net output)");
      const Tensor* noise = sampler.step_needs_noise(i) ? &sh.step_noises[size_t(i)] : nullptr;
      x = sampler.step(v, i, x, noise);
      require_finite(x, after + " (" + sampler.name() + " sampler update)");
    }
    if (on_step) on_step(i + 1, steps, seconds_since(t0));
  }
  res.latents = x;
  // Decoding peaks in activation memory: the U-Net's mapped weights need not stay resident meanwhile (a following
  // prompt variant reads them again from the page cache).
  if (!low_mem_) unet_->weights()->release("");
  drop();
  {
    ScopedStage ld(load_times, "load");
    load_vae();
  }
  {
    ScopedStage st(times, "vae_decode");
    res.decoded = vae_->decode_latents(x.reshaped({F, lc, h, w}), F, s.decode_chunk);
    require_finite(res.decoded, "the decoded heatmaps (VAE decoder output)");
  }
  drop();
  {
    ScopedStage st(times, "postprocess");
    const int64_t img = 3 * size_ * size_;
    for (int64_t f = 0; f < F; ++f) res.frames.push_back(renderer_->process_frame(res.decoded.data() + f * img));
  }
  return res;
}

}  // namespace egopd
