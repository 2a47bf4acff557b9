#pragma once
// Private helpers of the convolution kernels: implicit-im2col packing for stride-1 "same-width" convolutions,
// where row k = (c, ky, kx) of the im2col matrix is the frame shifted by (ky - ph, kx - pw) with zeros outside.
#include <cstdint>

#include "core/dtype.h"
#include "core/kernels/gemm.h"

namespace egopd::conv_detail {

// An Error naming `what` for a weight dtype the convolutions do not take (or an I8 weight without scales).
void check_weight(const Operand& w, const char* what);

// Bytes of the transformed-frame panels a thread of the temporal Winograd packs at a time (up to 8 pixel panels in
// 384 KiB; tests shrink it to one panel).
int64_t& temporal_winograd_bytes();
// The temporal Winograd's tile: 0 chooses F(2,3) or F(4,3) by frames and channels; tests force 2 or 4.
int& temporal_winograd_tile();

// Panel p of a flat numbering of pixel panels: groups (frames, frame pairs) of `pixels` pixels, each cut into
// panels_per_group panels of `width` (the last one shorter).
struct PixelPanel {
  int64_t group, n0;  // its group, its first pixel there
  int nr;             // its pixels
};
inline PixelPanel pixel_panel(int64_t p, int64_t panels_per_group, int64_t pixels, int64_t width) {
  const int64_t n0 = p % panels_per_group * width;
  return PixelPanel{p / panels_per_group, n0, int(pixels - n0 < width ? pixels - n0 : width)};
}

constexpr int64_t kMaxTaps = 64;  // kh*kw handled by the shift packer (larger kernels take the gather path)

struct ShiftGeom {
  int64_t h, w, kh, kw, ph, pw;
};

// masks[ky*kw + kx] bit j: column n0 + j (j < nr <= 32) reads inside the frame for that tap.
void shift_masks(const ShiftGeom& s, int64_t n0, int nr, uint32_t* masks);

// The rows k0, k0+1, ... of a shift-packed B panel in order: next() returns the shifted frame row's first column
// (column n0) and sets the mask of the columns j < nr that read inside the frame (bit j; the others must be zero).
class ShiftRows {
 public:
  ShiftRows(const float* xf, const ShiftGeom& s, int64_t k0, int64_t n0, int nr)
      : xf_(xf), taps_(s.kh * s.kw), plane_(s.h * s.w), c_(k0 / taps_), t_(k0 % taps_) {
    shift_masks(s, n0, nr, masks_);
    for (int64_t t = 0; t < taps_; ++t) offs_[t] = n0 + (t / s.kw - s.ph) * s.w + (t % s.kw - s.pw);
  }
  const float* next(uint32_t* mask) {
    const float* src = xf_ + c_ * plane_ + offs_[t_];
    *mask = masks_[t_];
    if (++t_ == taps_) t_ = 0, ++c_;
    return src;
  }

 private:
  const float* xf_;
  int64_t taps_, plane_, c_, t_;
  uint32_t masks_[kMaxTaps];
  int64_t offs_[kMaxTaps];
};

// dst[k*NR + j] = col(k0 + k, n0 + j) of frame xf [cin, h, w]; columns >= nr are zero. NR is the path's: 16 for
// portable and avx2, 32 for avx512, 12 for neon.
void pack_im2col_shift_portable(const float* xf, const ShiftGeom& s, int64_t k0, int64_t kc, int64_t n0, int nr,
                                float* dst);
void pack_im2col_shift_avx2(const float* xf, const ShiftGeom& s, int64_t k0, int64_t kc, int64_t n0, int nr,
                            float* dst);
void pack_im2col_shift_avx512(const float* xf, const ShiftGeom& s, int64_t k0, int64_t kc, int64_t n0, int nr,
                              float* dst);
void pack_im2col_shift_neon(const float* xf, const ShiftGeom& s, int64_t k0, int64_t kc, int64_t n0, int nr,
                            float* dst);

// 3x3 stride-1 pad-1 float32 convolution x [n, cin, h, w] -> y [n, cout, h, w] whose micro-kernel reads a small
// window of the input per output tile (no im2col panel), conv2d's epilogue. Returns false, having done nothing, for
// what it does not take (a width that is not a multiple of 16, packed filters over 16 MiB): the implicit GEMM runs
// those.
bool conv3x3_window_avx512(const float* x, int64_t n, int64_t h, int64_t w, const Operand& weight, const float* bias,
                           int64_t cin, int64_t cout, float* y, Act act, bool accumulate);

// Temporal conv weight W [cout, cin, 3] (F32/F16/BF16): 6 rows m0.. of the A micro-panel for the columns of one
// tap, dst[k*6 + i] = W[m0 + i, c0 + k, tap] for k < len. Returns the k handled (a multiple of 8; the caller
// packs the rest).
int64_t pack_a_temporal6_avx2(const void* w, DType dt, int64_t cin, int64_t m0, int64_t tap, int64_t c0, int64_t len,
                              float* dst);
// The same for the 12 rows of an AVX-512 panel (dst[k*12 + i]), as two runs of the AVX2 packer (AVX-512 CPUs have
// AVX2; the weights are read once either way).
int64_t pack_a_temporal12_avx2(const void* w, DType dt, int64_t cin, int64_t m0, int64_t tap, int64_t c0,
                               int64_t len, float* dst);

}  // namespace egopd::conv_detail
