// The temporal convolution (kernel (3,1,1)): either one implicit GEMM over the three taps (direct), or Winograd
// F(m,3) along time (m output frames from m + 2 input frames with m + 2 products of transformed filters instead of
// 3m: F(2,3) 2/3 of the GEMM work, F(4,3) 1/2), chosen like conv2d's algorithm (conv.h: ConvAlgo).
//
// Lavin & Gray, per tile q of m output frames (outputs mq .. mq + m - 1; inputs d_k = x[mq - 1 + k], zero outside
// the video); the input transform V = Bᵀd is temporal_wino_pack.h's, per channel;
//   F(2,3): U = (w0, (w0 + w1 + w2)/2, (w0 - w1 + w2)/2, w2)                       (filter transform, per (o, c))
//           y = (M0 + M1 + M2, M1 - M2 - M3)                                       (output transform)
//   F(4,3): U = (w0/4, -(w0 + w1 + w2)/6, -(w0 - w1 + w2)/6, (w0 + 2w1 + 4w2)/24, (w0 - 2w1 + 4w2)/24, w2)
//           y = (M0 + (M1 + M2) + (M3 + M4), (M1 - M2) + 2(M3 - M4), (M1 + M2) + 4(M3 + M4),
//                (M1 - M2) + 8(M3 - M4) + M5)
//   M_i = U_i · V_i                                                   (m + 2 products [cout, cin] x [cin, px])
// V exists only as the micro-kernel's B panels, M only as its tiles. Under Precision::Bf16: F(2,3) only, with U and V
// rounded to bfloat16 as the products' operands (the transforms themselves in float32). Under Precision::Int8:
// F(2,3) only, U and V quantised as the int8 GEMM quantises its packed panels (gemm.h), U_i per output channel and
// V_i per pixel, in int8_group(cin) groups of channels: the transformed values are the products' operands, as the
// stored weights and frames are the direct convolution's.
#include <omp.h>

#include <algorithm>
#include <string>

#include "core/error.h"
#include "core/kernels/conv.h"
#include "core/kernels/conv_internal.h"
#include "core/kernels/gemm_internal.h"
#include "core/kernels/kernel_profile.h"
#include "core/kernels/winograd_internal.h"
#include "core/memory.h"
#include "core/threading.h"

namespace egopd {

namespace {

// w(o, c, k) of the stored [cout, cin, 3] weight as float32.
float weight_at(const Operand& w, int64_t cin, int64_t o, int64_t c, int k) {
  const size_t i = size_t((o * cin + c) * 3 + k);
  switch (w.dtype) {
    case DType::F32: return static_cast<const float*>(w.data)[i];
    case DType::F16: return half_to_float(static_cast<const uint16_t*>(w.data)[i]);
    case DType::BF16: return bf16_to_float(static_cast<const uint16_t*>(w.data)[i]);
    default: return float(static_cast<const int8_t*>(w.data)[i]) * w.scale[o];
  }
}

// Temporal conv weight [cout, cin, 3] seen as A [cout, ntaps*cin] with column kk = (tap - tap0)*cin + c.
struct TemporalA : gemm_detail::ASource {
  Operand wt;
  int64_t cin, tap0;
  TemporalA(const Operand& w, int64_t cin_, int64_t tap0_) : wt(w), cin(cin_), tap0(tap0_) {}
  void pack(const gemm_detail::GemmPath& path, int64_t m0, int mr, int64_t k0, int64_t kc,
            float* dst) const override {
    const int MR = path.mr;
    const bool fast = mr == MR && wt.dtype != DType::I8 && path.pack_a_temporal;
    for (int64_t k = k0; k < k0 + kc;) {  // one run per tap
      const int64_t tap = tap0 + k / cin, c = k % cin, run = std::min(k0 + kc, (k / cin + 1) * cin) - k;
      float* d = dst + (k - k0) * MR;
      const int64_t done = fast ? path.pack_a_temporal(wt.data, wt.dtype, cin, m0, tap, c, run, d) : 0;
      pack_scalar(MR, m0, mr, tap, c + done, run - done, d + done * MR);
      k += run;
    }
  }

