#include "core/attention_layer.h"

#include <cmath>
#include <cstring>

#include "core/error.h"
#include "core/kernels/attention.h"
#include "core/kernels/channel_ops.h"

namespace egopd {

Attention::Attention(const WeightView& w, int64_t qd, int64_t cd, int64_t h, int64_t dh, bool qkv_bias)
    : query_dim(qd), context_dim(cd), heads(h), dim_head(dh), inner(h * dh) {
  to_q = Linear(w, "to_q", query_dim, inner, qkv_bias);
  to_k = Linear(w, "to_k", context_dim, inner, qkv_bias);
  to_v = Linear(w, "to_v", context_dim, inner, qkv_bias);
  to_out = Linear(w, "to_out.0", inner, query_dim, true);
}

void Attention::self_attention_add(const float* x, const SequenceLayout& lay, float* y, Arena& arena) const {
  const size_t mark = arena.mark();
  const int64_t rows = lay.rows();
  Tensor q = arena.take({rows, inner}), k = arena.take({rows, inner}), v = arena.take({rows, inner});
  to_q.forward(x, rows, q.data());
  to_k.forward(x, rows, k.data());
  to_v.forward(x, rows, v.data());
  Tensor o = arena.take({rows, inner});
  for (int64_t b = 0; b < lay.videos; ++b) {
    AttentionArgs a;
    a.batch = lay.seqs_per_video;
    a.heads = heads;
    a.lq = a.lk = lay.len;
    a.dh = dim_head;
    const int64_t off = b * lay.video_stride * inner;
    a.q = q.data() + off, a.k = k.data() + off, a.v = v.data() + off, a.out = o.data() + off;
    a.q_ld = a.k_ld = a.v_ld = a.out_ld = lay.elem_stride * inner;
    a.q_bs = a.k_bs = a.v_bs = a.out_bs = lay.seq_stride * inner;
    a.scale = float(1.0 / std::sqrt(double(dim_head)));
    attention(a);
  }
  to_out.forward(o.data(), rows, y, Act::None, /*accumulate=*/true);
  arena.release(mark);
}

ContextCache Attention::prepare_context(const float* ctx, int64_t videos, int64_t tokens) const {
  ContextCache c;
  c.videos = videos;
  c.tokens = tokens;
  Tensor k({videos * tokens, inner}), v({videos * tokens, inner});
  to_v.forward(ctx, videos * tokens, v.data());
  if (tokens == 1) {
    c.folded = Tensor({videos, query_dim});
    to_out.forward(v.data(), videos, c.folded.data());
    return c;
  }
  to_k.forward(ctx, videos * tokens, k.data());
  c.k = k;
  c.v = v;
  return c;
}

void Attention::cross_attention(const float* x, int64_t rows, int64_t rows_per_video, const ContextCache& ctx,
                                float* out, bool accumulate, Arena& arena) const {
  EGOPD_CHECK(rows == ctx.videos * rows_per_video, "cross-attention rows do not match the context's videos");
  if (ctx.is_folded()) {
    if (!accumulate) std::memset(out, 0, size_t(rows * query_dim) * sizeof(float));
    add_row_vectors(out, rows, query_dim, ctx.folded.data(), rows_per_video);
    return;
  }
  const size_t mark = arena.mark();
  Tensor q = arena.take({rows, inner}), o = arena.take({rows, inner});
  to_q.forward(x, rows, q.data());
  for (int64_t b = 0; b < ctx.videos; ++b) {
    AttentionArgs a;
    a.batch = 1;
    a.heads = heads;
    a.lq = rows_per_video;
    a.lk = ctx.tokens;
    a.dh = dim_head;
    a.q = q.data() + b * rows_per_video * inner;
    a.out = o.data() + b * rows_per_video * inner;
    a.k = ctx.k.data() + b * ctx.tokens * inner;
    a.v = ctx.v.data() + b * ctx.tokens * inner;
    a.q_ld = a.k_ld = a.v_ld = a.out_ld = inner;
    a.q_bs = a.out_bs = rows_per_video * inner;
    a.k_bs = a.v_bs = ctx.tokens * inner;
    a.scale = float(1.0 / std::sqrt(double(dim_head)));
    attention(a);
  }
  to_out.forward(o.data(), rows, out, Act::None, accumulate);
  arena.release(mark);
}

}  // namespace egopd
