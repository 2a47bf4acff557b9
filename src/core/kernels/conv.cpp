// Convolutions as implicit GEMMs on the SGEMM engine: out[cout, oh*ow] = W[cout, cin*kh*kw] · col[cin*kh*kw, oh*ow]
// per frame, where the B panels of col are packed straight from the input (never a whole im2col); frames are the
// engine's column segments, so the weight panels are packed once per column block, not once per frame. A kernel path
// may run float32 3x3 stride-1 convolutions its own way (GemmPath::conv3x3_window: AVX-512, from a per-tile window
// of the input instead of an im2col panel), and 3x3 stride-1 ones may take Winograd (winograd.h).
#include "core/kernels/conv.h"

#include <algorithm>
#include <cstdlib>
#include <string>

#include "core/error.h"
#include "core/kernels/conv_internal.h"
#include "core/kernels/gemm_internal.h"
#include "core/kernels/kernel_profile.h"
#include "core/kernels/winograd.h"

namespace egopd {

namespace {

int g_conv_algo = -1;  // -1: not chosen yet (EGOPD_CONV on first use)


// Implicit im2col of one frame: B(k, n) with k = (c*kh + ky)*kw + kx, n = oy*ow + ox.
struct Im2colB : gemm_detail::BSource {
  const float* x;
  int64_t h, w, oh, ow;
  Conv2dGeom g;
  bool shift;  // stride 1 and ow == w: column n of row k reads the frame at flat index n + (ky-ph)*w + (kx-pw)

  Im2colB(const float* x_, int64_t h_, int64_t w_, const Conv2dGeom& g_)
      : x(x_), h(h_), w(w_), oh(g_.out_h(h_)), ow(g_.out_w(w_)), g(g_) {
    shift = g.stride_h == 1 && g.stride_w == 1 && ow == w && g.kh * g.kw <= conv_detail::kMaxTaps;
  }

