#pragma once
// CLIPVisionModelWithProjection (HF transformers naming; clip.md §2): patch embedding, class + position embeddings,
// pre_layrnorm, pre-LN encoder, post_layernorm of the class token, visual_projection (no bias, no L2 norm).
#include <memory>
#include <string>

#include "clip_image/clip_encoder.h"
#include "core/config.h"
#include "core/layers.h"
#include "core/tensor.h"
#include "core/weights.h"

namespace egopd {

struct ClipVisionConfig {
  ClipEncoderConfig encoder;
  int64_t image_size = 224;
  int64_t patch_size = 32;
  int64_t num_channels = 3;
  int64_t projection_dim = 512;
  int64_t grid() const { return image_size / patch_size; }
  int64_t num_patches() const { return grid() * grid(); }
  // config.json of image_encoder/ (flat CLIPVisionConfig, or a CLIPConfig with vision_config).
  static ClipVisionConfig from_config(const Config& file);
};

struct ClipVisionOutput {
  Tensor last_hidden_state;  // [B, 1+P, hidden]: encoder output, without post_layernorm
  Tensor pooler_output;      // [B, hidden]: post_layernorm(class token)
  Tensor image_embeds;       // [B, projection_dim]
};

class ClipVisionModelWithProjection {
 public:
  // Folder with config.json + model.safetensors (or sharded / variant files). Strict key check.
  static ClipVisionModelWithProjection load_dir(const std::string& dir);
  // Builds the tower from an already open weight map (kept alive by the model).
  ClipVisionModelWithProjection(const ClipVisionConfig& config, std::shared_ptr<const WeightMap> weights);

  const ClipVisionConfig& config() const { return config_; }
  const std::shared_ptr<const WeightMap>& weights() const { return weights_; }
  // Low-memory mode: page each encoder layer's mapped weights out after it runs (they are re-read on the next call).
  void set_release_weights_after_use(bool on) { encoder.release_after_use = on; }
  // pixel_values [B, num_channels, image_size, image_size] (already normalised).
  ClipVisionOutput forward(const Tensor& pixel_values) const;
  // Work per image in FLOP (2 per multiply-add), for benchmarks.
  double flops_per_image() const;

 private:
  ClipVisionConfig config_;
  std::shared_ptr<const WeightMap> weights_;
  Conv2d patch_embedding;     // kernel = stride = patch_size, no bias
  Tensor class_embedding;     // [hidden]
  Tensor position_embedding;  // [1+P, hidden]
  LayerNorm pre_layrnorm;     // (sic: the real key name)
  ClipEncoder encoder;
  LayerNorm post_layernorm;
  Linear visual_projection;  // hidden -> projection_dim, no bias
};

}  // namespace egopd
