#include "unet3d/transformer.h"

#include <algorithm>

#include "core/error.h"
#include "core/kernels/channel_ops.h"
#include "core/kernels/elementwise.h"
#include "core/kernels/layout.h"
#include "unet3d/resblock.h"

namespace egopd {

// Rows per feed-forward chunk: bounds its scratch ([rows, 4·dim], and [rows, 8·dim] where the projection is stored
// whole: gemm_geglu).
constexpr int64_t kFeedForwardRows = 2048;

FeedForward::FeedForward(const WeightView& w, int64_t d) : dim(d), inner(4 * d) {
  proj = Linear(w, "net.0.proj", dim, 2 * inner);
  out = Linear(w, "net.2", inner, dim);
}

void FeedForward::forward_add(const float* x, int64_t rows, float* y, Arena& arena) const {
  const size_t mark = arena.mark();
  const int64_t chunk = std::min(rows, kFeedForwardRows);
  Tensor g = arena.take({chunk, inner});
  Tensor p = proj.geglu_needs_scratch() ? arena.take({chunk, 2 * inner}) : Tensor();
  for (int64_t r0 = 0; r0 < rows; r0 += chunk) {
    const int64_t r = std::min(chunk, rows - r0);
    proj.forward_geglu(x + r0 * dim, r, g.data(), p.data());
    out.forward(g.data(), r, y + r0 * dim, Act::None, /*accumulate=*/true);
  }
  arena.release(mark);
}

TransformerSpatioTemporal::TransformerSpatioTemporal(const WeightView& w, int64_t c, int64_t h, int64_t layers,
                                                     int64_t cross_dim, int64_t pifr_text_dim)
    : channels(c), heads(h) {
  const int64_t dh = c / h;
  norm = GroupNorm(w, "norm", c, 32, 1e-6f);
  proj_in = Linear(w, "proj_in", c, c);
  proj_out = Linear(w, "proj_out", c, c);
  pos_linear_1 = Linear(w, "time_pos_embed.linear_1", c, 4 * c);
  pos_linear_2 = Linear(w, "time_pos_embed.linear_2", 4 * c, c);
  alpha = sigmoid_of_mix_factor(w.sub("time_mixer"));
  spatial.resize(size_t(layers));
  temporal.resize(size_t(layers));
  for (int64_t i = 0; i < layers; ++i) {
    const WeightView s = w.sub("transformer_blocks." + std::to_string(i));
    auto& b = spatial[size_t(i)];
    b.norm1 = LayerNorm(s, "norm1", c, 1e-5f);
    b.attn1 = Attention(s.sub("attn1"), c, c, h, dh, false);
    b.norm2 = LayerNorm(s, "norm2", c, 1e-5f);
    b.attn2 = Attention(s.sub("attn2"), c, cross_dim, h, dh, false);
    b.norm3 = LayerNorm(s, "norm3", c, 1e-5f);
    b.ff = FeedForward(s.sub("ff"), c);
    if (pifr_text_dim > 0) b.pifr = std::make_unique<Pifr>(s.sub("pifr"), c, h, pifr_text_dim);

    const WeightView t = w.sub("temporal_transformer_blocks." + std::to_string(i));
    auto& tb = temporal[size_t(i)];
    tb.norm_in = LayerNorm(t, "norm_in", c, 1e-5f);
    tb.ff_in = FeedForward(t.sub("ff_in"), c);
    tb.norm1 = LayerNorm(t, "norm1", c, 1e-5f);
    tb.attn1 = Attention(t.sub("attn1"), c, c, h, dh, false);
    tb.norm2 = LayerNorm(t, "norm2", c, 1e-5f);
    tb.attn2 = Attention(t.sub("attn2"), c, cross_dim, h, dh, false);
    tb.norm3 = LayerNorm(t, "norm3", c, 1e-5f);
    tb.ff = FeedForward(t.sub("ff"), c);
  }
}

TransformerConditioning TransformerSpatioTemporal::prepare(const Tensor& ehs, const Tensor* text) const {
  const int64_t B = ehs.dim(0), S = ehs.dim(1);
  TransformerConditioning c;
  for (size_t i = 0; i < spatial.size(); ++i) {
    // spatial context: every frame's ehs = its video's; temporal context: frame 0's ehs of the video (the same)
    c.spatial.push_back(spatial[i].attn2.prepare_context(ehs.data(), B, S));
    c.temporal.push_back(temporal[i].attn2.prepare_context(ehs.data(), B, S));
    if (text && spatial[i].pifr) c.text.push_back(spatial[i].pifr->prepare_text(text->data(), B, text->dim(1)));
  }
  return c;
}

Tensor TransformerSpatioTemporal::forward(const Tensor& x, int64_t videos, const TransformerConditioning& cond,
                                          Arena& arena) const {
  const int64_t N = x.dim(0), C = channels, H = x.dim(2), W = x.dim(3), L = H * W, F = N / videos;
  const int64_t rows = N * L;
  const size_t mark = arena.mark();

  // z = proj_in(Tok(GN(x))): [N, C, L] -> [N, L, C] -> [N*L, C]; one GEMM over every token of every frame
  Tensor g = arena.take({N, C, L});
  norm.forward(x.data(), g.data(), N, 1, L, false);
  Tensor tok = arena.take({rows, C});
  transpose_batched(g.data(), tok.data(), N, C, L);
  Tensor z = arena.take({rows, C});
  proj_in.forward(tok.data(), rows, z.data());

  // pe [F, C] = time_pos_embed(Sin(f, C)), f = frame index
  Tensor frame_idx({F}), sin_f = arena.take({F, C}), pe_h = arena.take({F, 4 * C}), pe = arena.take({F, C});
  for (int64_t f = 0; f < F; ++f) frame_idx[f] = float(f);
  timestep_embedding(frame_idx.data(), F, C, sin_f.data());
  pos_linear_1.forward(sin_f.data(), F, pe_h.data(), Act::SiLU);
  pos_linear_2.forward(pe_h.data(), F, pe.data());

  Tensor nrm = arena.take({rows, C}), zt = arena.take({rows, C});
  const SequenceLayout per_frame{1, N, L, 0, L, 1};                 // spatial: the L tokens of each frame
  const SequenceLayout per_token{videos, L, F, F * L, 1, L};        // temporal: the F frames of each token
  const int64_t rows_per_video = F * L;
  for (size_t i = 0; i < spatial.size(); ++i) {
    const BasicTransformerBlock& b = spatial[i];
    b.norm1.forward(z.data(), nrm.data(), rows);
    b.attn1.self_attention_add(nrm.data(), per_frame, z.data(), arena);
    b.norm2.forward(z.data(), nrm.data(), rows);
    if (b.pifr) {
      const ContextCache* text = cond.text.empty() ? nullptr : &cond.text[i];
      b.pifr->apply(nrm.data(), rows, rows_per_video, b.attn2, cond.spatial[i], text, z.data(), arena);
    } else {
      b.attn2.cross_attention(nrm.data(), rows, rows_per_video, cond.spatial[i], z.data(), true, arena);
    }
    b.norm3.forward(z.data(), nrm.data(), rows);
    b.ff.forward_add(nrm.data(), rows, z.data(), arena);

    // zt = z + pe[f] for every token of frame f
    copy_floats(zt.data(), z.data(), rows * C);
    for (int64_t n = 0; n < N; ++n) add_row_vectors(zt.data() + n * L * C, L, C, pe.data() + (n % F) * C, L);
    const TemporalBasicTransformerBlock& t = temporal[i];
    t.norm_in.forward(zt.data(), nrm.data(), rows);
    t.ff_in.forward_add(nrm.data(), rows, zt.data(), arena);
    t.norm1.forward(zt.data(), nrm.data(), rows);
    t.attn1.self_attention_add(nrm.data(), per_token, zt.data(), arena);
    t.norm2.forward(zt.data(), nrm.data(), rows);
    t.attn2.cross_attention(nrm.data(), rows, rows_per_video, cond.temporal[i], zt.data(), true, arena);
    t.norm3.forward(zt.data(), nrm.data(), rows);
    t.ff.forward_add(nrm.data(), rows, zt.data(), arena);

    // z = α·z + (1−α)·zt
    blend_inplace(zt.data(), z.data(), alpha, rows * C);
    std::swap(z, zt);
  }

  // out = x + Tok⁻¹(proj_out(z)): [N*L, C] -> [N, C, L], added onto the input
  proj_out.forward(z.data(), rows, tok.data());
  Tensor out = x.clone();
  transpose_add_batched(tok.data(), out.data(), N, L, C);
  arena.release(mark);
  return out;
}

}  // namespace egopd
