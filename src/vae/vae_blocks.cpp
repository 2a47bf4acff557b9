#include "vae/vae_blocks.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "core/error.h"
#include "core/kernels/attention.h"
#include "core/kernels/elementwise.h"
#include "core/kernels/layout.h"
#include "core/memory.h"
#include "core/threading.h"
#include "vae/vae_config.h"

namespace egopd {

// ---------------------------------------------------------------- ResnetBlock2D

ResnetBlock2D::ResnetBlock2D(const WeightView& w, int64_t cin_, int64_t cout_, float eps)
    : cin(cin_),
      cout(cout_),
      norm1(w, "norm1", cin_, VaeConfig::kGroups, eps),
      norm2(w, "norm2", cout_, VaeConfig::kGroups, eps),
      conv1(w, "conv1", cin_, cout_, 3, 1, 1),
      conv2(w, "conv2", cout_, cout_, 3, 1, 1),
      has_shortcut(cin_ != cout_) {
  if (has_shortcut) conv_shortcut = Conv2d(w, "conv_shortcut", cin, cout, 1, 1, 0);
}

void ResnetBlock2D::forward_frame(const float* x, float* out, int64_t H, int64_t W, float* scratch) const {
  EGOPD_CHECK(!has_shortcut || out != x, "a res-block that changes width cannot run in place");
  run_frame(x, scratch, out, H, W, scratch + cin * H * W);
}

void ResnetBlock2D::forward_frame_consuming(float* x, float* out, int64_t H, int64_t W, float* scratch) const {
  EGOPD_CHECK(out != x, "a consuming res-block call cannot run in place");
  run_frame(x, x, out, H, W, scratch);
}

// out = shortcut(x) + conv2(SiLU(GN2(conv1(n1)))), n1 = SiLU(GN1(x)). n1 == x normalises x in place, so the shortcut
// is taken first; out == x (in place, no shortcut) keeps x as the residual. The sums are the same either way.
void ResnetBlock2D::run_frame(const float* x, float* n1, float* out, int64_t H, int64_t W, float* h) const {
  const int64_t hw = H * W;
  const auto shortcut = [&] {
    if (has_shortcut) conv_shortcut.forward(x, 1, H, W, out);
    else if (out != x) copy_floats(out, x, cout * hw);
  };
  const bool in_place_norm = n1 == x;
  if (in_place_norm) shortcut();
  norm1.forward(x, n1, 1, 1, hw, /*silu=*/true);
  conv1.forward(n1, 1, H, W, h);                  // h [cout, H, W]
  norm2.forward(h, h, 1, 1, hw, /*silu=*/true);
  if (!in_place_norm) shortcut();
  conv2.forward(h, 1, H, W, out, Act::None, /*accumulate=*/true);
}

// ---------------------------------------------------------------- MidBlockAttention

MidBlockAttention::MidBlockAttention(const WeightView& w, int64_t c_)
    : c(c_),
      group_norm(w, "group_norm", c_, VaeConfig::kGroups, 1e-6f),
      to_q(w, "to_q", c_, c_),
      to_k(w, "to_k", c_, c_),
      to_v(w, "to_v", c_, c_),
      to_out(w, "to_out.0", c_, c_) {}

void MidBlockAttention::forward_frame(float* x, int64_t hw, float* scratch) const {
  float* n = scratch;          // [c, L]
  float* tok = n + c * hw;     // [L, c]
  float* q = tok + c * hw;     // [L, c]
  float* k = q + c * hw;       // [L, c]
  float* v = k + c * hw;       // [L, c]
  float* a = v + c * hw;       // [L, c]
  group_norm.forward(x, n, 1, 1, hw, /*silu=*/false);
  transpose_batched(n, tok, 1, c, hw);  // [c, L] -> [L, c]
  to_q.forward(tok, hw, q);
  to_k.forward(tok, hw, k);
  to_v.forward(tok, hw, v);
  AttentionArgs args;
  args.batch = 1;
  args.heads = 1;
  args.lq = args.lk = hw;
  args.dh = c;
  args.q = q;
  args.k = k;
  args.v = v;
  args.out = a;
  args.q_ld = args.k_ld = args.v_ld = args.out_ld = c;
  args.scale = float(1.0 / std::sqrt(double(c)));
  attention(args);
  to_out.forward(a, hw, tok);           // o [L, c]
  transpose_batched(tok, n, 1, hw, c);  // [L, c] -> [c, L]
  add_inplace(x, n, c * hw);            // residual
}

// ---------------------------------------------------------------- EncoderDownsample / Upsample2x

EncoderDownsample::EncoderDownsample(const WeightView& w, int64_t c_) : c(c_), conv(w, "conv", c_, c_, 3, 2, 0) {}

void EncoderDownsample::forward_frame(const float* x, int64_t H, int64_t W, float* y, float* scratch) const {
  const int64_t pw = W + 1;
  float* padded = scratch;  // [c, H+1, W+1]: x with a zero column on the right and a zero row at the bottom
#pragma omp parallel for schedule(static) if (parallel_worth(c * H * W))
  for (int64_t ch = 0; ch < c; ++ch) {
    float* dst = padded + ch * (H + 1) * pw;
    const float* src = x + ch * H * W;
    for (int64_t r = 0; r < H; ++r) {
      std::memcpy(dst + r * pw, src + r * W, size_t(W) * sizeof(float));
      dst[r * pw + W] = 0.0f;
    }
    std::fill(dst + H * pw, dst + (H + 1) * pw, 0.0f);
  }
  conv.forward(padded, 1, H + 1, W + 1, y);
}

Upsample2x::Upsample2x(const WeightView& w, int64_t c_) : c(c_), conv(w, "conv", c_, c_, 3, 1, 1) {}

void Upsample2x::forward_frame(const float* x, int64_t H, int64_t W, float* y, float* scratch) const {
  upsample_nearest2x(x, c, H, W, scratch);  // [c, H, W] -> [c, 2H, 2W]
  conv.forward(scratch, 1, 2 * H, 2 * W, y);
}

// ---------------------------------------------------------------- TemporalResnetBlock

namespace {

// Per-channel scale and shift of GroupNorm group g from its statistics: y = x·scale[ch] + shift[ch].
void group_affine(const GroupNorm& gn, int64_t g, double mean, double var, float* scale, float* shift) {
  const int64_t cg = gn.c / gn.groups;
  const float mean_f = float(mean);
  const float rstd = float(1.0 / std::sqrt(var + double(gn.eps)));
  for (int64_t ci = 0; ci < cg; ++ci) {
    const int64_t ch = g * cg + ci;
    scale[ch] = rstd * gn.gamma[ch];
    shift[ch] = gn.beta[ch] - mean_f * scale[ch];
  }
}

// Scale and shift of a 5-D GroupNorm of one video [F, c, hw]: statistics of each group over all frames, mean then
// biased variance, both in double (two passes), exactly the kernel's recipe.
void video_group_norm_affine(const float* x, int64_t frames, int64_t hw, const GroupNorm& gn, float* scale,
                             float* shift) {
  const int64_t c = gn.c, cg = c / gn.groups;
  const double count = double(frames * cg * hw);
#pragma omp parallel for schedule(dynamic, 1) if (parallel_worth(frames * c * hw))
  for (int64_t g = 0; g < gn.groups; ++g) {
    double part[4] = {0, 0, 0, 0};  // independent partial sums keep the adder pipeline busy
    for (int64_t f = 0; f < frames; ++f) {
      const float* p = x + (f * c + g * cg) * hw;
      const int64_t n = cg * hw;
      int64_t i = 0;
      for (; i + 4 <= n; i += 4)
        for (int u = 0; u < 4; ++u) part[u] += p[i + u];
      for (; i < n; ++i) part[0] += p[i];
    }
    const double mean = (part[0] + part[1]) + (part[2] + part[3]);
    const double mu = mean / count;
    double sq[4] = {0, 0, 0, 0};
    for (int64_t f = 0; f < frames; ++f) {
      const float* p = x + (f * c + g * cg) * hw;
      const int64_t n = cg * hw;
      int64_t i = 0;
      for (; i + 4 <= n; i += 4)
        for (int u = 0; u < 4; ++u) {
          const double d = p[i + u] - mu;
          sq[u] += d * d;
        }
      for (; i < n; ++i) sq[0] += (p[i] - mu) * (p[i] - mu);
    }
    group_affine(gn, g, mu, ((sq[0] + sq[1]) + (sq[2] + sq[3])) / count, scale, shift);
  }
}

// Running per-group sums (Σx, Σx²) in double over the tiles of a video, for a GroupNorm whose input is never stored
// whole. One pass instead of two: in double the cancellation of Σx²/n − mean² costs nothing at float precision
// unless |mean| exceeds the standard deviation by ~10⁶, far beyond anything a trained decoder produces.
struct GroupMoments {
  std::vector<double> sum, sumsq;
  explicit GroupMoments(int64_t groups) : sum(size_t(groups), 0.0), sumsq(size_t(groups), 0.0) {}

