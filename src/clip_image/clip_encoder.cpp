#include "clip_image/clip_encoder.h"

#include <cmath>

#include "core/error.h"
#include "core/kernels/attention.h"

namespace egopd {

Act clip_activation(const Config& c, const std::string& fallback) {
  const std::string act = c.get_string("hidden_act", fallback);
  if (act == "gelu") return Act::GELU;
  if (act == "quick_gelu") return Act::QuickGELU;
  c.fail("hidden_act", "unsupported activation '" + act + "' (supported: gelu, quick_gelu)");
}

Config clip_tower_config(const Config& file, const std::string& nested_key) {
  if (file.get_string("model_type", "") == "clip") return file.sub(nested_key);
  return file;
}

ClipEncoderConfig read_clip_encoder_config(const Config& c, bool vision) {
  // transformers' CLIPVisionConfig / CLIPTextConfig defaults, used only for keys a config leaves out.
  ClipEncoderConfig e;
  e.hidden = c.get_int("hidden_size", vision ? 768 : 512, kChannelRange);
  e.intermediate = c.get_int("intermediate_size", vision ? 3072 : 2048, kChannelRange);
  e.heads = c.get_int("num_attention_heads", vision ? 12 : 8, kCountRange);
  e.layers = c.get_int("num_hidden_layers", 12, IntRange{0, 1024});
  e.eps = float(c.get_double("layer_norm_eps", 1e-5, kEpsRange));
  e.act = clip_activation(c, "quick_gelu");
  if (e.hidden <= 0 || e.intermediate <= 0 || e.layers < 0) c.fail("hidden_size", "sizes must be positive");
  if (e.heads <= 0 || e.hidden % e.heads != 0)
    c.fail("num_attention_heads",
           std::to_string(e.heads) + " heads do not divide hidden_size " + std::to_string(e.hidden));
  return e;
}

std::vector<std::string> clip_tolerated_extra_keys(bool vision) {
  if (vision) return {"position_ids", "logit_scale", "text_model.", "text_projection."};
  return {"position_ids", "logit_scale", "vision_model.", "visual_projection."};
}

ClipEncoderLayer::ClipEncoderLayer(const WeightView& w, const ClipEncoderConfig& c)
    : hidden(c.hidden), heads(c.heads), act(c.act) {
  layer_norm1 = LayerNorm(w, "layer_norm1", c.hidden, c.eps);
  layer_norm2 = LayerNorm(w, "layer_norm2", c.hidden, c.eps);
  const WeightView attn = w.sub("self_attn");
  q_proj = Linear(attn, "q_proj", c.hidden, c.hidden);
  k_proj = Linear(attn, "k_proj", c.hidden, c.hidden);
  v_proj = Linear(attn, "v_proj", c.hidden, c.hidden);
  out_proj = Linear(attn, "out_proj", c.hidden, c.hidden);
  const WeightView mlp = w.sub("mlp");
  fc1 = Linear(mlp, "fc1", c.hidden, c.intermediate);
  fc2 = Linear(mlp, "fc2", c.intermediate, c.hidden);
}

void ClipEncoderLayer::forward(float* h, int64_t batch, int64_t seq, bool causal, Arena& arena) const {
  const size_t mark = arena.mark();
  const int64_t rows = batch * seq;
  const int64_t dh = hidden / heads;
  Tensor normed = arena.take({rows, hidden});
  Tensor q = arena.take({rows, hidden});
  Tensor k = arena.take({rows, hidden});
  Tensor v = arena.take({rows, hidden});
  Tensor attn = arena.take({rows, hidden});

  // Self-attention block: heads are contiguous channel slices of q/k/v [batch, seq, hidden].
  layer_norm1.forward(h, normed.data(), rows);
  q_proj.forward(normed.data(), rows, q.data());
  k_proj.forward(normed.data(), rows, k.data());
  v_proj.forward(normed.data(), rows, v.data());
  AttentionArgs a;
  a.batch = batch;
  a.heads = heads;
  a.lq = a.lk = seq;
  a.dh = dh;
  a.q = q.data();
  a.k = k.data();
  a.v = v.data();
  a.out = attn.data();
  a.q_ld = a.k_ld = a.v_ld = a.out_ld = hidden;
  a.q_bs = a.k_bs = a.v_bs = a.out_bs = seq * hidden;
  a.scale = float(1.0 / std::sqrt(double(dh)));
  a.causal = causal;
  attention(a);
  out_proj.forward(attn.data(), rows, h, Act::None, /*accumulate=*/true);  // h = h + out_proj(attn)

  // MLP block: h = h + fc2(act(fc1(layer_norm2(h)))).
  layer_norm2.forward(h, normed.data(), rows);
  Tensor mid = arena.take({rows, fc1.out});
  fc1.forward(normed.data(), rows, mid.data(), act);
  fc2.forward(mid.data(), rows, h, Act::None, /*accumulate=*/true);
  arena.release(mark);
}

ClipEncoder::ClipEncoder(const WeightView& encoder, const ClipEncoderConfig& c) {
  layers.reserve(size_t(c.layers));
  for (int64_t i = 0; i < c.layers; ++i) {
    layer_weights.push_back(encoder.sub("layers." + std::to_string(i)));
    layers.emplace_back(layer_weights.back(), c);
  }
}

void ClipEncoder::forward(float* h, int64_t batch, int64_t seq, bool causal, Arena& arena) const {
  for (size_t i = 0; i < layers.size(); ++i) {
    layers[i].forward(h, batch, seq, causal, arena);
    if (release_after_use) layer_weights[i].release();
  }
}

}  // namespace egopd
