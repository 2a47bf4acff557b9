#pragma once
// The EgoPressureDiff inference pipeline (egopressurediff.md): RGB frames -> per-frame VAE latents, hint masks ->
// mask features, prototype heatmap -> CLIP image token, prompt -> CLIP text tokens (PIFR), sampler loop over the
// U-Net, temporal VAE decode, heatmap post-processing -> 162 taxel pressures.
// Everything that does not depend on the text is computed once in encode() and shared by prompt variants
// (counterfactual prompting, §9).
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "clip_image/clip_vision.h"
#include "clip_image/svd_preprocess.h"
#include "clip_text/clip_text.h"
#include "clip_text/clip_tokenizer.h"
#include "core/config.h"
#include "core/timing.h"
#include "mask_encoder/mask_encoder.h"
#include "pipeline/prompt.h"
#include "pressure/pressure.h"
#include "scheduler/sampler.h"
#include "unet3d/unet.h"
#include "vae/temporal_vae.h"

namespace egopd {

// model_index.json "egopd_defaults" (every key optional; egopressurediff.md §8).
struct ModelDefaults {
  int steps = 0;  // 0: the sampler's own default (Euler 25, AnimateLCM 8)
  int64_t frames = 16, resolution = 256;
  float fps = 5, motion_bucket_id = 127, noise_aug_strength = 0.02f;
  float min_guidance = 1, max_guidance = 1;
  std::string prompt_template;  // empty: the paper's template with clause dropping
};
// From a parsed model_index.json; each value range-checked (errors name the file and field).
ModelDefaults read_model_defaults(const Config& model_index);

struct PipelineSettings {
  int64_t frames = 16;
  std::string sampler;  // "" = the model's scheduler config; "euler" or "lcm" to override
  int steps = 0;        // 0 = default (model defaults, else sampler default)
  uint64_t seed = 0;
  float min_guidance = 1, max_guidance = 1;
  float fps = 5, motion_bucket_id = 127, noise_aug_strength = 0.02f;
  int64_t decode_chunk = 0;  // frames per VAE decode call; 0 = all frames (vae.md §5.2: other values change the result)
};

// Low-memory mode runs the decoder's temporal halves in pixel tiles of this many floats and recomputes their first
// convolution instead of keeping its whole-clip output: the same numbers, decoded as one clip, in less memory.
constexpr TemporalMemory kLowMemTemporal{int64_t(1) << 20, /*recompute_conv1=*/true};

// step (1-based), steps, seconds of that step
using StepCallback = std::function<void(int, int, double)>;

class EgoPressureDiffPipeline {
 public:
  // Loads every component of an EgoPressureDiff model directory (weights.md §1) for S x S frames. text_encoder/,
  // tokenizer/ and mask_encoder/ are optional (without them only no-text mode / no masks are available).
  // low_mem: components are loaded right before the stage that uses them and dropped after it (VAE, mask encoder and
  // CLIP towers in encode() / encode_text(), paging each layer's weights out after it runs; the U-Net for the sampler
  // loop, paging each block's weights out after it runs; the VAE again for the decode, paging each decoder block out
  // after it runs, whose temporal layers then work in small tiles without a whole-clip temporary), so peak memory is
  // about one component's working set, and the process keeps no freed activation blocks for reuse
  // (set_block_cache_limit(0)). The results are the same as in normal mode. Loading time then counts in the "load"
  // stage of each call.
  EgoPressureDiffPipeline(const std::string& model_dir, int64_t size, const std::string& template_path = "",
                          bool low_mem = false);

  const ModelDefaults& defaults() const { return defaults_; }
  int64_t size() const { return size_; }
  bool has_text_encoder() const { return has_text_; }
  bool has_mask_encoder() const { return has_masks_; }
  bool low_mem() const { return low_mem_; }
  const HandTemplate& hand_template() const { return template_; }
  const PressureRenderer& renderer() const { return *renderer_; }
  // settings filled from the model defaults where the caller left them at their defaults
  PipelineSettings settings_from_defaults() const;

  struct Shared {
    int64_t frames = 0;
    Tensor rgb_latents;    // [1, F, 4, h, w]  (unscaled VAE means)
    Tensor mask_features;  // [F, 8, h, w]     (empty without masks)
    Tensor prototype;      // [1, 1, D]        CLIP image token of the prototype heatmap
    Tensor init_noise;     // [1, F, 4, h, w]  N(0,1), torch-compatible draw from the seed
    std::vector<Tensor> step_noises;  // one per sampler step that needs noise (AnimateLCM), else empty tensors
    std::unique_ptr<Sampler> sampler;
  };
  // frames [F, 3, S, S] in [-1, 1]; masks [F, 1, S, S] in {0, 1} or null.
  Shared encode(const Tensor& frames, const Tensor* masks, const PipelineSettings& s, StageTimes* times) const;

  // Prompt for metadata fields (nullopt: no-text mode); uses the model's template if it has one.
  std::optional<std::string> prompt_for(const PromptFields& fields) const;
  // [1, 77, text_dim] text tokens, or an empty tensor for no-text mode. *truncated is set when the prompt was
  // longer than 77 tokens.
  Tensor encode_text(const std::optional<std::string>& prompt, bool* truncated, StageTimes* times) const;

  struct Result {
    Tensor latents;   // [1, F, 4, h, w]
    Tensor decoded;   // [F, 3, S, S]
    std::vector<PressureRenderer::Frame> frames;  // heatmaps and normalised taxels per frame
  };
  Result run(const Shared& shared, const Tensor& text, const PipelineSettings& s, const StepCallback& on_step,
             StageTimes* times);

 private:
  // Each loads one component (with its cross-checks against the U-Net config) unless it is loaded already; drop()
  // releases every component again in low-memory mode and does nothing otherwise. Const because encode() and
  // encode_text() load lazily in low-memory mode.
  void load_unet() const;
  void load_vae() const;
  void load_image_encoder() const;
  void load_text() const;
  void load_masks() const;
  void drop() const;

  std::string dir_;
  int64_t size_;
  bool low_mem_ = false, has_text_ = false, has_masks_ = false;
  ModelDefaults defaults_;
  UNetConfig unet_cfg_;
  HandTemplate template_;
  std::unique_ptr<PressureRenderer> renderer_;
  // mutable: loaded on demand and dropped inside const calls in low-memory mode
  mutable std::unique_ptr<UNetSpatioTemporal> unet_;
  mutable std::unique_ptr<TemporalVAE> vae_;
  mutable std::unique_ptr<ClipVisionModelWithProjection> image_encoder_;
  ClipImageNormalization clip_norm_;
  mutable std::unique_ptr<ClipTextModel> text_;
  mutable std::unique_ptr<ClipTokenizer> tokenizer_;
  mutable std::unique_ptr<MaskEncoder> masks_;
};

}  // namespace egopd
