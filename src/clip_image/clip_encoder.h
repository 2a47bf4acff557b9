#pragma once
// The pre-LN transformer shared by the CLIP vision and text towers (clip.md §1), and the config reading both towers
// need (flat CLIPVisionConfig / CLIPTextConfig, or nested in a CLIPConfig; weights.md §1.2).
#include <string>
#include <vector>

#include "core/config.h"
#include "core/kernels/gemm.h"
#include "core/layers.h"
#include "core/tensor.h"
#include "core/weights.h"

namespace egopd {

struct ClipEncoderConfig {
  int64_t hidden = 0;        // hidden_size
  int64_t intermediate = 0;  // intermediate_size
  int64_t heads = 0;         // num_attention_heads
  int64_t layers = 0;        // num_hidden_layers
  float eps = 1e-5f;         // layer_norm_eps
  Act act = Act::GELU;       // hidden_act: "gelu" (exact erf) or "quick_gelu"
  int64_t head_dim() const { return hidden / heads; }
};

// `hidden_act` of a CLIP config -> kernel activation; any other value is an error naming the field.
Act clip_activation(const Config& c, const std::string& fallback);

// The tower config inside an HF config file: the file itself when flat, its `nested_key` object when
// model_type is "clip" (a full CLIPConfig).
Config clip_tower_config(const Config& file, const std::string& nested_key);

// Encoder fields with the HF defaults of the given tower ("vision" or "text") for absent keys.
ClipEncoderConfig read_clip_encoder_config(const Config& c, bool vision);

// Weight keys a tower tolerates besides its own (weights.md §3.1): buffers, logit_scale, and the other tower's
// keys when a full CLIPModel file is given.
std::vector<std::string> clip_tolerated_extra_keys(bool vision);

// encoder.layers.N: x = x + self_attn(layer_norm1(x)); x = x + fc2(act(fc1(layer_norm2(x)))).
struct ClipEncoderLayer {
  int64_t hidden = 0, heads = 0;
  Act act = Act::GELU;
  LayerNorm layer_norm1, layer_norm2;
  Linear q_proj, k_proj, v_proj, out_proj;
  Linear fc1, fc2;
  ClipEncoderLayer() = default;
  ClipEncoderLayer(const WeightView& w, const ClipEncoderConfig& c);
  // h [batch, seq, hidden] updated in place; causal: query i attends to keys j <= i (the text tower's mask).
  void forward(float* h, int64_t batch, int64_t seq, bool causal, Arena& arena) const;
};

// encoder.layers.0 .. num_hidden_layers-1
struct ClipEncoder {
  std::vector<ClipEncoderLayer> layers;
  std::vector<WeightView> layer_weights;  // encoder.layers.i, for paging a layer out after it runs
  bool release_after_use = false;         // low-memory mode: only the running layer's weights stay resident
  ClipEncoder() = default;
  ClipEncoder(const WeightView& encoder, const ClipEncoderConfig& c);
  void forward(float* h, int64_t batch, int64_t seq, bool causal, Arena& arena) const;
};

}  // namespace egopd
