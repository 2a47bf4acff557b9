// FLOP count of one U-Net evaluation from its configuration (multiply-add = 2 FLOPs; norms and element-wise
// work are not counted). `total` counts the stock cross-attentions as PyTorch runs them (per query and frame);
// `executed` drops them, since with one context token they reduce to a once-per-run vector.
#include "unet3d/unet.h"

namespace egopd {
namespace {

struct Counter {
  double total = 0, executed = 0;
  void both(double f) {
    total += f;
    executed += f;
  }
};

void count_resblock(Counter& c, const SpatioTemporalResBlock& r, double N, double S, double ted) {
  c.both(2 * N * S * r.cout * r.cin * 9 + 2 * N * S * r.cout * r.cout * 9);  // conv1, conv2
  if (r.has_shortcut) c.both(2 * N * S * r.cout * r.cin);
  c.both(2 * 2 * N * S * r.cout * r.cout * 3);  // temporal conv1, conv2 (zero-padded frames counted)
  c.both(2 * 2 * N * ted * r.cout);              // time projections
}

void count_transformer(Counter& c, const TransformerSpatioTemporal& t, double B, double F, double L, double ctx,
                       double text) {
  const double N = B * F, C = double(t.channels), rows = N * L;
  c.both(2 * 2 * rows * C * C);                        // proj_in, proj_out
  c.both(2 * N * (C * 4 * C + 4 * C * C));             // time_pos_embed
  const double ff = 2 * rows * C * 8 * C + 2 * rows * 4 * C * C;
  for (size_t i = 0; i < t.spatial.size(); ++i) {
    const double cross = double(t.spatial[i].attn2.context_dim);
    const double self = 4 * 2 * rows * C * C + 4 * N * L * L * C;  // q,k,v,out + scores and P·V
    c.both(self);
    // spatial cross-attention (to_k/to_v per frame as PyTorch runs it)
    const double stock_cross = 2 * 2 * rows * C * C + 2 * 2 * N * ctx * cross * C + 4 * rows * ctx * C;
    c.total += stock_cross;
    if (ctx > 1) c.executed += stock_cross;
    if (t.spatial[i].pifr && text > 0) {
      const double pifr = 2 * 2 * rows * C * C + 4 * rows * text * C + 2 * rows * C * 2 * C;
      c.total += pifr + 2 * 2 * N * text * double(t.spatial[i].pifr->attn_text.context_dim) * C;
      c.executed += pifr;
    }
    c.both(ff);
    // temporal block: ff_in, self-attention over F frames of B·L sequences, cross-attention, ff
    c.both(ff + 4 * 2 * rows * C * C + 4 * B * L * F * F * C + ff);
    const double t_cross = 2 * 2 * rows * C * C + 2 * 2 * B * L * ctx * cross * C + 4 * rows * ctx * C;
    c.total += t_cross;
    if (ctx > 1) c.executed += t_cross;
  }
}

}  // namespace

UNetSpatioTemporal::Flops UNetSpatioTemporal::flops(int64_t videos, int64_t frames, int64_t h, int64_t w,
                                                    int64_t context_tokens, int64_t text_tokens) const {
  Counter c;
  const double B = double(videos), F = double(frames), N = B * F, ted = double(cfg_.time_embed_dim());
  const double ctx = double(context_tokens), text = double(text_tokens);
  const auto& ch = cfg_.block_out_channels;
  double H = double(h), W = double(w);
  c.both(2 * N * H * W * ch[0] * cfg_.in_channels * 9);
  for (const auto& d : down_) {
    for (size_t j = 0; j < d.resnets.size(); ++j) {
      count_resblock(c, d.resnets[j], N, H * W, ted);
      if (!d.attentions.empty()) count_transformer(c, d.attentions[j], B, F, H * W, ctx, text);
    }
    if (d.has_downsampler) {
      H /= 2, W /= 2;
      c.both(2 * N * H * W * double(d.downsampler.geom.cout) * double(d.downsampler.geom.cin) * 9);
    }
  }
  count_resblock(c, mid_res0_, N, H * W, ted);
  count_transformer(c, mid_attn_, B, F, H * W, ctx, text);
  count_resblock(c, mid_res1_, N, H * W, ted);
  for (const auto& u : up_) {
    for (size_t j = 0; j < u.resnets.size(); ++j) {
      count_resblock(c, u.resnets[j], N, H * W, ted);
      if (!u.attentions.empty()) count_transformer(c, u.attentions[j], B, F, H * W, ctx, text);
    }
    if (u.has_upsampler) {
      H *= 2, W *= 2;
      c.both(2 * N * H * W * double(u.upsampler.geom.cout) * double(u.upsampler.geom.cin) * 9);
    }
  }
  c.both(2 * N * double(h) * double(w) * double(cfg_.out_channels) * ch[0] * 9);
  return {c.total, c.executed};
}

}  // namespace egopd
