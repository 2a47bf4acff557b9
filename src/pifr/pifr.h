#pragma once
// PIFR (Physically-Informed Feature Rectification, egopressurediff.md §6): in every spatial transformer block the
// prototype cross-attention output z_proto is modulated by the text:
//   z_text = attn_text(n, text_tokens)   (0 without text)
//   [γ, β] = split_half(Linear_{C→2C}(SiLU(z_text)))
//   x     += z_proto ⊙ (1 + γ) + β
#include "core/attention_layer.h"

namespace egopd {

struct Pifr {
  int64_t channels = 0;
  Attention attn_text;  // pifr.attn_text: C queries, text_dim keys/values, no qkv bias
  Linear mod;           // pifr.mod.1: C -> 2C

  Pifr() = default;
  Pifr(const WeightView& w, int64_t channels, int64_t heads, int64_t text_dim);

  // Text keys/values for the whole run: text [videos, tokens, text_dim].
  ContextCache prepare_text(const float* text, int64_t videos, int64_t tokens) const;

  // n [rows, C] = norm2(x); proto = the stock attn2 with its context cache; text = nullptr for no-text mode.
  // x [rows, C] += z_proto ⊙ (1 + γ) + β.
  void apply(const float* n, int64_t rows, int64_t rows_per_video, const Attention& attn2,
             const ContextCache& proto, const ContextCache* text, float* x, Arena& arena) const;
};

}  // namespace egopd
