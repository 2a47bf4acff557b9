#pragma once
// SpatioTemporalResBlock (unet3d.md §5): ResnetBlock2D per frame, TemporalResnetBlock over the frames of each
// video, mixed by a learned AlphaBlender. Activations stay frame-major [B*F, C, H, W] throughout: the temporal
// GroupNorm takes its statistics over the F frames of a video and the (3,1,1) convolution reads neighbouring
// frames directly, so the [B, C, F, H, W] re-layout (R5) is never materialised.
#include "core/layers.h"

namespace egopd {

struct SpatioTemporalResBlock {
  int64_t cin = 0, cout = 0;
  // spatial_res_block (ResnetBlock2D)
  GroupNorm s_norm1, s_norm2;
  Conv2d s_conv1, s_conv2, s_shortcut;
  Linear s_time_proj;
  bool has_shortcut = false;
  // temporal_res_block (TemporalResnetBlock)
  GroupNorm t_norm1, t_norm2;
  TemporalConv3 t_conv1, t_conv2;
  Linear t_time_proj;
  float alpha = 0.5f;  // sigmoid(time_mixer.mix_factor)

  SpatioTemporalResBlock() = default;
  SpatioTemporalResBlock(const WeightView& w, int64_t cin, int64_t cout, int64_t temb_dim, float eps);
  // x [B*F, cin, H, W] -> [B*F, cout, H, W]; temb_silu [B*F, temb_dim] = SiLU(temb)
  Tensor forward(const Tensor& x, int64_t videos, const float* temb_silu, Arena& arena) const;
};

float sigmoid_of_mix_factor(const WeightView& w);  // reads `mix_factor` [1]

}  // namespace egopd
