#pragma once
// CLIPTextModel (HF transformers naming; clip.md §3): token + position embeddings, causal pre-LN encoder,
// final_layer_norm over all positions, pooling at the first eos_token_id, optional text_projection.
#include <memory>
#include <string>

#include "clip_image/clip_encoder.h"
#include "core/config.h"
#include "core/layers.h"
#include "core/tensor.h"
#include "core/weights.h"

namespace egopd {

struct ClipTextConfig {
  ClipEncoderConfig encoder;
  int64_t vocab_size = 49408;
  int64_t max_position_embeddings = 77;
  int64_t eos_token_id = 49407;  // 2 in legacy configs: pool at argmax(input_ids) instead
  int64_t projection_dim = 512;  // only used when the file has text_projection.weight
  // config.json of text_encoder/ (flat CLIPTextConfig, or a CLIPConfig with text_config).
  static ClipTextConfig from_config(const Config& file);
};

struct ClipTextOutput {
  Tensor last_hidden_state;  // [N, L, hidden], after final_layer_norm, all positions
  Tensor pooler_output;      // [N, hidden]
  Tensor text_embeds;        // [N, projection_dim]; empty without text_projection.weight
};

class ClipTextModel {
 public:
  // Folder with config.json + model.safetensors (or sharded / variant files). Strict key check.
  static ClipTextModel load_dir(const std::string& dir);
  ClipTextModel(const ClipTextConfig& config, std::shared_ptr<const WeightMap> weights);

  const ClipTextConfig& config() const { return config_; }
  const std::shared_ptr<const WeightMap>& weights() const { return weights_; }
  // Low-memory mode: page each encoder layer's mapped weights out after it runs (they are re-read on the next call).
  void set_release_weights_after_use(bool on) { encoder.release_after_use = on; }
  int64_t hidden_size() const { return config_.encoder.hidden; }
  bool has_projection() const { return has_projection_; }
  // input_ids [N, L], L <= max_position_embeddings, ids in [0, vocab_size).
  ClipTextOutput forward(const IdTensor& input_ids) const;
  // Row of the pooled token for one sequence (clip.md §3 step 5).
  int64_t pooling_position(const int64_t* ids, int64_t len) const;
  // Work per sequence of `len` tokens in FLOP (2 per multiply-add; causal attention counted in full).
  double flops_per_sequence(int64_t len) const;

 private:
  ClipTextConfig config_;
  std::shared_ptr<const WeightMap> weights_;
  WeightRef token_embedding;  // [vocab, hidden] in its stored dtype; rows converted when gathered
  Tensor position_embedding;  // [max_positions, hidden]
  ClipEncoder encoder;
  LayerNorm final_layer_norm;
  bool has_projection_ = false;
  Linear text_projection;  // hidden -> projection_dim, no bias (CLIPTextModelWithProjection files only)
};

}  // namespace egopd
