#include "clip_image/clip_vision.h"

#include <algorithm>
#include <cstring>
#include <filesystem>

#include "core/error.h"
#include "core/kernels/layout.h"

namespace egopd {

ClipVisionConfig ClipVisionConfig::from_config(const Config& file) {
  const Config c = clip_tower_config(file, "vision_config");
  ClipVisionConfig v;
  v.encoder = read_clip_encoder_config(c, /*vision=*/true);
  v.image_size = c.get_int("image_size", 224, IntRange{1, 4096});
  v.patch_size = c.get_int("patch_size", 32, IntRange{1, 4096});
  v.num_channels = c.get_int("num_channels", 3, kChannelRange);
  // A CLIPConfig keeps projection_dim at the top level.
  v.projection_dim = c.get_int("projection_dim", file.get_int("projection_dim", 512));
  if (v.patch_size <= 0 || v.image_size % v.patch_size != 0)
    c.fail("patch_size", "image_size " + std::to_string(v.image_size) + " is not a multiple of patch_size " +
                             std::to_string(v.patch_size));
  if (v.num_channels <= 0) c.fail("num_channels", "must be positive");
  if (v.projection_dim <= 0) c.fail("projection_dim", "must be positive");
  return v;
}

ClipVisionModelWithProjection ClipVisionModelWithProjection::load_dir(const std::string& dir) {
  const ClipVisionConfig config =
      ClipVisionConfig::from_config(Config::load((std::filesystem::path(dir) / "config.json").string()));
  auto weights = std::make_shared<const WeightMap>(WeightMap::load_dir(dir, "model", "image_encoder"));
  ClipVisionModelWithProjection model(config, weights);
  weights->check_all_used(clip_tolerated_extra_keys(/*vision=*/true));
  return model;
}

ClipVisionModelWithProjection::ClipVisionModelWithProjection(const ClipVisionConfig& config,
                                                             std::shared_ptr<const WeightMap> weights)
    : config_(config), weights_(std::move(weights)) {
  const int64_t d = config_.encoder.hidden;
  const WeightView root = weights_->root();
  const WeightView vm = root.sub("vision_model");
  const WeightView emb = vm.sub("embeddings");
  patch_embedding = Conv2d(emb, "patch_embedding", config_.num_channels, d, config_.patch_size, config_.patch_size,
                           /*pad=*/0, /*has_bias=*/false);
  class_embedding = emb.get_f32("class_embedding", {d});
  position_embedding = emb.get_f32("position_embedding.weight", {config_.num_patches() + 1, d});
  pre_layrnorm = LayerNorm(vm, "pre_layrnorm", d, config_.encoder.eps);
  encoder = ClipEncoder(vm.sub("encoder"), config_.encoder);
  post_layernorm = LayerNorm(vm, "post_layernorm", d, config_.encoder.eps);
  visual_projection = Linear(root, "visual_projection", d, config_.projection_dim, /*has_bias=*/false);
}

ClipVisionOutput ClipVisionModelWithProjection::forward(const Tensor& pixel_values) const {
  const int64_t s = config_.image_size, c = config_.num_channels;
  if (pixel_values.ndim() != 4 || pixel_values.dim(1) != c || pixel_values.dim(2) != s || pixel_values.dim(3) != s)
    throw Error("image_encoder: pixel_values must be [B," + std::to_string(c) + "," + std::to_string(s) + "," +
                std::to_string(s) + "], got " + pixel_values.shape().str());
  const int64_t b = pixel_values.dim(0), d = config_.encoder.hidden;
  const int64_t p = config_.num_patches(), seq = p + 1, g = config_.grid();

  Arena arena;
  // Patch embedding: [B,3,S,S] -> [B,D,g,g]; tokens in raster order [B,D,P] -> [B,P,D] after the class token.
  Tensor patches = arena.take({b, d, g, g});
  patch_embedding.forward(pixel_values.data(), b, s, s, patches.data());
  ClipVisionOutput out;
  out.last_hidden_state = Tensor({b, seq, d});
  float* h = out.last_hidden_state.data();
  for (int64_t i = 0; i < b; ++i) {
    float* hi = h + i * seq * d;
    std::memcpy(hi, class_embedding.data(), size_t(d) * sizeof(float));
    transpose_batched(patches.data() + i * d * p, hi + d, 1, d, p);  // [D,P] -> [P,D]
    for (int64_t t = 0; t < seq * d; ++t) hi[t] += position_embedding[t];
  }
  pre_layrnorm.forward(h, h, b * seq);
  encoder.forward(h, b, seq, /*causal=*/false, arena);

  // Pooling: post_layernorm of the class token of each image, then the projection.
  out.pooler_output = Tensor({b, d});
  for (int64_t i = 0; i < b; ++i) post_layernorm.forward(h + i * seq * d, out.pooler_output.data() + i * d, 1);
  out.image_embeds = Tensor({b, config_.projection_dim});
  visual_projection.forward(out.pooler_output.data(), b, out.image_embeds.data());
  return out;
}

double ClipVisionModelWithProjection::flops_per_image() const {
  const double d = double(config_.encoder.hidden), i = double(config_.encoder.intermediate);
  const double seq = double(config_.num_patches() + 1);
  const double patch = 2.0 * double(config_.num_patches()) * d * double(config_.num_channels) *
                       double(config_.patch_size * config_.patch_size);
  const double per_layer = 2.0 * seq * (4 * d * d + 2 * d * i) + 2.0 * 2.0 * seq * seq * d;
  return patch + double(config_.encoder.layers) * per_layer + 2.0 * d * double(config_.projection_dim);
}

}  // namespace egopd
