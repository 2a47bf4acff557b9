#pragma once
// Register-level loads and transposes shared by the NEON GEMM and convolution files. Include ONLY from
// kernels/neon/ (after core/dtype.h); everything is static (one private copy per file).
#include <arm_neon.h>

#include <cstdint>
#include <cstring>

namespace egopd::pack_neon {

// 4 consecutive elements starting at element idx, as float32 (I8: before its scale). Every conversion is exact:
// F16 by fcvtl (ARMv8.0-A), BF16 by a 16-bit shift, I8 by widening to int32.
static inline __attribute__((always_inline)) float32x4_t load4(const void* p, DType dt, int64_t idx) {
  if (dt == DType::F32) return vld1q_f32(static_cast<const float*>(p) + idx);
  if (dt == DType::I8) {
    int32_t w;
    std::memcpy(&w, static_cast<const int8_t*>(p) + idx, 4);
    const int16x8_t h = vmovl_s8(vreinterpret_s8_s32(vdup_n_s32(w)));
    return vcvtq_f32_s32(vmovl_s16(vget_low_s16(h)));
  }
  const uint16x4_t h = vld1_u16(static_cast<const uint16_t*>(p) + idx);
  if (dt == DType::F16) return vcvt_f32_f16(vreinterpret_f16_u16(h));
  return vreinterpretq_f32_u32(vshll_n_u16(h, 16));  // BF16
}

// r[i] (row i, 4 columns) -> r[j] (column j, 4 rows).
static inline __attribute__((always_inline)) void transpose4(float32x4_t* r) {
  const float32x4_t t0 = vtrn1q_f32(r[0], r[1]), t1 = vtrn2q_f32(r[0], r[1]);
  const float32x4_t t2 = vtrn1q_f32(r[2], r[3]), t3 = vtrn2q_f32(r[2], r[3]);
  r[0] = vreinterpretq_f32_f64(vtrn1q_f64(vreinterpretq_f64_f32(t0), vreinterpretq_f64_f32(t2)));
  r[1] = vreinterpretq_f32_f64(vtrn1q_f64(vreinterpretq_f64_f32(t1), vreinterpretq_f64_f32(t3)));
  r[2] = vreinterpretq_f32_f64(vtrn2q_f64(vreinterpretq_f64_f32(t0), vreinterpretq_f64_f32(t2)));
  r[3] = vreinterpretq_f32_f64(vtrn2q_f64(vreinterpretq_f64_f32(t1), vreinterpretq_f64_f32(t3)));
}

}  // namespace egopd::pack_neon
