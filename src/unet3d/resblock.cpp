#include "unet3d/resblock.h"

#include <cmath>

#include "core/kernels/channel_ops.h"
#include "core/kernels/elementwise.h"

namespace egopd {

float sigmoid_of_mix_factor(const WeightView& w) {
  const float m = w.get_f32("mix_factor", {1})[0];
  return float(1.0 / (1.0 + std::exp(-double(m))));
}

SpatioTemporalResBlock::SpatioTemporalResBlock(const WeightView& w, int64_t cin_, int64_t cout_, int64_t temb_dim,
                                               float eps)
    : cin(cin_), cout(cout_) {
  const WeightView s = w.sub("spatial_res_block");
  s_norm1 = GroupNorm(s, "norm1", cin, 32, eps);
  s_conv1 = Conv2d(s, "conv1", cin, cout, 3, 1, 1);
  s_time_proj = Linear(s, "time_emb_proj", temb_dim, cout);
  s_norm2 = GroupNorm(s, "norm2", cout, 32, eps);
  s_conv2 = Conv2d(s, "conv2", cout, cout, 3, 1, 1);
  has_shortcut = cin != cout;
  if (has_shortcut) s_shortcut = Conv2d(s, "conv_shortcut", cin, cout, 1, 1, 0);
  const WeightView t = w.sub("temporal_res_block");
  t_norm1 = GroupNorm(t, "norm1", cout, 32, eps);
  t_conv1 = TemporalConv3(t, "conv1", cout, cout);
  t_time_proj = Linear(t, "time_emb_proj", temb_dim, cout);
  t_norm2 = GroupNorm(t, "norm2", cout, 32, eps);
  t_conv2 = TemporalConv3(t, "conv2", cout, cout);
  alpha = sigmoid_of_mix_factor(w.sub("time_mixer"));
}

Tensor SpatioTemporalResBlock::forward(const Tensor& x, int64_t videos, const float* temb_silu, Arena& arena) const {
  const int64_t N = x.dim(0), H = x.dim(2), W = x.dim(3), S = H * W, F = N / videos;
  const size_t mark = arena.mark();
  Tensor te = arena.take({N, cout});

  // ResnetBlock2D: sp = shortcut(x) + conv2(SiLU(GN(conv1(SiLU(GN(x))) + time_proj)))
  Tensor a = arena.take({N, cin, H, W});
  s_norm1.forward(x.data(), a.data(), N, 1, S, /*silu=*/true);
  Tensor h = arena.take({N, cout, H, W});
  s_conv1.forward(a.data(), N, H, W, h.data());
  s_time_proj.forward(temb_silu, N, te.data());
  add_frame_channel_bias(h.data(), N, cout, S, te.data());
  s_norm2.forward(h.data(), h.data(), N, 1, S, true);
  Tensor sp = arena.take({N, cout, H, W});
  if (has_shortcut) {
    s_shortcut.forward(x.data(), N, H, W, sp.data());
  } else {
    copy_floats(sp.data(), x.data(), sp.numel());
  }
  s_conv2.forward(h.data(), N, H, W, sp.data(), Act::None, /*accumulate=*/true);

  // TemporalResnetBlock on the video volume: u = sp + conv2(SiLU(GN(conv1(SiLU(GN(sp))) + te)))
  Tensor g = arena.take({N, cout, H, W});
  t_norm1.forward(sp.data(), g.data(), videos, F, S, true);
  t_conv1.forward(g.data(), videos, F, S, h.data());
  t_time_proj.forward(temb_silu, N, te.data());
  add_frame_channel_bias(h.data(), N, cout, S, te.data());
  t_norm2.forward(h.data(), h.data(), videos, F, S, true);
  Tensor u = sp.clone();
  t_conv2.forward(h.data(), videos, F, S, u.data(), Act::None, true);

  // AlphaBlender: out = α·spatial + (1−α)·temporal
  blend_inplace(u.data(), sp.data(), alpha, u.numel());
  arena.release(mark);
  return u;
}

}  // namespace egopd
