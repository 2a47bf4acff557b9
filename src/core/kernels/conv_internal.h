#pragma once
// Private helpers of the convolution kernels: implicit-im2col packing for stride-1 "same-width" convolutions,
// where row k = (c, ky, kx) of the im2col matrix is the frame shifted by (ky - ph, kx - pw) with zeros outside.
#include <cstdint>

#include "core/dtype.h"

namespace egopd::conv_detail {

constexpr int64_t kMaxTaps = 64;  // kh*kw handled by the shift packer (larger kernels take the gather path)

struct ShiftGeom {
  int64_t h, w, kh, kw, ph, pw;
};

// masks[ky*kw + kx] bit j: column n0 + j (j < nr <= 32) reads inside the frame for that tap.
void shift_masks(const ShiftGeom& s, int64_t n0, int nr, uint32_t* masks);

// dst[k*NR + j] = col(k0 + k, n0 + j) of frame xf [cin, h, w]; columns >= nr are zero. NR is the path's: 16 for
// portable and avx2, 32 for avx512.
void pack_im2col_shift_portable(const float* xf, const ShiftGeom& s, int64_t k0, int64_t kc, int64_t n0, int nr,
                                float* dst);
void pack_im2col_shift_avx2(const float* xf, const ShiftGeom& s, int64_t k0, int64_t kc, int64_t n0, int nr,
                            float* dst);
void pack_im2col_shift_avx512(const float* xf, const ShiftGeom& s, int64_t k0, int64_t kc, int64_t n0, int nr,
                              float* dst);

// Temporal conv weight W [cout, cin, 3] (F32/F16/BF16): 6 rows m0.. of the A micro-panel for the columns of one
// tap, dst[k*6 + i] = W[m0 + i, c0 + k, tap] for k < len. Returns the k handled (a multiple of 8; the caller
// packs the rest).
int64_t pack_a_temporal6_avx2(const void* w, DType dt, int64_t cin, int64_t m0, int64_t tap, int64_t c0, int64_t len,
                              float* dst);

}  // namespace egopd::conv_detail
