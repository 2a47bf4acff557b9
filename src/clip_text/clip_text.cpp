#include "clip_text/clip_text.h"

#include <filesystem>

#include "core/dtype.h"
#include "core/error.h"

namespace egopd {

ClipTextConfig ClipTextConfig::from_config(const Config& file) {
  const Config c = clip_tower_config(file, "text_config");
  ClipTextConfig t;
  t.encoder = read_clip_encoder_config(c, /*vision=*/false);
  t.vocab_size = c.get_int("vocab_size", 49408);
  t.max_position_embeddings = c.get_int("max_position_embeddings", 77);
  t.eos_token_id = c.get_int("eos_token_id", 2);  // transformers' CLIPTextConfig default (legacy pooling)
  t.projection_dim = c.get_int("projection_dim", file.get_int("projection_dim", 512));
  if (t.vocab_size <= 0) c.fail("vocab_size", "must be positive");
  if (t.max_position_embeddings <= 0) c.fail("max_position_embeddings", "must be positive");
  return t;
}

ClipTextModel ClipTextModel::load_dir(const std::string& dir) {
  const ClipTextConfig config =
      ClipTextConfig::from_config(Config::load((std::filesystem::path(dir) / "config.json").string()));
  auto weights = std::make_shared<const WeightMap>(WeightMap::load_dir(dir, "model", "text_encoder"));
  ClipTextModel model(config, weights);
  weights->check_all_used(clip_tolerated_extra_keys(/*vision=*/false));
  return model;
}

ClipTextModel::ClipTextModel(const ClipTextConfig& config, std::shared_ptr<const WeightMap> weights)
    : config_(config), weights_(std::move(weights)) {
  const int64_t d = config_.encoder.hidden;
  const WeightView root = weights_->root();
  const WeightView tm = root.sub("text_model");
  const WeightView emb = tm.sub("embeddings");
  token_embedding = emb.get("token_embedding.weight", {config_.vocab_size, d});
  if (!is_float_weight(token_embedding.dtype))
    throw Error("text_encoder: " + token_embedding.key + " must be stored as F32, F16 or BF16");
  position_embedding = emb.get_f32("position_embedding.weight", {config_.max_position_embeddings, d});
  encoder = ClipEncoder(tm.sub("encoder"), config_.encoder);
  final_layer_norm = LayerNorm(tm, "final_layer_norm", d, config_.encoder.eps);
  has_projection_ = root.has("text_projection.weight");
  if (has_projection_) text_projection = Linear(root, "text_projection", d, config_.projection_dim, /*has_bias=*/false);
}

int64_t ClipTextModel::pooling_position(const int64_t* ids, int64_t len) const {
  if (config_.eos_token_id == 2) {  // legacy configs: the first occurrence of the largest id (the EOS 49407)
    int64_t best = 0;
    for (int64_t j = 1; j < len; ++j)
      if (ids[j] > ids[best]) best = j;
    return best;
  }
  for (int64_t j = 0; j < len; ++j)
    if (ids[j] == config_.eos_token_id) return j;
  return 0;
}

ClipTextOutput ClipTextModel::forward(const IdTensor& input_ids) const {
  if (input_ids.shape.ndim() != 2) throw Error("text_encoder: input_ids must be [N, L], got " + input_ids.shape.str());
  const int64_t n = input_ids.shape[0], len = input_ids.shape[1], d = config_.encoder.hidden;
  if (len < 1 || len > config_.max_position_embeddings)
    throw Error("text_encoder: sequence length " + std::to_string(len) + " outside 1.." +
                std::to_string(config_.max_position_embeddings) + " (max_position_embeddings)");
  EGOPD_CHECK(int64_t(input_ids.values.size()) == n * len, "input_ids size");

  // h = token_embedding[ids] + position_embedding[0..L-1]   -> [N, L, D]
  ClipTextOutput out;
  out.last_hidden_state = Tensor({n, len, d});
  float* h = out.last_hidden_state.data();
  for (int64_t r = 0; r < n * len; ++r) {
    const int64_t id = input_ids.values[size_t(r)];
    if (id < 0 || id >= config_.vocab_size)
      throw Error("text_encoder: token id " + std::to_string(id) + " outside the vocabulary (vocab_size " +
                  std::to_string(config_.vocab_size) + ")");
    const size_t row_bytes = size_t(d) * dtype_size(token_embedding.dtype);
    const auto* row = static_cast<const uint8_t*>(token_embedding.data) + size_t(id) * row_bytes;
    convert_to_f32(token_embedding.dtype, row, h + r * d, size_t(d));
    const float* pe = position_embedding.data() + (r % len) * d;
    for (int64_t c = 0; c < d; ++c) h[r * d + c] += pe[c];
  }
  Arena arena;
  encoder.forward(h, n, len, /*causal=*/true, arena);
  final_layer_norm.forward(h, h, n * len);

  out.pooler_output = Tensor({n, d});
  for (int64_t i = 0; i < n; ++i) {
    const int64_t pos = pooling_position(input_ids.values.data() + i * len, len);
    std::copy(h + (i * len + pos) * d, h + (i * len + pos + 1) * d, out.pooler_output.data() + i * d);
  }
  if (has_projection_) {
    out.text_embeds = Tensor({n, config_.projection_dim});
    text_projection.forward(out.pooler_output.data(), n, out.text_embeds.data());
  }
  return out;
}

double ClipTextModel::flops_per_sequence(int64_t len) const {
  const double d = double(config_.encoder.hidden), i = double(config_.encoder.intermediate), l = double(len);
  const double per_layer = 2.0 * l * (4 * d * d + 2 * d * i) + 2.0 * 2.0 * l * l * d;
  return double(config_.encoder.layers) * per_layer;
}

}  // namespace egopd