  void pack(const gemm_detail::GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr,
            float* dst) const override {
    const float* xf = x + seg * g.cin * h * w;
    if (shift) return path.pack_im2col_shift(xf, {h, w, g.kh, g.kw, g.pad_h, g.pad_w}, k0, kc, n0, nr, dst);
    // General geometry (strided, patch embedding): per-column input origin, then one gather per element.
    const int NR = path.nr;
    int64_t iy0[gemm_detail::kMaxNR], ix0[gemm_detail::kMaxNR];
    for (int j = 0; j < nr; ++j) {
      const int64_t n = n0 + j;
      iy0[j] = (n / ow) * g.stride_h - g.pad_h;
      ix0[j] = (n % ow) * g.stride_w - g.pad_w;
    }
    const int64_t taps = g.kh * g.kw;
    int64_t c = k0 / taps, ky = (k0 % taps) / g.kw, kx = k0 % g.kw;
    for (int64_t k = 0; k < kc; ++k) {
      float* d = dst + k * NR;
      const float* xc = xf + c * h * w;
      for (int j = 0; j < nr; ++j) {
        const int64_t iy = iy0[j] + ky, ix = ix0[j] + kx;
        d[j] = (iy >= 0 && iy < h && ix >= 0 && ix < w) ? xc[iy * w + ix] : 0.0f;
      }
      for (int j = nr; j < NR; ++j) d[j] = 0.0f;
      if (++kx == g.kw) {
        kx = 0;
        if (++ky == g.kh) ky = 0, ++c;
      }
    }
  }
};

}  // namespace

const char* conv_algo_name(ConvAlgo a) {
  switch (a) {
    case ConvAlgo::Direct: return "direct";
    case ConvAlgo::Winograd: return "winograd";
    default: return "auto";
  }
}

bool conv_algo_from_name(const std::string& s, ConvAlgo* out) {
  for (ConvAlgo a : {ConvAlgo::Direct, ConvAlgo::Winograd, ConvAlgo::Auto})
    if (s == conv_algo_name(a)) {
      *out = a;
      return true;
    }
  return false;
}

ConvAlgo conv_algo_from_env() {
  ConvAlgo a = ConvAlgo::Auto;
  if (const char* e = std::getenv("EGOPD_CONV"); e && *e && !conv_algo_from_name(e, &a))
    throw Error(std::string("EGOPD_CONV=") + e + ": unknown convolution algorithm (direct, winograd or auto)");
  return a;
}

ConvAlgo conv_algo() {
  if (g_conv_algo < 0) g_conv_algo = int(conv_algo_from_env());
  return ConvAlgo(g_conv_algo);
}

void set_conv_algo(ConvAlgo a) { g_conv_algo = int(a); }

namespace {

bool same_3x3(const Conv2dGeom& g) {
  return g.kh == 3 && g.kw == 3 && g.stride_h == 1 && g.stride_w == 1 && g.pad_h == 1 && g.pad_w == 1;
}

bool use_winograd(const Conv2dGeom& g, int64_t n, int64_t h, int64_t w) {
  const ConvAlgo algo = same_3x3(g) ? conv_algo() : ConvAlgo::Direct;
  if (algo != ConvAlgo::Auto) return algo == ConvAlgo::Winograd;
  // Winograd's arithmetic is float32. Under bf16 it rounds its inputs as the direct convolution does, and beats the
  // bfloat16 direct convolution on every layer measured (AMD EPYC Zen 5 class, 2 threads, vdpbf16ps: 1280 ch 8x8
  // 1.2-1.4x, 640 16x16 1.2x, 128 ch 256x256 2x). Under int8 it quantises its inputs, and beats the int8 direct
  // convolution where the path has no fast int8 dot product, on frames of the path's minimum size (GemmPath).
  if (!winograd_wins(g.cin, g.cout, n, h, w)) return false;
  return precision() != Precision::Int8 || std::min(h, w) >= gemm_detail::gemm_path().i8_winograd_min_frame;
}

}  // namespace

std::string conv2d_algorithm(const Conv2dGeom& g, int64_t n, int64_t h, int64_t w) {
  if (!use_winograd(g, n, h, w)) return "direct";
  return std::string("winograd ") + winograd_tile_name(winograd_tile_for(h, w));
}

namespace conv_detail {

void check_weight(const Operand& w, const char* what) {
  if (w.dtype != DType::F32 && w.dtype != DType::F16 && w.dtype != DType::BF16 && w.dtype != DType::I8)
    throw Error(std::string(what) + ": unsupported weight dtype " + dtype_name(w.dtype));
  if (w.dtype == DType::I8 && !w.scale) throw Error(std::string(what) + ": I8 weight has no scale");
}

void shift_masks(const ShiftGeom& s, int64_t n0, int nr, uint32_t* masks) {
  // Validity factors into a row part (ky) and a column part (kx): bit j of rows[ky] / cols[kx].
  uint32_t rows[kMaxTaps] = {}, cols[kMaxTaps] = {};
  int64_t oy = n0 / s.w, ox = n0 % s.w;
  for (int j = 0; j < nr; ++j) {
    for (int64_t ky = 0; ky < s.kh; ++ky)
      if (oy + ky - s.ph >= 0 && oy + ky - s.ph < s.h) rows[ky] |= 1u << j;
    for (int64_t kx = 0; kx < s.kw; ++kx)
      if (ox + kx - s.pw >= 0 && ox + kx - s.pw < s.w) cols[kx] |= 1u << j;
    if (++ox == s.w) ox = 0, ++oy;
  }
  for (int64_t ky = 0; ky < s.kh; ++ky)
    for (int64_t kx = 0; kx < s.kw; ++kx) masks[ky * s.kw + kx] = rows[ky] & cols[kx];
}

void pack_im2col_shift_portable(const float* xf, const ShiftGeom& s, int64_t k0, int64_t kc, int64_t n0, int nr,
                                float* dst) {
  constexpr int NR = gemm_detail::kNrPortable;
  uint32_t masks[kMaxTaps];
  shift_masks(s, n0, nr, masks);
  const int64_t taps = s.kh * s.kw;
  int64_t c = k0 / taps, tap = k0 % taps;
  for (int64_t k = 0; k < kc; ++k) {
    const int64_t ky = tap / s.kw, kx = tap % s.kw;
    const float* src = xf + c * s.h * s.w + n0 + (ky - s.ph) * s.w + (kx - s.pw);
    const unsigned m = masks[tap];
    float* d = dst + k * NR;
    for (int j = 0; j < NR; ++j) d[j] = (m >> j) & 1u ? src[j] : 0.0f;
    if (++tap == taps) tap = 0, ++c;
  }
}

}  // namespace conv_detail

void conv2d(const float* x, int64_t n, int64_t h, int64_t w, const Operand& weight, const float* bias,
            const Conv2dGeom& g, float* y, Act act, bool accumulate) {
  const KernelTimer timer(2.0 * double(n * g.out_h(h) * g.out_w(w)) * double(g.cin * g.cout * g.kh * g.kw), [&] {
    return "conv2d " + std::to_string(g.kh) + "x" + std::to_string(g.kw) + " s" + std::to_string(g.stride_h) + " " +
           std::to_string(g.cin) + "->" + std::to_string(g.cout) + " " + std::to_string(n) + "x" + std::to_string(h) +
           "x" + std::to_string(w) + " " + conv2d_algorithm(g, n, h, w);
  });
  conv_detail::check_weight(weight, "conv2d");
  const int64_t oh = g.out_h(h), ow = g.out_w(w);
  if (n <= 0 || oh <= 0 || ow <= 0 || g.cout <= 0) return;
  if (use_winograd(g, n, h, w))
    return conv2d_winograd(x, n, h, w, weight, bias, g.cin, g.cout, y, act, accumulate, winograd_tile_for(h, w));
  // The path's own 3x3 kernel packs all filters once per call: from 4096 pixels per call on (under it, e.g. the
  // VAE decoder's 512 channels on one 32x32 frame, it ran 0.93x the implicit GEMM, whose filter blocks are packed
  // per column block). It returns false for shapes it does not take.
  const auto window = gemm_detail::gemm_path().conv3x3_window;
  if (same_3x3(g) && window && precision() == Precision::Fp32 && n * h * w >= 4096 &&
      window(x, n, h, w, weight, bias, g.cin, g.cout, y, act, accumulate))
    return;
  const int64_t K = g.cin * g.kh * g.kw;
  Operand wa = weight;  // [cout, cin*kh*kw] row-major
  wa.trans = false;
  wa.ld = K;
  gemm_detail::OperandA a(wa);
  gemm_detail::GemmJob job;
  job.M = g.cout;
  job.K = K;
  job.segments = n;
  job.seg_cols = oh * ow;
  job.a = &a;
  job.c = y;
  job.ldc = oh * ow;
  job.c_seg_stride = g.cout * oh * ow;
  job.ep = Epilogue{bias, true, act, accumulate};
  if (g.kh == 1 && g.kw == 1 && g.stride_h == 1 && g.stride_w == 1 && g.pad_h == 0 && g.pad_w == 0) {
    gemm_detail::OperandB b(f32_operand(x, h * w), g.cin * h * w);  // the frame itself is col [cin, h*w]
    job.b = &b;
    gemm_detail::run_gemm(job);
  } else {
    Im2colB b(x, h, w, g);
    job.b = &b;
    gemm_detail::run_gemm(job);
  }
}

}  // namespace egopd
