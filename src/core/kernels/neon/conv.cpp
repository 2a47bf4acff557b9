// NEON implicit-im2col packing: each 12-column row of a B panel is three 4-float groups of the shifted frame; a
// group wholly inside the frame is one load, a group wholly outside is zero, a group across the frame's edge is
// read element by element (nothing outside the frame is ever read).
#include <cstdint>

#include "core/kernels/conv_internal.h"
#include "core/kernels/gemm_internal.h"
#include <arm_neon.h>

namespace egopd::conv_detail {

void pack_im2col_shift_neon(const float* xf, const ShiftGeom& s, int64_t k0, int64_t kc, int64_t n0, int nr,
                            float* dst) {
  constexpr int NR = gemm_detail::kNrNeon;
  static_assert(NR % 4 == 0, "whole 4-float groups");
  ShiftRows rows(xf, s, k0, n0, nr);
  for (int64_t k = 0; k < kc; ++k) {
    uint32_t m;
    const float* src = rows.next(&m);
    float* d = dst + k * NR;
    for (int g = 0; g < NR; g += 4) {
      const uint32_t mg = (m >> g) & 0xfu;
      if (mg == 0xfu) {
        vst1q_f32(d + g, vld1q_f32(src + g));
      } else if (mg == 0) {
        vst1q_f32(d + g, vdupq_n_f32(0.0f));
      } else {
        for (int j = g; j < g + 4; ++j) d[j] = (m >> j) & 1u ? src[j] : 0.0f;
      }
    }
  }
}

}  // namespace egopd::conv_detail