  // dst[k*MR + i] = W[m0 + i, c0 + k, tap] for k < len (rows >= mr zero).
  void pack_scalar(int MR, int64_t m0, int mr, int64_t tap, int64_t c0, int64_t len, float* dst) const {
    for (int i = 0; i < MR; ++i)
      for (int64_t k = 0; k < len; ++k) dst[k * MR + i] = i < mr ? weight_at(wt, cin, m0 + i, c0 + k, int(tap)) : 0.0f;
  }
};

// Frames t-1, t, t+1 of one video are consecutive [cin, hw] blocks, so B rows kk = (tap - tap0)*cin + c of output
// frame s are the contiguous rows of x starting at frame s + tap0 - 1; taps that fall outside the video are zero.
struct TemporalB : gemm_detail::BSource {
  const float* x;
  int64_t f, cin, hw, tap0;
  TemporalB(const float* x_, int64_t f_, int64_t cin_, int64_t hw_, int64_t tap0_)
      : x(x_), f(f_), cin(cin_), hw(hw_), tap0(tap0_) {}
  void pack(const gemm_detail::GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr,
            float* dst) const override {
    const int64_t t = seg % f;
    const int NR = path.nr;
    for (int64_t k = k0; k < k0 + kc;) {
      const int64_t tap = tap0 + k / cin;
      const int64_t run = std::min(k0 + kc, (k / cin + 1) * cin) - k;  // rows of this tap in the block
      float* d = dst + (k - k0) * NR;
      const int64_t src_t = t + tap - 1;
      if (src_t < 0 || src_t >= f) {
        std::fill(d, d + run * NR, 0.0f);
      } else {
        const float* p = x + ((seg + tap - 1) * cin + k % cin) * hw + n0;
        path.pack_b(p, DType::F32, hw, false, nullptr, run, nr, d);
      }
      k += run;
    }
  }
};

// The filter transform (per call, ~cout*cin) is paid back by the third (F(2,3)) or half (F(4,3)) of the
// multiplications saved (~cout*cin*f*hw) once a frame has a few pixel panels: measured on an AMD EPYC (Zen 5
// class), 2 threads, 16 frames, F16 weights, F(2,3) 1.15-1.6x the direct convolution on the U-Net's and the VAE
// decoder's frames of 256 pixels and more; on 1280 channels of 4x4 frames 0.94x (each unit of 16 pixels reads all
// four transformed filters, 26 MB).
constexpr int64_t kMinPixels = 32;

bool temporal_winograd(int64_t f, int64_t cin, int64_t cout, int64_t hw) {
  // One frame: the centre tap only; no input channel: nothing to transform.
  if (f < 2 || cin < 1) return false;
  const ConvAlgo algo = conv_algo();
  if (algo == ConvAlgo::Auto && precision() == Precision::Int8 && !gemm_detail::gemm_path().i8_temporal_winograd)
    return false;
  // Bf16 (F(2,3) on vdpbf16ps) gains from 256 input channels on; on the VAE decoder's 128 its transforms outweigh
  // the products saved (AMD EPYC Zen 4, 16 frames of 2048-pixel tiles: 2.78 s direct, 3.35 s F(2,3)).
  // Where vdpbf16ps doubles the direct convolution's rate, also from more pixels per frame (GemmPath).
  const bool bf16 = precision() == Precision::Bf16;
  const int64_t min_cin = bf16 ? 256 : 16;
  const int64_t min_hw = std::max(kMinPixels, bf16 ? gemm_detail::gemm_path().temporal_winograd_min_pixels_bf16 : 0);
  return algo == ConvAlgo::Winograd || (algo == ConvAlgo::Auto && cin >= min_cin && cout >= 16 && hw >= min_hw);
}

// F(4,3) where it needs fewer products than F(2,3) (4 per 2 frames against 6 per 4; 16 frames: 32 and 24) and the
// channels make the products the larger part of the work. Measured on an AMD EPYC (Zen 5 class), 2 threads, 16
// frames, F16 weights, alternating with F(2,3): 128 channels 0.94x (its transforms, 6 panels in and 6 products out
// per tile, outweigh the quarter of the products saved), 256-512 channels 1.05-1.17x, 1280 channels of 8x8 frames
// 1.22x.
int temporal_tile(int64_t f, int64_t cin) {
  // Bf16 rounds the transformed operands: F(2,3)'s add and halve values and lose ~1.3x the direct bfloat16
  // convolution's accuracy, F(4,3)'s scale them by up to 8 and lose ~3.8x (float64 simulation over 320 channels).
  // Int8 quantises them, with the same reasoning.
  if (precision() != Precision::Fp32) return 2;
  if (const int forced = conv_detail::temporal_winograd_tile()) return forced;
  return cin >= 256 && 6 * ((f + 3) / 4) < 4 * ((f + 1) / 2) ? 4 : 2;
}

// U_i (at u + i * stride) from the taps w0, w1, w2 of n elements of the packed A panels; plain loops on restrict
// pointers, multiplying by the reciprocals, so that the compiler vectorises them (scalar divisions took ~6% of a
// 1280-channel call).
template <int M>
void filter_transform(const float* __restrict w0, const float* __restrict w1, const float* __restrict w2, int64_t n,
                      float* u, int64_t stride) {
  float *__restrict u0 = u, *__restrict u1 = u + stride, *__restrict u2 = u + 2 * stride,
                    *__restrict u3 = u + 3 * stride;
  if constexpr (M == 2) {
    for (int64_t e = 0; e < n; ++e) {
      const float h = 0.5f * (w0[e] + w2[e]);
      u0[e] = w0[e], u1[e] = h + 0.5f * w1[e], u2[e] = h - 0.5f * w1[e], u3[e] = w2[e];
    }
  } else {
    float *__restrict u4 = u + 4 * stride, *__restrict u5 = u + 5 * stride;
    constexpr float kSixth = 1.0f / 6.0f, kTwentyFourth = 1.0f / 24.0f;
    for (int64_t e = 0; e < n; ++e) {
      const float s = w0[e] + w2[e], d = w0[e] + 4.0f * w2[e];
      u0[e] = 0.25f * w0[e];
      u1[e] = -(s + w1[e]) * kSixth;
      u2[e] = -(s - w1[e]) * kSixth;
      u3[e] = (d + 2.0f * w1[e]) * kTwentyFourth;
      u4[e] = (d - 2.0f * w1[e]) * kTwentyFourth;
      u5[e] = w2[e];
    }
  }
}

template <int M>
void conv_temporal3_winograd(const float* x, int64_t b, int64_t f, int64_t cin, int64_t hw, const Operand& weight,
                             const float* bias, int64_t cout, float* y, Act act, bool accumulate, int64_t ys) {
  using gemm_detail::GemmPath;
  constexpr int kA = M + 2;  // tile positions: transformed frames, filters and products per tile
  const GemmPath& path = gemm_detail::gemm_path();
  const int MR = path.mr, NR = path.nr;
  const int64_t tiles = (f + M - 1) / M, segs = b * tiles;
  // The filter transform, straight into the micro-kernel's A panels: panel (i, q) holds rows q*MR .. of U_i,
  // element (r, c) at [c*MR + r] (rows past cout zero). The taps are packed by the direct convolution's A packer
  // (vectorised per path) into three panels of the thread's, then combined.
  // Bf16: the transformed filters and frames are the products' inputs, rounded to bfloat16 (pairs for the native
  // micro-kernel, float32 values of bfloat16 precision for the emulated one). Int8: quantised in place, each panel
  // then in the int8 GEMM's group layout.
  const bool bf16 = precision() == Precision::Bf16, pairs = bf16 && path.micro_bf16;
  const bool int8 = precision() == Precision::Int8;
  const int64_t k_rows = int8 ? gemm_detail::i8_panel_rows(cin) : cin;  // float rows of one panel
  const int64_t mpanels = (cout + MR - 1) / MR, panel_floats = MR * k_rows, u_floats = mpanels * panel_floats;
  gemm_detail::TileEpilogue plain;
  if (int8) plain.i8_group = int8_group(cin);
  const gemm_detail::MicroKernel micro = int8 ? path.micro_i8 : pairs ? path.micro_bf16 : path.micro;
  const auto to_bf16 = [&](float* panel, int width) {
    if (pairs) path.to_bf16_pairs(panel, width, cin);
    else gemm_detail::round_to_bf16(panel, width * cin);
  };
  thread_local AlignedScratch a_buf, v_buf;
  const int transform_threads = cout * cin >= 4096 && !omp_in_parallel() ? num_threads() : 1;
  float* const A = a_buf.get(size_t(kA * u_floats + 3 * transform_threads * panel_floats));
  const TemporalA taps(weight, cin, 0);
#pragma omp parallel num_threads(transform_threads) if (transform_threads > 1)
  {
    float* const w0 = A + kA * u_floats + 3 * omp_get_thread_num() * panel_floats;
    float* const w1 = w0 + panel_floats;
    float* const w2 = w1 + panel_floats;
#pragma omp for schedule(static)
    for (int64_t q = 0; q < mpanels; ++q) {
      const int mr = int(std::min<int64_t>(MR, cout - q * MR));
      taps.pack(path, q * MR, mr, 0, cin, w0);
      taps.pack(path, q * MR, mr, cin, cin, w1);
      taps.pack(path, q * MR, mr, 2 * cin, cin, w2);
      filter_transform<M>(w0, w1, w2, MR * cin, A + q * panel_floats, u_floats);
      for (int i = 0; i < kA; ++i) {
        float* const u = A + i * u_floats + q * panel_floats;
        if (bf16) to_bf16(u, MR);
        if (int8) path.quantize_a_i8(u, u, MR, cin, plain.i8_group);
      }
    }
  }
  // Units of work: one pixel panel (NR pixels) of one tile, whose V_i panels are packed once and multiplied by every
  // row panel of the U_i; a thread takes `group` units at a time (their panels take about temporal_winograd_bytes(),
  // in L2), so each A panel it reads serves them all. The products of a micro-tile never leave the stack: the
  // output transform, bias, activation and residual follow at once (the products written to memory and read back
  // took most of the saving on 128-channel layers).
  const int64_t panels_per_seg = (hw + NR - 1) / NR, units = segs * panels_per_seg;
  // Panels one cache line more than their floats apart: the packer writes all kA of them row by row, which at a
  // power-of-two distance (128 channels: 16 KiB) would share one L1 set.
  const int64_t vpanel = k_rows * NR + 16, unit_floats = kA * vpanel;
  const int64_t group = std::clamp<int64_t>(conv_detail::temporal_winograd_bytes() / (unit_floats * 4), 1, 8);
  const int64_t ngroups = (units + group - 1) / group;
  int threads = omp_in_parallel() ? 1 : num_threads();
  if (2.0 * double(segs * hw) * double(kA * cout * cin) < gemm_detail::kSerialFlops) threads = 1;
  threads = int(std::min<int64_t>(threads, ngroups));
  float* const V = v_buf.get(size_t(threads * group * unit_floats));
  alignas(64) static const float zero_row[gemm_detail::kMaxNR] = {};
  // Unit u: tile (segment) s, pixels n0 .. n0 + nr - 1.
  const auto unit = [&](int64_t u) { return conv_detail::pixel_panel(u, panels_per_seg, hw, NR); };
#pragma omp parallel num_threads(threads) if (threads > 1)
  {
    float* const vb = V + omp_get_thread_num() * group * unit_floats;
    using gemm_detail::kMaxTile;
    alignas(64) float m[kA][kMaxTile];     // M_i of one micro-tile, row stride NR
    alignas(64) float out[M * kMaxTile];  // its output frames, where an activation follows
#pragma omp for schedule(dynamic)
    for (int64_t g = 0; g < ngroups; ++g) {
      const int64_t u0 = g * group, nu = std::min(group, units - u0);
      for (int64_t u = 0; u < nu; ++u) {
        const conv_detail::PixelPanel un = unit(u0 + u);
        const int64_t bi = un.group / tiles, t0 = M * (un.group % tiles) - 1;  // d_k = x[t0 + k]
        const float* in[kA];
        int64_t ld[kA];
        for (int k = 0; k < kA; ++k) {
          const int64_t t = t0 + k;
          const bool inside = t >= 0 && t < f;
          in[k] = inside ? x + (bi * f + t) * cin * hw + un.n0 : zero_row;
          ld[k] = inside ? hw : 0;
        }
        path.pack_b_temporal_wino(M, in, ld, cin, un.nr, vb + u * unit_floats, vpanel);
        for (int i = 0; i < kA; ++i) {
          float* const v = vb + u * unit_floats + i * vpanel;
          if (bf16) to_bf16(v, NR);
          if (int8) path.quantize_b_i8(v, v, NR, cin, plain.i8_group);
        }
      }
      for (int64_t q = 0; q < mpanels; ++q) {
        const int64_t m0 = q * MR;
        const int mr = int(std::min<int64_t>(MR, cout - m0));
        for (int64_t u = 0; u < nu; ++u) {
          const conv_detail::PixelPanel un = unit(u0 + u);  // named fields: lambdas below use them
          const int64_t s = un.group, n0 = un.n0;
          const int nr = un.nr;
          // The last tile's frames past the video are not written.
          const int64_t bi = s / tiles, t0 = M * (s % tiles), t1 = std::min<int64_t>(t0 + M, f);
          const auto dst_row = [&](int64_t t, int r) { return y + ((bi * f + t) * cout + m0 + r) * ys + n0; };
          // The tile's output rows lie a frame's width apart (often a multiple of 4 KiB), each on a page of its own,
          // beyond the prefetchers: fetch their lines now, while the products are computed.
          for (int64_t t = t0; t < t1; ++t)
            for (int r = 0; r < mr; ++r)
              for (int j = 0; j < nr; j += 16) __builtin_prefetch(dst_row(t, r) + j, 1, 3);
          for (int i = 0; i < kA; ++i)
            micro(cin, A + i * u_floats + q * panel_floats, 1, MR, vb + u * unit_floats + i * vpanel, m[i], NR, mr,
                  nr, plain);
          const float* const b = bias ? bias + m0 : nullptr;
          const int frames = int(t1 - t0);
          if (act == Act::None) {  // straight into place (the models' case)
            path.temporal_wino_output(M, m[0], kMaxTile, frames, mr, nr, b, accumulate, dst_row(t0, 0), cout * ys, ys);
            continue;
          }
          path.temporal_wino_output(M, m[0], kMaxTile, frames, mr, nr, b, false, out, MR * NR, NR);
          for (int t = 0; t < frames; ++t)
            for (int r = 0; r < mr; ++r) {
              float* const o = out + (t * MR + r) * NR;
              float* const dst = dst_row(t0 + t, r);
              wino_detail::apply_act_inplace(act, o, nr);
              if (accumulate)
                for (int j = 0; j < nr; ++j) dst[j] += o[j];
              else
                std::copy_n(o, nr, dst);
            }
        }
      }
    }
  }
}

}  // namespace

int& conv_detail::temporal_winograd_tile() {
  static int tile = 0;
  return tile;
}

int64_t& conv_detail::temporal_winograd_bytes() {
  static int64_t bytes = int64_t(384) << 10;
  return bytes;
}

std::string conv_temporal3_algorithm(int64_t f, int64_t cin, int64_t cout, int64_t hw) {
  if (!temporal_winograd(f, cin, cout, hw)) return "direct";
  return temporal_tile(f, cin) == 4 ? "winograd F(4,3)" : "winograd F(2,3)";
}

void conv_temporal3(const float* x, int64_t b, int64_t f, int64_t cin, int64_t hw, const Operand& weight,
                    const float* bias, int64_t cout, float* y, Act act, bool accumulate, int64_t y_stride) {
  // A frame's taps beyond the clip are zeros and skipped: 3 f - 2 taps per output pixel (one for a 1-frame clip).
  const KernelTimer timer(2.0 * double(b * std::max<int64_t>(3 * f - 2, 0) * hw) * double(cin * cout), [&] {
    return "conv_temporal3 " + std::to_string(cin) + "->" + std::to_string(cout) + " " + std::to_string(b) + "x" +
           std::to_string(f) + "x" + std::to_string(hw) + " " + conv_temporal3_algorithm(f, cin, cout, hw);
  });
  conv_detail::check_weight(weight, "conv_temporal3");
  if (b <= 0 || f <= 0 || hw <= 0 || cout <= 0) return;
  const int64_t ys = y_stride > 0 ? y_stride : hw;
  if (ys < hw) throw Error("conv_temporal3: output row stride " + std::to_string(ys) + " < " + std::to_string(hw) + " pixels");
  if (temporal_winograd(f, cin, cout, hw))
    return temporal_tile(f, cin) == 4
               ? conv_temporal3_winograd<4>(x, b, f, cin, hw, weight, bias, cout, y, act, accumulate, ys)
               : conv_temporal3_winograd<2>(x, b, f, cin, hw, weight, bias, cout, y, act, accumulate, ys);
  // One frame only: just the centre tap (the others always see zero padding).
  const int64_t tap0 = f == 1 ? 1 : 0, ntaps = f == 1 ? 1 : 3;
  TemporalA a(weight, cin, tap0);
  TemporalB bsrc(x, f, cin, hw, tap0);
  gemm_detail::GemmJob job;
  job.M = cout;
  job.K = ntaps * cin;
  job.segments = b * f;
  job.seg_cols = hw;
  job.a = &a;
  job.b = &bsrc;
  job.c = y;
  job.ldc = ys;
  job.c_seg_stride = cout * ys;
  job.ep = Epilogue{bias, true, act, accumulate};
  gemm_detail::run_gemm(job);
}


}  // namespace egopd
