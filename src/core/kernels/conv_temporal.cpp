// The temporal convolution (kernel (3,1,1)): either one implicit GEMM over the three taps (direct), or Winograd
// F(2,3) along time (two output frames from four input frames with four products instead of six: 2/3 of the
// GEMM work), chosen like conv2d's algorithm (conv.h: ConvAlgo).
//
// F(2,3) (Lavin & Gray), per frame pair p (outputs 2p, 2p+1; inputs d_k = x[2p-1+k], zero outside the video):
//   V_0 = d_0 - d_2, V_1 = d_1 + d_2, V_2 = d_2 - d_1, V_3 = d_1 - d_3        (input transform, per channel)
//   U_0 = w_0, U_1 = (w_0 + w_1 + w_2)/2, U_2 = (w_0 - w_1 + w_2)/2, U_3 = w_2  (filter transform, per (o, c))
//   M_i = U_i · V_i                                                          (four products [cout, cin] x [cin, px])
//   y_2p = M_0 + M_1 + M_2,  y_2p+1 = M_1 - M_2 - M_3                        (output transform)
// V exists only as the micro-kernel's B panels (packed from the two frames each combines), M only as its tiles.
#include <omp.h>

#include <algorithm>
#include <string>

#include "core/error.h"
#include "core/kernels/conv.h"
#include "core/kernels/conv_internal.h"
#include "core/kernels/gemm_internal.h"
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

