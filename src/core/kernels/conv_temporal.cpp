// The temporal convolution (kernel (3,1,1)): either one implicit GEMM over the three taps (direct), or Winograd
// F(2,3) along time (two output frames from four input frames with four products instead of six: 2/3 of the
// GEMM work), chosen like conv2d's algorithm (conv.h: ConvAlgo).
//
// F(2,3) (Lavin & Gray), per frame pair p (outputs 2p, 2p+1; inputs d_k = x[2p-1+k], zero outside the video):
//   V_0 = d_0 - d_2, V_1 = d_1 + d_2, V_2 = d_2 - d_1, V_3 = d_1 - d_3        (input transform, per channel)
//   U_0 = w_0, U_1 = (w_0 + w_1 + w_2)/2, U_2 = (w_0 - w_1 + w_2)/2, U_3 = w_2  (filter transform, per (o, c))
//   M_i = U_i · V_i                                                          (four GEMMs [cout, cin] x [cin, px])
//   y_2p = M_0 + M_1 + M_2,  y_2p+1 = M_1 - M_2 - M_3                        (output transform)
// V is never stored: the GEMM's B packer forms it from the two frames it combines.
#include <omp.h>

#include <algorithm>

#include "core/kernels/conv.h"
#include "core/kernels/conv_internal.h"
#include "core/kernels/gemm_internal.h"
#include "core/kernels/winograd_internal.h"
#include "core/memory.h"

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

// V_i of frame pairs: B(c, n) of segment s = (batch, pair) is sa * d_ka + sb * d_kb at pixel n0_block + n.
struct WinogradTemporalB : gemm_detail::BSource {
  const float* x;
  int64_t f, cin, hw, pairs, px0;  // px0: the first pixel of this block
  int ka, kb;
  float sb;  // sa = 1 for every V_i (V_2 = d_2 - d_1 is written with d_2 first)
  void pack(const gemm_detail::GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr,
            float* dst) const override {
    const int64_t bi = seg / pairs, p = seg % pairs, NR = path.nr;
    const int64_t ta = 2 * p - 1 + ka, tb = 2 * p - 1 + kb;
    const auto frame = [&](int64_t t) { return x + ((bi * f + t) * cin + k0) * hw + px0 + n0; };
    const bool has_a = ta >= 0 && ta < f, has_b = tb >= 0 && tb < f;
    if (!has_a && !has_b) return std::fill(dst, dst + kc * NR, 0.0f);
    if (!has_b) return path.pack_b(frame(ta), DType::F32, hw, false, nullptr, kc, nr, dst);
    if (!has_a) {
      path.pack_b(frame(tb), DType::F32, hw, false, nullptr, kc, nr, dst);
      for (int64_t i = 0; i < kc * NR; ++i) dst[i] *= sb;
      return;
    }
    path.pack_b_sum(frame(ta), frame(tb), sb, hw, kc, nr, dst);
  }
};

// The filter transform (per call, ~cout*cin) is paid back by a third of the GEMM work (~cout*cin*f*hw) from a
// few pixels on: measured on an AMD EPYC (Zen 5 class), 2 threads, 16 frames, F16 weights: 1.17x on 1280 channels
// of 4x4 frames, 1.3-1.5x on the U-Net's and the VAE decoder's 256-1024 pixel frames, 1.25x on 128 channels of
// 256x256 (the products' memory traffic).
constexpr int64_t kMinPixels = 16;

bool temporal_winograd(int64_t f, int64_t cin, int64_t cout, int64_t hw) {
  if (f < 2 || precision() != Precision::Fp32) return false;  // one frame: the centre tap only; reduced precision
  const ConvAlgo algo = conv_algo();
  return algo == ConvAlgo::Winograd || (algo == ConvAlgo::Auto && cin >= 16 && cout >= 16 && hw >= kMinPixels);
}

