#pragma once
// TransformerSpatioTemporalModel (unet3d.md §6): GroupNorm → proj_in → [spatial BasicTransformerBlock (+PIFR),
// temporal TemporalBasicTransformerBlock on z + frame-position embedding, AlphaBlender] × layers → proj_out,
// plus the input as residual. Tokens stay frame-major [B*F*L, C] (row (b·F+f)·L + l): the temporal block's
// per-row operations do not care about row order, and its attention reads the F rows of a token sequence with a
// stride of L rows, so the Seq re-layout is never materialised.
#include <memory>
#include <vector>

#include "core/attention_layer.h"
#include "core/layers.h"
#include "pifr/pifr.h"

namespace egopd {

// FeedForward(dim, mult=4) with GEGLU: net.0.proj (dim → 8·dim), GEGLU, net.2 (4·dim → dim).
struct FeedForward {
  int64_t dim = 0, inner = 0;
  Linear proj, out;
  FeedForward() = default;
  FeedForward(const WeightView& w, int64_t dim);
  void forward_add(const float* x, int64_t rows, float* y, Arena& arena) const;  // y += ff(x)
};

struct BasicTransformerBlock {
  LayerNorm norm1, norm2, norm3;
  Attention attn1, attn2;
  FeedForward ff;
  std::unique_ptr<Pifr> pifr;  // EgoPressureDiff only
};

struct TemporalBasicTransformerBlock {
  LayerNorm norm_in, norm1, norm2, norm3;
  FeedForward ff_in, ff;
  Attention attn1, attn2;
};

// Per-run conditioning of one transformer: context caches of every layer's cross-attentions.
struct TransformerConditioning {
  std::vector<ContextCache> spatial, temporal, text;  // text empty in no-text mode
};

struct TransformerSpatioTemporal {
  int64_t channels = 0, heads = 1;
  GroupNorm norm;
  Linear proj_in, proj_out;
  Linear pos_linear_1, pos_linear_2;  // time_pos_embed
  std::vector<BasicTransformerBlock> spatial;
  std::vector<TemporalBasicTransformerBlock> temporal;
  float alpha = 0.5f;

  TransformerSpatioTemporal() = default;
  TransformerSpatioTemporal(const WeightView& w, int64_t channels, int64_t heads, int64_t layers,
                            int64_t cross_dim, int64_t pifr_text_dim);
  // ehs [B, S, cross_dim]; text [B, T, text_dim] or null
  TransformerConditioning prepare(const Tensor& ehs, const Tensor* text) const;
  // x [B*F, C, H, W] -> same shape
  Tensor forward(const Tensor& x, int64_t videos, const TransformerConditioning& cond, Arena& arena) const;
};

}  // namespace egopd
