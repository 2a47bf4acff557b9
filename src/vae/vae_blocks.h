#pragma once
// Building blocks of the temporal VAE (vae.md §3–4). Spatial work runs one frame at a time with per-block scratch,
// so no whole-clip temporary (nor a whole-clip upsampled input) is ever materialised; the temporal half of a
// decoder res-block works in place on the clip, tiled over pixels (its GroupNorm statistics span the whole video).
#include <cstdint>

#include "core/layers.h"
#include "core/tensor.h"
#include "core/weights.h"

namespace egopd {

// ResnetBlock2D without time embedding (unet3d.md §5.1 minus the temb term), GroupNorm(32, eps), SiLU.
struct ResnetBlock2D {
  int64_t cin = 0, cout = 0;
  GroupNorm norm1, norm2;
  Conv2d conv1, conv2;
  Conv2d conv_shortcut;  // 1x1, only when cin != cout
  bool has_shortcut = false;

  ResnetBlock2D(const WeightView& w, int64_t cin, int64_t cout, float eps);
  // One frame: x [cin, H, W] -> out [cout, H, W]; out may alias x when cin == cout.
  void forward_frame(const float* x, float* out, int64_t H, int64_t W, float* scratch) const;
  int64_t scratch_floats(int64_t hw) const { return (cin + cout) * hw; }
  // The same result when x is the caller's own copy: x is normalised in place (x is garbage afterwards), so the
  // scratch holds only the [cout, H, W] hidden state. out must not alias x.
  void forward_frame_consuming(float* x, float* out, int64_t H, int64_t W, float* scratch) const;
  int64_t consuming_scratch_floats(int64_t hw) const { return cout * hw; }

 private:
  void run_frame(const float* x, float* n1, float* out, int64_t H, int64_t W, float* h) const;
};

// Mid-block attention (diffusers Attention with group norm, biases, one head of width c, residual).
struct MidBlockAttention {
  int64_t c = 0;
  GroupNorm group_norm;
  Linear to_q, to_k, to_v, to_out;

  MidBlockAttention(const WeightView& w, int64_t c);
  // One frame in place: x [c, H*W] <- Tok⁻¹(to_out(softmax(q kᵀ / sqrt(c)) v)) + x, q/k/v from Tok(GN(x)).
  void forward_frame(float* x, int64_t hw, float* scratch) const;
  int64_t scratch_floats(int64_t hw) const { return 6 * c * hw; }
};

// Encoder downsampler: one zero column on the right and one zero row at the bottom, then conv 3x3 stride 2 pad 0.
struct EncoderDownsample {
  int64_t c = 0;
  Conv2d conv;

  EncoderDownsample(const WeightView& w, int64_t c);
  static int64_t out_size(int64_t n) { return (n + 1 - 3) / 2 + 1; }
  // One frame: x [c, H, W] -> y [c, out_size(H), out_size(W)].
  void forward_frame(const float* x, int64_t H, int64_t W, float* y, float* scratch) const;
  int64_t scratch_floats(int64_t H, int64_t W) const { return c * (H + 1) * (W + 1); }
};

// Decoder upsampler: nearest x2, then conv 3x3 pad 1.
struct Upsample2x {
  int64_t c = 0;
  Conv2d conv;

  Upsample2x(const WeightView& w, int64_t c);
  // One frame: x [c, H, W] -> y [c, 2H, 2W].
  void forward_frame(const float* x, int64_t H, int64_t W, float* y, float* scratch) const;
  int64_t scratch_floats(int64_t H, int64_t W) const { return c * 4 * H * W; }
};

constexpr int64_t kDefaultTileFloats = int64_t(1) << 22;

// How the decoder's temporal halves trade memory for time. Neither setting changes the result beyond float rounding.
struct TemporalMemory {
  int64_t tile_floats = kDefaultTileFloats;  // pixel tiles of at most tile_floats / (F·c) positions
  // false: one whole-video buffer holds conv1's output (GroupNorm 2 needs statistics over all of it);
  // true: no such buffer: conv1 runs twice, once for GroupNorm 2's statistics and once for the output (low memory).
  bool recompute_conv1 = false;
};

// TemporalResnetBlock on one video [F, c, HW] (frame-major, i.e. R5 without moving data): 5-D GroupNorm(32, eps)
// statistics over all F frames, Conv3d (3,1,1) zero-padded in time, no shortcut.
struct TemporalResnetBlock {
  int64_t c = 0;
  GroupNorm norm1, norm2;
  TemporalConv3 conv1, conv2;

  TemporalResnetBlock(const WeightView& w, int64_t c, float eps);
  // In place: video <- w_s·video + (1 − w_s)·(video + g), g = conv2(SiLU(GN2(conv1(SiLU(GN1(video)))))), worked on
  // pixel tiles as `mem` says.
  void forward_blend(float* video, int64_t frames, int64_t hw, float spatial_weight, const TemporalMemory& mem) const;
};

// The whole-video conv1 output of the temporal blocks (TemporalMemory::recompute_conv1 false) lives in one grow-only
// buffer of the calling thread, kept across blocks and decodes: allocated per block, its pages were faulted in and
// zeroed anew every time (2.8 GB per 16 x 256x256 decode: 1 s of system time, 3-7% of the decode). The decoder
// gives the pages back when it moves to a larger resolution level and when it returns (the allocation, not its
// resident pages, stays with the thread).
void release_temporal_buffer();

// Decoder VaeSpatioTemporalResBlock: spatial ResnetBlock2D (eps 1e-6) per frame, TemporalResnetBlock (eps 1e-5) per
// video, AlphaBlender `learned` with switch_spatial_to_temporal_mix: out = (1 − σ(m))·spatial + σ(m)·temporal.
struct VaeSpatioTemporalResBlock {
  ResnetBlock2D spatial;
  TemporalResnetBlock temporal;
  float spatial_weight = 0;  // 1 − sigmoid(time_mixer.mix_factor), evaluated as diffusers does in float32

  VaeSpatioTemporalResBlock(const WeightView& w, int64_t cin, int64_t cout);
  int64_t cin() const { return spatial.cin; }
  int64_t cout() const { return spatial.cout; }
  // x [batch·frames, cin, H, W] -> [batch·frames, cout, H, W]; with `pre`, x is [batch·frames, cin, H/2, W/2] and each
  // frame is first upsampled by it (the upsampled clip is never stored). Reuses x's storage when it can; pass the
  // last reference to x (std::move): its memory is then given back frame by frame as the spatial half consumes it,
  // and before the temporal half runs.
  Tensor forward(Tensor x, int64_t batch, int64_t frames, int64_t H, int64_t W, const Upsample2x* pre = nullptr,
                 const TemporalMemory& mem = {}) const;
};

}  // namespace egopd