void conv_temporal3_winograd(const float* x, int64_t b, int64_t f, int64_t cin, int64_t hw, const Operand& weight,
                             const float* bias, int64_t cout, float* y, Act act, bool accumulate) {
  const int64_t pairs = (f + 1) / 2, segs = b * pairs, K = std::max<int64_t>(cin, 1);
  // U_i [cout, cin] row-major, i = 0..3.
  thread_local AlignedScratch u_buf, m_buf;
  float* const U = u_buf.get(size_t(4 * cout * K));
#pragma omp parallel for schedule(static) if (cout * cin >= 4096 && !omp_in_parallel())
  for (int64_t o = 0; o < cout; ++o)
    for (int64_t c = 0; c < K; ++c) {
      const float w0 = c < cin ? weight_at(weight, cin, o, c, 0) : 0.0f, w1 = c < cin ? weight_at(weight, cin, o, c, 1) : 0.0f,
                  w2 = c < cin ? weight_at(weight, cin, o, c, 2) : 0.0f;
      const float h = 0.5f * (w0 + w2);
      float* u = U + o * K + c;
      u[0] = w0;
      u[cout * K] = h + 0.5f * w1;
      u[2 * cout * K] = h - 0.5f * w1;
      u[3 * cout * K] = w2;
    }
  // Pixel blocks whose four products M_i [segs, cout, nb] take about temporal_winograd_bytes() (a multiple of the
  // GEMM's panel width).
  const int64_t NR = gemm_detail::gemm_path().nr;
  int64_t nb = conv_detail::temporal_winograd_bytes() / (4 * 4 * segs * cout) / NR * NR;
  nb = std::clamp<int64_t>(nb, NR, (hw + NR - 1) / NR * NR);
  float* const Mb = m_buf.get(size_t(4 * segs * cout * nb));
  // {ka, kb, sb}: V_0 = d0 - d2, V_1 = d1 + d2, V_2 = d2 - d1, V_3 = d1 - d3.
  constexpr struct { int ka, kb; float sb; } kV[4] = {{0, 2, -1.0f}, {1, 2, 1.0f}, {2, 1, -1.0f}, {1, 3, -1.0f}};
  for (int64_t px0 = 0; px0 < hw; px0 += nb) {
    const int64_t n = std::min(nb, hw - px0);
    for (int i = 0; i < 4; ++i) {
      const Operand ua = f32_operand(U + i * cout * K, K);
      gemm_detail::OperandA a(ua);
      WinogradTemporalB v;
      v.x = x, v.f = f, v.cin = cin, v.hw = hw, v.pairs = pairs, v.px0 = px0;
      v.ka = kV[i].ka, v.kb = kV[i].kb, v.sb = kV[i].sb;
      gemm_detail::GemmJob job;
      job.M = cout;
      job.K = K;
      job.segments = segs;
      job.seg_cols = n;
      job.a = &a;
      job.b = &v;
      job.c = Mb + i * segs * cout * nb;
      job.ldc = nb;
      job.c_seg_stride = cout * nb;
      gemm_detail::run_gemm(job);
    }
    // Output transform, bias, activation and residual, one row of n pixels of one output frame at a time, in
    // chunks on the stack (no allocation per call: a batch run's memory must stay flat).
    constexpr int64_t kChunk = 256;
#pragma omp parallel for schedule(static) if (segs * cout * n >= 16384 && !omp_in_parallel())
    for (int64_t r = 0; r < segs * cout * 2; ++r) {
      const int64_t s = r / (2 * cout), o = (r / 2) % cout, odd = r % 2;
      const int64_t bi = s / pairs, t = 2 * (s % pairs) + odd;
      if (t >= f) continue;
      const int64_t mi = segs * cout * nb;  // floats between M_i and M_i+1
      const float bv = bias ? bias[o] : 0.0f;
      float* dst = y + ((bi * f + t) * cout + o) * hw + px0;
      for (int64_t j0 = 0; j0 < n; j0 += kChunk) {
        const int64_t len = std::min(kChunk, n - j0);
        const float* m0 = Mb + (s * cout + o) * nb + j0;
        alignas(64) float v[kChunk];
        if (odd)
          for (int64_t j = 0; j < len; ++j) v[j] = m0[mi + j] - m0[2 * mi + j] - m0[3 * mi + j] + bv;
        else
          for (int64_t j = 0; j < len; ++j) v[j] = m0[j] + m0[mi + j] + m0[2 * mi + j] + bv;
        wino_detail::apply_act_inplace(act, v, len);
        if (accumulate)
          for (int64_t j = 0; j < len; ++j) dst[j0 + j] += v[j];
        else
          std::copy_n(v, len, dst + j0);
      }
    }
  }
}

}  // namespace

int64_t& conv_detail::temporal_winograd_bytes() {
  static int64_t bytes = int64_t(8) << 20;
  return bytes;
}

std::string conv_temporal3_algorithm(int64_t f, int64_t cin, int64_t cout, int64_t hw) {
  return temporal_winograd(f, cin, cout, hw) ? "winograd F(2,3)" : "direct";
}

void conv_temporal3(const float* x, int64_t b, int64_t f, int64_t cin, int64_t hw, const Operand& weight,
                    const float* bias, int64_t cout, float* y, Act act, bool accumulate) {
  conv_detail::check_weight(weight, "conv_temporal3");
  if (b <= 0 || f <= 0 || hw <= 0 || cout <= 0) return;
  if (temporal_winograd(f, cin, cout, hw)) return conv_temporal3_winograd(x, b, f, cin, hw, weight, bias, cout, y, act, accumulate);
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
  job.ldc = hw;
  job.c_seg_stride = cout * hw;
  job.ep = Epilogue{bias, true, act, accumulate};
  gemm_detail::run_gemm(job);
}


}  // namespace egopd
