// Int8 micro-kernel (Precision::Int8) on the ARMv8.2 dot product: `sdot` adds four int8 x int8 products into each
// int32 lane, exactly (no intermediate width to saturate), so it multiplies the signed quad panels of the scalar
// emulation (gemm_internal.h: I8Group; both operands within -127..127) and gives the same numbers. 8 x 12 tile as
// the float32 kernel: per quad (4 k) one packed A slot row (8 rows x 4 bytes, 2 loads) and one B slot row (12
// columns x 4 bytes, 3 loads) feed 24 `sdot`-by-element instructions of 16 products each. Everything below the
// pragma may use ARMv8.2 instructions: gemm_paths.cpp calls it only when the CPU reports them (cpu.h:
// neon_dotprod).
#include <algorithm>
#include <cstdint>

#include "core/kernels/gemm_internal.h"

#include <arm_neon.h>

#pragma GCC target("arch=armv8.2-a+dotprod")

namespace egopd::gemm_detail {

namespace {
constexpr int MR = kMrNeon, NR = kNrNeon;
static_assert(MR == 8 && NR == 12, "the micro-kernel below is written for an 8 x 12 tile");
}  // namespace

// Row i of the tile: accumulators c[i][0..2]; row i's quad is lane i % 4 of A register i / 4.
#define EGOPD_SDOT_ROW(i, areg, lane)                      \
  do {                                                     \
    c##i##0 = vdotq_laneq_s32(c##i##0, b0, areg, lane);    \
    c##i##1 = vdotq_laneq_s32(c##i##1, b1, areg, lane);    \
    c##i##2 = vdotq_laneq_s32(c##i##2, b2, areg, lane);    \
  } while (0)

void microkernel_neon_sdot(int64_t kc, const float* a_panel, int64_t, int64_t, const float* b_panel, float* c,
                           int64_t ldc, int mr, int nr, const TileEpilogue& ep) {
  float sum[MR * 16] = {};  // float sums of the groups, row stride 16 (store_tile_neon)
  for (int64_t g = 0, k0 = 0; k0 < kc; ++g, k0 += ep.i8_group) {
    const I8Group pa(a_panel, MR, ep.i8_group, g), pb(b_panel, NR, ep.i8_group, g);
    const int8_t* a = reinterpret_cast<const int8_t*>(pa.slots);
    const int8_t* b = reinterpret_cast<const int8_t*>(pb.slots);
    const int32x4_t z = vdupq_n_s32(0);
    int32x4_t c00 = z, c01 = z, c02 = z, c10 = z, c11 = z, c12 = z, c20 = z, c21 = z, c22 = z, c30 = z, c31 = z,
              c32 = z, c40 = z, c41 = z, c42 = z, c50 = z, c51 = z, c52 = z, c60 = z, c61 = z, c62 = z, c70 = z,
              c71 = z, c72 = z;
    const int64_t quads = i8_slot_rows(std::min(ep.i8_group, kc - k0));
#pragma GCC unroll 2
    for (int64_t p = 0; p < quads; ++p) {
      const int8x16_t a0 = vld1q_s8(a), a1 = vld1q_s8(a + 16);
      const int8x16_t b0 = vld1q_s8(b), b1 = vld1q_s8(b + 16), b2 = vld1q_s8(b + 32);
      __builtin_prefetch(b + 8 * 4 * NR);
      EGOPD_SDOT_ROW(0, a0, 0);
      EGOPD_SDOT_ROW(1, a0, 1);
      EGOPD_SDOT_ROW(2, a0, 2);
      EGOPD_SDOT_ROW(3, a0, 3);
      EGOPD_SDOT_ROW(4, a1, 0);
      EGOPD_SDOT_ROW(5, a1, 1);
      EGOPD_SDOT_ROW(6, a1, 2);
      EGOPD_SDOT_ROW(7, a1, 3);
      a += 4 * MR;
      b += 4 * NR;
    }
    const int32x4_t acc[MR][3] = {{c00, c01, c02}, {c10, c11, c12}, {c20, c21, c22}, {c30, c31, c32},
                                  {c40, c41, c42}, {c50, c51, c52}, {c60, c61, c62}, {c70, c71, c72}};
    // sum = fma(float(int32 sum), s_row * s_col, sum), as on every path (gemm_i8.cpp).
    for (int i = 0; i < MR; ++i) {
      const float32x4_t sa = vdupq_n_f32(pa.scale[i]);
      for (int q = 0; q < 3; ++q) {
        float* s = sum + i * 16 + 4 * q;
        vst1q_f32(s, vfmaq_f32(vld1q_f32(s), vcvtq_f32_s32(acc[i][q]), vmulq_f32(sa, vld1q_f32(pb.scale + 4 * q))));
      }
    }
  }
  store_tile_neon(sum, c, ldc, mr, nr, ep);
}

#undef EGOPD_SDOT_ROW

}  // namespace egopd::gemm_detail
