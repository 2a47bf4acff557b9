// NEON micro-kernel (8 x 12, 24 q-register accumulators) and packing with on-the-fly F16/BF16/I8 conversion, for
// AArch64's 32 128-bit registers: per k step one packed A column (8 floats, 2 loads) and one packed B row
// (12 floats, 3 loads) feed 24 FMLA-by-element instructions (4.8 FMAs per load), using 29 of the 32 registers.
#include <cstdint>

#include "core/kernels/gemm_internal.h"
#include "core/kernels/neon/pack.h"
#include "core/kernels/neon/vec_math.h"

namespace egopd::gemm_detail {

namespace {

constexpr int MR = kMrNeon, NR = kNrNeon;
static_assert(MR == 8 && NR == 12, "the micro-kernel below is written for an 8 x 12 tile");

inline float32x4_t act_v(Act act, float32x4_t v) {
  switch (act) {
    case Act::SiLU: return nmath::silu_v(v);
    case Act::GELU: return nmath::gelu_v(v);
    case Act::QuickGELU: return nmath::x_sigmoid_v(v, 1.702f);
    default: return v;
  }
}

// One full row of the tile: v[0..2] = columns 0-3, 4-7, 8-11 of the sum.
inline void store_row(float* c, float32x4_t* v, int i, const TileEpilogue& ep) {
  float32x4_t old[3] = {vdupq_n_f32(0.0f), vdupq_n_f32(0.0f), vdupq_n_f32(0.0f)};
  if (ep.load_c || ep.add_after)
    for (int q = 0; q < 3; ++q) old[q] = vld1q_f32(c + 4 * q);
  for (int q = 0; q < 3; ++q) {
    float32x4_t s = v[q];
    if (ep.load_c) s = vaddq_f32(s, old[q]);
    if (ep.bias_row) s = vaddq_f32(s, vdupq_n_f32(ep.bias_row[i]));
    if (ep.bias_col) s = vaddq_f32(s, vld1q_f32(ep.bias_col + 4 * q));
    if (ep.act != Act::None) s = act_v(ep.act, s);
    if (ep.add_after) s = vaddq_f32(s, old[q]);
    vst1q_f32(c + 4 * q, s);
  }
}

}  // namespace

// Rows i of the tile: accumulators c[i][0..2]; row i takes lane i % 4 of A register i / 4.
#define EGOPD_FMLA_ROW(i, areg, lane)                 \
  do {                                                \
    c##i##0 = vfmaq_laneq_f32(c##i##0, b0, areg, lane); \
    c##i##1 = vfmaq_laneq_f32(c##i##1, b1, areg, lane); \
    c##i##2 = vfmaq_laneq_f32(c##i##2, b2, areg, lane); \
  } while (0)

// A is always packed on this path (GemmPath::a_in_place is false): a[k*MR + i].
void microkernel_neon(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c, int64_t ldc,
                      int mr, int nr, const TileEpilogue& ep) {
  const float32x4_t z = vdupq_n_f32(0.0f);
  float32x4_t c00 = z, c01 = z, c02 = z, c10 = z, c11 = z, c12 = z, c20 = z, c21 = z, c22 = z, c30 = z, c31 = z,
              c32 = z, c40 = z, c41 = z, c42 = z, c50 = z, c51 = z, c52 = z, c60 = z, c61 = z, c62 = z, c70 = z,
              c71 = z, c72 = z;
  const float* ap = a;
#pragma GCC unroll 4
  for (int64_t k = 0; k < kc; ++k) {
    const float32x4_t a0 = vld1q_f32(ap), a1 = vld1q_f32(ap + 4);
    const float32x4_t b0 = vld1q_f32(b), b1 = vld1q_f32(b + 4), b2 = vld1q_f32(b + 8);
    __builtin_prefetch(b + 8 * NR);
    EGOPD_FMLA_ROW(0, a0, 0);
    EGOPD_FMLA_ROW(1, a0, 1);
    EGOPD_FMLA_ROW(2, a0, 2);
    EGOPD_FMLA_ROW(3, a0, 3);
    EGOPD_FMLA_ROW(4, a1, 0);
    EGOPD_FMLA_ROW(5, a1, 1);
    EGOPD_FMLA_ROW(6, a1, 2);
    EGOPD_FMLA_ROW(7, a1, 3);
    ap += MR;
    b += NR;
  }
  float32x4_t rows[MR][3] = {{c00, c01, c02}, {c10, c11, c12}, {c20, c21, c22}, {c30, c31, c32},
                             {c40, c41, c42}, {c50, c51, c52}, {c60, c61, c62}, {c70, c71, c72}};
  if (mr == MR && nr == NR) {
    for (int i = 0; i < MR; ++i) store_row(c + i * ldc, rows[i], i, ep);
    return;
  }
  float sum[MR * 16];  // store_tile_scalar's layout: row stride 16
  for (int i = 0; i < MR; ++i)
    for (int q = 0; q < 3; ++q) vst1q_f32(sum + i * 16 + 4 * q, rows[i][q]);
  store_tile_scalar(sum, c, ldc, mr, nr, ep);
}

#undef EGOPD_FMLA_ROW

void store_tile_neon(const float* sum, float* c, int64_t ldc, int mr, int nr, const TileEpilogue& ep) {
  if (mr < MR || nr < NR) return store_tile_scalar(sum, c, ldc, mr, nr, ep);
  for (int i = 0; i < MR; ++i) {
    float32x4_t row[3] = {vld1q_f32(sum + i * 16), vld1q_f32(sum + i * 16 + 4), vld1q_f32(sum + i * 16 + 8)};
    store_row(c + i * ldc, row, i, ep);
  }
}

// ---- packing --------------------------------------------------------------------------------------------------

namespace {

using pack_neon::load4;
using pack_neon::transpose4;

inline int64_t elem_size(DType dt) { return dt == DType::F32 ? 4 : dt == DType::I8 ? 1 : 2; }
inline bool packable(DType dt) {
  return dt == DType::F32 || dt == DType::F16 || dt == DType::BF16 || dt == DType::I8;
}

// B(k, j) = p[k*ld + j] (* scale[j]), all 12 columns valid.
__attribute__((always_inline)) inline void pack_b_rows12(const void* p, DType dt, int64_t ld, const float* scale,
                                                         int64_t kc, float* dst) {
  const int64_t es = elem_size(dt);
  float32x4_t s[3];
  for (int q = 0; q < 3; ++q) s[q] = scale ? vld1q_f32(scale + 4 * q) : vdupq_n_f32(1.0f);
  for (int64_t k = 0; k < kc; ++k) {
    __builtin_prefetch(static_cast<const char*>(p) + (k * ld + NR) * es);  // the next panel's part of this row
    for (int q = 0; q < 3; ++q) {
      float32x4_t v = load4(p, dt, k * ld + 4 * q);
      if (scale) v = vmulq_f32(v, s[q]);
      vst1q_f32(dst + k * NR + 4 * q, v);
    }
  }
}

// B(k, j) = p[j*ld + k] (* scale[j]), all 12 columns valid: 4 x 4 register transposes; returns the k handled
// (a multiple of 4).
__attribute__((always_inline)) inline int64_t pack_b_cols12(const void* p, DType dt, int64_t ld, const float* scale,
                                                            int64_t kc, float* dst) {
  const int64_t k4 = kc / 4 * 4;
  for (int64_t k = 0; k < k4; k += 4)
    for (int g = 0; g < 3; ++g) {
      float32x4_t r[4];
      for (int j = 0; j < 4; ++j) {
        r[j] = load4(p, dt, (g * 4 + j) * ld + k);
        if (scale) r[j] = vmulq_n_f32(r[j], scale[g * 4 + j]);
      }
      transpose4(r);
      for (int q = 0; q < 4; ++q) vst1q_f32(dst + (k + q) * NR + g * 4, r[q]);
    }
  return k4;
}

// A(i, k) = p[i*ld + k] (* scale[i]), all 8 rows valid: two 4 x 4 transposes per 4 k; returns the k handled.
__attribute__((always_inline)) inline int64_t pack_a_rows8(const void* p, DType dt, int64_t ld, const float* scale,
                                                           int64_t kc, float* dst) {
  const int64_t k4 = kc / 4 * 4;
  for (int64_t k = 0; k < k4; k += 4)
    for (int g = 0; g < 2; ++g) {
      float32x4_t r[4];
      for (int i = 0; i < 4; ++i) {
        r[i] = load4(p, dt, (g * 4 + i) * ld + k);
        if (scale) r[i] = vmulq_n_f32(r[i], scale[g * 4 + i]);
      }
      transpose4(r);
      for (int q = 0; q < 4; ++q) vst1q_f32(dst + (k + q) * MR + g * 4, r[q]);
    }
  return k4;
}

// A(i, k) = p[k*ld + i] (* scale[i]), all 8 rows valid: each k is 8 consecutive elements.
__attribute__((always_inline)) inline void pack_a_cols8(const void* p, DType dt, int64_t ld, const float* scale,
                                                        int64_t kc, float* dst) {
  const float32x4_t s0 = scale ? vld1q_f32(scale) : vdupq_n_f32(1.0f);
  const float32x4_t s1 = scale ? vld1q_f32(scale + 4) : vdupq_n_f32(1.0f);
  for (int64_t k = 0; k < kc; ++k) {
    float32x4_t v0 = load4(p, dt, k * ld), v1 = load4(p, dt, k * ld + 4);
    if (scale) v0 = vmulq_f32(v0, s0), v1 = vmulq_f32(v1, s1);
    vst1q_f32(dst + k * MR, v0);
    vst1q_f32(dst + k * MR + 4, v1);
  }
}

}  // namespace

void pack_b_neon(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int64_t kc, int nr,
                 float* dst) {
  if (nr != NR || !packable(dt)) return pack_b_portable<NR>(p, dt, ld, trans, scale, kc, nr, dst);
  if (!trans) {
    switch (dt) {
      case DType::F32: return pack_b_rows12(p, DType::F32, ld, scale, kc, dst);
      case DType::F16: return pack_b_rows12(p, DType::F16, ld, scale, kc, dst);
      case DType::BF16: return pack_b_rows12(p, DType::BF16, ld, scale, kc, dst);
      default: return pack_b_rows12(p, DType::I8, ld, scale, kc, dst);
    }
  }
  int64_t done;
  switch (dt) {
    case DType::F32: done = pack_b_cols12(p, DType::F32, ld, scale, kc, dst); break;
    case DType::F16: done = pack_b_cols12(p, DType::F16, ld, scale, kc, dst); break;
    case DType::BF16: done = pack_b_cols12(p, DType::BF16, ld, scale, kc, dst); break;
    default: done = pack_b_cols12(p, DType::I8, ld, scale, kc, dst); break;
  }
  if (done < kc)
    pack_b_portable<NR>(static_cast<const char*>(p) + done * elem_size(dt), dt, ld, true, scale, kc - done, nr,
                        dst + done * NR);
}

void pack_a_neon(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int mr, int64_t kc,
                 float* dst) {
  if (mr != MR || !packable(dt)) return pack_a_portable<MR>(p, dt, ld, trans, scale, mr, kc, dst);
  if (trans) {
    switch (dt) {
      case DType::F32: return pack_a_cols8(p, DType::F32, ld, scale, kc, dst);
      case DType::F16: return pack_a_cols8(p, DType::F16, ld, scale, kc, dst);
      case DType::BF16: return pack_a_cols8(p, DType::BF16, ld, scale, kc, dst);
      default: return pack_a_cols8(p, DType::I8, ld, scale, kc, dst);
    }
  }
  int64_t done;
  switch (dt) {
    case DType::F32: done = pack_a_rows8(p, DType::F32, ld, scale, kc, dst); break;
    case DType::F16: done = pack_a_rows8(p, DType::F16, ld, scale, kc, dst); break;
    case DType::BF16: done = pack_a_rows8(p, DType::BF16, ld, scale, kc, dst); break;
    default: done = pack_a_rows8(p, DType::I8, ld, scale, kc, dst); break;
  }
  if (done < kc)
    pack_a_portable<MR>(static_cast<const char*>(p) + done * elem_size(dt), dt, ld, false, scale, mr, kc - done,
                        dst + done * MR);
}

}  // namespace egopd::gemm_detail