  // tile [F, c, tn]
  void add(const float* tile, int64_t frames, int64_t c, int64_t tn) {
    const int64_t groups = int64_t(sum.size()), cg = c / groups;
#pragma omp parallel for schedule(dynamic, 1) if (parallel_worth(frames * c * tn))
    for (int64_t g = 0; g < groups; ++g) {
      double s[4] = {0, 0, 0, 0}, q[4] = {0, 0, 0, 0};
      for (int64_t f = 0; f < frames; ++f) {
        const float* p = tile + (f * c + g * cg) * tn;
        const int64_t n = cg * tn;
        int64_t i = 0;
        for (; i + 4 <= n; i += 4)
          for (int u = 0; u < 4; ++u) {
            const double v = p[i + u];
            s[u] += v;
            q[u] += v * v;
          }
        for (; i < n; ++i) s[0] += p[i], q[0] += double(p[i]) * p[i];
      }
      sum[size_t(g)] += (s[0] + s[1]) + (s[2] + s[3]);
      sumsq[size_t(g)] += (q[0] + q[1]) + (q[2] + q[3]);
    }
  }

  void affine(const GroupNorm& gn, double count_per_group, float* scale, float* shift) const {
    for (int64_t g = 0; g < gn.groups; ++g) {
      const double mean = sum[size_t(g)] / count_per_group;
      const double var = std::max(0.0, sumsq[size_t(g)] / count_per_group - mean * mean);
      group_affine(gn, g, mean, var, scale, shift);
    }
  }
};

// tile [F, c, tn] = SiLU(src[:, :, t0:t0+tn] · scale + shift) of a video src [F, c, hw].
void gather_norm_silu(const float* src, int64_t frames, int64_t c, int64_t hw, int64_t t0, int64_t tn,
                      const float* scale, const float* shift, float* tile) {
#pragma omp parallel for schedule(static) if (parallel_worth(frames * c * tn))
  for (int64_t r = 0; r < frames * c; ++r) {
    const int64_t ch = r % c;
    const float* s = src + r * hw + t0;
    float* d = tile + r * tn;
    for (int64_t i = 0; i < tn; ++i) d[i] = s[i] * scale[ch] + shift[ch];
  }
  silu_inplace(tile, frames * c * tn);
}

// AlphaBlender with the temporal branch u = s + g: s <- ws·s + wt·u on dst[:, :, t0:t0+tn], g = tile [rows, tn].
void blend_tile(const float* g, int64_t rows, int64_t hw, int64_t t0, int64_t tn, float ws, float wt, float* dst) {
#pragma omp parallel for schedule(static) if (parallel_worth(rows * tn))
  for (int64_t r = 0; r < rows; ++r) {
    float* s = dst + r * hw + t0;
    const float* gr = g + r * tn;
    for (int64_t i = 0; i < tn; ++i) {
      const float u = s[i] + gr[i];
      s[i] = ws * s[i] + wt * u;
    }
  }
}

struct TemporalBuffer {
  AlignedScratch storage;
  size_t used = 0;  // floats handed out since the last release
};
thread_local TemporalBuffer tl_temporal_buffer;

}  // namespace

void release_temporal_buffer() {
  TemporalBuffer& b = tl_temporal_buffer;
  if (b.used) discard_pages(b.storage.get(b.used), b.used * sizeof(float));
  b.used = 0;
}

TemporalResnetBlock::TemporalResnetBlock(const WeightView& w, int64_t c_, float eps)
    : c(c_),
      norm1(w, "norm1", c_, VaeConfig::kGroups, eps),
      norm2(w, "norm2", c_, VaeConfig::kGroups, eps),
      conv1(w, "conv1", c_, c_),
      conv2(w, "conv2", c_, c_) {}

void TemporalResnetBlock::forward_blend(float* video, int64_t frames, int64_t hw, float spatial_weight,
                                        const TemporalMemory& mem) const {
  const int64_t rows = frames * c;
  const int64_t tile = std::clamp<int64_t>(mem.tile_floats / rows, 1, hw);
  const size_t nc = static_cast<size_t>(c);
  std::vector<float> scale1(nc), shift1(nc), scale2(nc), shift2(nc);
  Tensor a(Shape{rows * tile}), b(Shape{rows * tile});

  video_group_norm_affine(video, frames, hw, norm1, scale1.data(), shift1.data());
  // dst [F, c, tn] (rows dst_stride apart) = conv1(SiLU(GN1(video[:, :, t0:t0+tn]))); the temporal conv mixes
  // frames, never pixels
  const auto conv1_tile = [&](int64_t t0, int64_t tn, float* dst, int64_t dst_stride) {
    gather_norm_silu(video, frames, c, hw, t0, tn, scale1.data(), shift1.data(), a.data());
    conv1.forward(a.data(), 1, frames, tn, dst, Act::None, false, dst_stride);
  };

  Tensor g1;  // conv1 output of the whole video [F, c, hw], unless it is recomputed
  if (!mem.recompute_conv1) {
    TemporalBuffer& buf = tl_temporal_buffer;
    buf.used = std::max(buf.used, size_t(rows * hw));
    g1 = Tensor::view(Shape{frames, c, hw}, buf.storage.get(size_t(rows * hw)));
    for (int64_t t0 = 0; t0 < hw; t0 += tile) {
      const int64_t tn = std::min(tile, hw - t0);
      conv1_tile(t0, tn, g1.data() + t0, hw);  // straight into its columns of g1
    }
    video_group_norm_affine(g1.data(), frames, hw, norm2, scale2.data(), shift2.data());
  } else {
    GroupMoments moments(norm2.groups);
    for (int64_t t0 = 0; t0 < hw; t0 += tile) {
      const int64_t tn = std::min(tile, hw - t0);
      conv1_tile(t0, tn, b.data(), tn);
      moments.add(b.data(), frames, c, tn);
    }
    moments.affine(norm2, double(frames * (c / norm2.groups) * hw), scale2.data(), shift2.data());
  }

  const float temporal_weight = 1.0f - spatial_weight;
  for (int64_t t0 = 0; t0 < hw; t0 += tile) {
    const int64_t tn = std::min(tile, hw - t0);
    if (mem.recompute_conv1) {  // video[:, :, t0:t0+tn] is still unblended: conv1 sees the same input again
      conv1_tile(t0, tn, b.data(), tn);
      gather_norm_silu(b.data(), frames, c, tn, 0, tn, scale2.data(), shift2.data(), a.data());
    } else {
      gather_norm_silu(g1.data(), frames, c, hw, t0, tn, scale2.data(), shift2.data(), a.data());
    }
    conv2.forward(a.data(), 1, frames, tn, b.data());  // g [F, c, tn]
    blend_tile(b.data(), rows, hw, t0, tn, spatial_weight, temporal_weight, video);
  }
}

// ---------------------------------------------------------------- VaeSpatioTemporalResBlock

VaeSpatioTemporalResBlock::VaeSpatioTemporalResBlock(const WeightView& w, int64_t cin, int64_t cout)
    : spatial(w.sub("spatial_res_block"), cin, cout, 1e-6f), temporal(w.sub("temporal_res_block"), cout, 1e-5f) {
  const float m = w.get_f32("time_mixer.mix_factor", {1})[0];
  const float alpha = 1.0f / (1.0f + std::exp(-m));  // torch.sigmoid
  spatial_weight = 1.0f - alpha;                     // switch_spatial_to_temporal_mix: alpha <- 1 - alpha
}

Tensor VaeSpatioTemporalResBlock::forward(Tensor x, int64_t batch, int64_t frames, int64_t H, int64_t W,
                                          const Upsample2x* pre, const TemporalMemory& mem) const {
  const int64_t n = batch * frames, hw = H * W, ci = cin(), co = cout();
  const int64_t hin = pre ? H / 2 : H, win = pre ? W / 2 : W;
  EGOPD_CHECK(x.numel() == n * ci * hin * win, "res-block input " + x.shape().str() + " vs " + std::to_string(n) +
                                                   " frames of [" + std::to_string(ci) + "," + std::to_string(hin) +
                                                   "," + std::to_string(win) + "]");
  EGOPD_CHECK(!pre || (pre->c == ci && H == 2 * hin && W == 2 * win), "upsampler does not fit the res-block");
  Tensor out = (!pre && ci == co) ? x : Tensor(Shape{n, co, H, W});
  // A separate output fills up while the input is consumed: give each input frame's pages back once it is read, so
  // the two together never hold much more than the larger one.
  const bool discard_input = out.data() != x.data() && x.sole_owner();
  {
    // Spatial half, frame by frame. With pre: [upsampled frame] [nearest-upsampled frame, then the res-block's
    // hidden state]; the upsampled frame is the block's own copy, so the res-block normalises it in place.
    const int64_t up = pre ? ci * hw : 0, in_frame = ci * hin * win;
    Tensor scratch(Shape{pre ? up + std::max(pre->scratch_floats(hin, win), spatial.consuming_scratch_floats(hw))
                             : spatial.scratch_floats(hw)});
    for (int64_t f = 0; f < n; ++f) {
      const float* xf = x.data() + f * in_frame;
      float* of = out.data() + f * co * hw;
      if (pre) {
        pre->forward_frame(xf, hin, win, scratch.data(), scratch.data() + up);
        spatial.forward_frame_consuming(scratch.data(), of, H, W, scratch.data() + up);
      } else {
        spatial.forward_frame(xf, of, H, W, scratch.data());
      }
      if (discard_input) discard_pages(x.data() + f * in_frame, size_t(in_frame) * sizeof(float));
    }
  }
  x = Tensor();  // the input's memory goes before the temporal half allocates its buffers
  // Temporal half per video: R5 of frame-major rows is the same memory viewed as [F, C, H·W] per video.
  for (int64_t b = 0; b < batch; ++b)
    temporal.forward_blend(out.data() + b * frames * co * hw, frames, hw, spatial_weight, mem);
  return out.reshaped(Shape{n, co, H, W});
}

}  // namespace egopd