// V_i of frame pairs: B(c, n) of segment s = (batch, pair) is sa * d_ka + sb * d_kb at pixel n0_block + n.
struct WinogradTemporalB : gemm_detail::BSource {
  const float* x;
  int64_t f, cin, hw, pairs;
  int ka, kb;
  float sb;  // sa = 1 for every V_i (V_2 = d_2 - d_1 is written with d_2 first)
  void pack(const gemm_detail::GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr,
            float* dst) const override {
    const int64_t bi = seg / pairs, p = seg % pairs, NR = path.nr;
    const int64_t ta = 2 * p - 1 + ka, tb = 2 * p - 1 + kb;
    const auto frame = [&](int64_t t) { return x + ((bi * f + t) * cin + k0) * hw + n0; };
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

// The filter transform (per call, ~cout*cin) is paid back by a third of the multiplications (~cout*cin*f*hw)
// once a frame has a few pixel panels: measured on an AMD EPYC (Zen 5 class), 2 threads, 16 frames, F16 weights,
// 1.15-1.6x the direct convolution on the U-Net's and the VAE decoder's frames of 256 pixels and more; on 1280
// channels of 4x4 frames 0.94x (each unit of 16 pixels reads all four transformed filters, 26 MB).
constexpr int64_t kMinPixels = 32;

bool temporal_winograd(int64_t f, int64_t cin, int64_t cout, int64_t hw) {
  // One frame: the centre tap only; reduced precision: the direct GEMM's; no input channel: nothing to transform.
  if (f < 2 || cin < 1 || precision() != Precision::Fp32) return false;
  const ConvAlgo algo = conv_algo();
  return algo == ConvAlgo::Winograd || (algo == ConvAlgo::Auto && cin >= 16 && cout >= 16 && hw >= kMinPixels);
}

void conv_temporal3_winograd(const float* x, int64_t b, int64_t f, int64_t cin, int64_t hw, const Operand& weight,
                             const float* bias, int64_t cout, float* y, Act act, bool accumulate, int64_t ys) {
  using gemm_detail::GemmPath;
  const GemmPath& path = gemm_detail::gemm_path();
  const int MR = path.mr, NR = path.nr;
  const int64_t pairs = (f + 1) / 2, segs = b * pairs;
  // The filter transform, straight into the micro-kernel's A panels: panel (i, q) holds rows q*MR .. of U_i,
  // element (r, c) at [c*MR + r] (rows past cout zero). The taps are packed by the direct convolution's A packer
  // (vectorised per path), then combined.
  const int64_t mpanels = (cout + MR - 1) / MR, panel_floats = MR * cin, u_floats = mpanels * panel_floats;
  thread_local AlignedScratch a_buf, v_buf;
  const int transform_threads = cout * cin >= 4096 && !omp_in_parallel() ? num_threads() : 1;
  float* const A = a_buf.get(size_t(4 * u_floats + transform_threads * panel_floats));  // then tap 1 per thread
  const TemporalA taps(weight, cin, 0);
#pragma omp parallel num_threads(transform_threads) if (transform_threads > 1)
  {
    float* const w1 = A + 4 * u_floats + omp_get_thread_num() * panel_floats;
#pragma omp for schedule(static)
    for (int64_t q = 0; q < mpanels; ++q) {
      const int mr = int(std::min<int64_t>(MR, cout - q * MR));
      float* const u0 = A + q * panel_floats;
      float* const u1 = u0 + u_floats;
      float* const u2 = u1 + u_floats;
      float* const u3 = u2 + u_floats;
      taps.pack(path, q * MR, mr, 0, cin, u0);
      taps.pack(path, q * MR, mr, cin, cin, w1);
      taps.pack(path, q * MR, mr, 2 * cin, cin, u3);
      for (int64_t e = 0; e < panel_floats; ++e) {
        const float h = 0.5f * (u0[e] + u3[e]);
        u1[e] = h + 0.5f * w1[e];
        u2[e] = h - 0.5f * w1[e];
      }
    }
  }
  // Units of work: one pixel panel (NR pixels) of one frame pair, whose V_0..V_3 panels are packed once and
  // multiplied by every row panel of the U_i; a thread takes `group` units at a time (their panels take about
  // temporal_winograd_bytes(), in L2), so each A panel it reads serves them all. The four products of a micro-tile
  // never leave the stack: the output transform, bias, activation and residual follow at once (the products
  // written to memory and read back took most of the saving on 128-channel layers).
  const int64_t panels_per_seg = (hw + NR - 1) / NR, units = segs * panels_per_seg;
  const int64_t unit_floats = 4 * cin * NR;
  const int64_t group = std::clamp<int64_t>(conv_detail::temporal_winograd_bytes() / (unit_floats * 4), 1, 8);
  const int64_t ngroups = (units + group - 1) / group;
  int threads = omp_in_parallel() ? 1 : num_threads();
  if (2.0 * double(segs * hw) * double(4 * cout * cin) < gemm_detail::kSerialFlops) threads = 1;
  threads = int(std::min<int64_t>(threads, ngroups));
  float* const V = v_buf.get(size_t(threads * group * unit_floats));
  // {ka, kb, sb}: V_0 = d0 - d2, V_1 = d1 + d2, V_2 = d2 - d1, V_3 = d1 - d3.
  constexpr struct { int ka, kb; float sb; } kV[4] = {{0, 2, -1.0f}, {1, 2, 1.0f}, {2, 1, -1.0f}, {1, 3, -1.0f}};
  // Unit u: frame pair (segment) s, pixels n0 .. n0 + nr - 1.
  const auto unit = [&](int64_t u) { return conv_detail::pixel_panel(u, panels_per_seg, hw, NR); };
  WinogradTemporalB v[4];
  for (int i = 0; i < 4; ++i) {
    v[i].x = x, v[i].f = f, v[i].cin = cin, v[i].hw = hw, v[i].pairs = pairs;
    v[i].ka = kV[i].ka, v[i].kb = kV[i].kb, v[i].sb = kV[i].sb;
  }
#pragma omp parallel num_threads(threads) if (threads > 1)
  {
    float* const vb = V + omp_get_thread_num() * group * unit_floats;
    alignas(64) float m[4][gemm_detail::kMaxMR * gemm_detail::kMaxNR];  // M_i of one micro-tile, row stride NR
    alignas(64) float out[gemm_detail::kMaxNR];
    const gemm_detail::TileEpilogue plain;
#pragma omp for schedule(dynamic)
    for (int64_t g = 0; g < ngroups; ++g) {
      const int64_t u0 = g * group, nu = std::min(group, units - u0);
      for (int64_t u = 0; u < nu; ++u) {
        const conv_detail::PixelPanel un = unit(u0 + u);
        for (int i = 0; i < 4; ++i) v[i].pack(path, un.group, 0, cin, un.n0, un.nr, vb + (4 * u + i) * cin * NR);
      }
      for (int64_t q = 0; q < mpanels; ++q) {
        const int64_t m0 = q * MR;
        const int mr = int(std::min<int64_t>(MR, cout - m0));
        for (int64_t u = 0; u < nu; ++u) {
          const auto [s, n0, nr] = unit(u0 + u);
          for (int i = 0; i < 4; ++i)
            path.micro(cin, A + i * u_floats + q * panel_floats, 1, MR, vb + (4 * u + i) * cin * NR, m[i], NR, mr, nr,
                       plain);
          // y_2p = M_0 + M_1 + M_2, y_2p+1 = M_1 - M_2 - M_3 (the second frame of the last pair may not exist).
          const int64_t bi = s / pairs, t0 = 2 * (s % pairs);
          for (int64_t t = t0; t < std::min(t0 + 2, f); ++t)
            for (int r = 0; r < mr; ++r) {
              const float* m_0 = m[0] + r * NR;
              const float* m_1 = m[1] + r * NR;
              const float* m_2 = m[2] + r * NR;
              const float* m_3 = m[3] + r * NR;
              const float bv = bias ? bias[m0 + r] : 0.0f;
              if (t == t0)
                for (int j = 0; j < nr; ++j) out[j] = m_0[j] + m_1[j] + m_2[j] + bv;
              else
                for (int j = 0; j < nr; ++j) out[j] = m_1[j] - m_2[j] - m_3[j] + bv;
              wino_detail::apply_act_inplace(act, out, nr);
              float* dst = y + ((bi * f + t) * cout + m0 + r) * ys + n0;
              if (accumulate)
                for (int j = 0; j < nr; ++j) dst[j] += out[j];
              else
                std::copy_n(out, nr, dst);
            }
        }
      }
    }
  }
}

}  // namespace

int64_t& conv_detail::temporal_winograd_bytes() {
  static int64_t bytes = int64_t(384) << 10;
  return bytes;
}

std::string conv_temporal3_algorithm(int64_t f, int64_t cin, int64_t cout, int64_t hw) {
  return temporal_winograd(f, cin, cout, hw) ? "winograd F(2,3)" : "direct";
}

void conv_temporal3(const float* x, int64_t b, int64_t f, int64_t cin, int64_t hw, const Operand& weight,
                    const float* bias, int64_t cout, float* y, Act act, bool accumulate, int64_t y_stride) {
  conv_detail::check_weight(weight, "conv_temporal3");
  if (b <= 0 || f <= 0 || hw <= 0 || cout <= 0) return;
  const int64_t ys = y_stride > 0 ? y_stride : hw;
  if (ys < hw) throw Error("conv_temporal3: output row stride " + std::to_string(ys) + " < " + std::to_string(hw) + " pixels");
  if (temporal_winograd(f, cin, cout, hw))
    return conv_temporal3_winograd(x, b, f, cin, hw, weight, bias, cout, y, act, accumulate, ys);
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
