#pragma once
// diffusers `Attention` (to_q, to_k, to_v, to_out.0) with the default processor: heads are contiguous channel
// slices, softmax(Q Kᵀ · dh^-0.5) V, then to_out. Used for self-attention over token sequences laid out with
// strides, and for cross-attention against a per-video context whose keys/values are computed once per run.
#include <string>

#include "core/layers.h"
#include "core/tensor.h"

namespace egopd {

// Where the rows of the attention sequences are: sequence s of video b, element t, is row
// b*video_stride + s*seq_stride + t*elem_stride of a [rows, dim] matrix.
struct SequenceLayout {
  int64_t videos = 1, seqs_per_video = 1, len = 1;
  int64_t video_stride = 0, seq_stride = 0, elem_stride = 1;
  int64_t rows() const { return videos * seqs_per_video * len; }
};

// Keys/values of a per-video context [videos, tokens, ctx_dim], computed once. With one token the softmax is
// exactly 1, so the whole attention output is to_out(to_v(token)) for every query: `folded` holds it [videos, dim].
struct ContextCache {
  int64_t videos = 0, tokens = 0;
  Tensor k, v;    // [videos, tokens, inner]   (tokens > 1)
  Tensor folded;  // [videos, dim]             (tokens == 1)
  bool is_folded() const { return tokens == 1; }
};

struct Attention {
  int64_t query_dim = 0, context_dim = 0, heads = 1, dim_head = 0, inner = 0;
  Linear to_q, to_k, to_v, to_out;
  Attention() = default;
  Attention(const WeightView& w, int64_t query_dim, int64_t context_dim, int64_t heads, int64_t dim_head,
            bool qkv_bias);

  // y += to_out(attention(x, x)) over the sequences of `layout`; x, y [rows, query_dim].
  void self_attention_add(const float* x, const SequenceLayout& layout, float* y, Arena& arena) const;

  ContextCache prepare_context(const float* ctx, int64_t videos, int64_t tokens) const;
  // out (=, or += when accumulate) attention(x, context of video r / rows_per_video); x, out [rows, query_dim].
  void cross_attention(const float* x, int64_t rows, int64_t rows_per_video, const ContextCache& ctx, float* out,
                       bool accumulate, Arena& arena) const;
};

}  // namespace egopd
