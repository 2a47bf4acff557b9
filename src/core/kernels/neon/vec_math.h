#pragma once
// Vectorised float32 math for the NEON kernels (AArch64 Advanced SIMD, ARMv8.0-A): exp, exp2, erf, 1+erf, SiLU,
// GELU, horizontal reductions, and tail handling. The same algorithms and coefficients (vec_math_poly.h) as the
// AVX2 versions (avx2/vec_math.h), four lanes wide, so both paths give the same accuracy (tested against double
// precision).
// Include ONLY from kernels/neon/; everything is `static inline` (one private copy per file).
#include <arm_neon.h>

#include <cstdint>
#include <cstring>

#include "core/kernels/vec_math_poly.h"

namespace egopd::nmath {

using vmath_poly::kErfcTail;
using vmath_poly::kErfSmall;
using vmath_poly::kExp;

static inline float32x4_t horner(float32x4_t x, const float* c, int n) {  // c[0] x^(n-1) + ... + c[n-1]
  float32x4_t p = vdupq_n_f32(c[0]);
  for (int i = 1; i < n; ++i) p = vfmaq_f32(vdupq_n_f32(c[i]), p, x);
  return p;
}

// 2^n (n integral, -126..127) times exp(r) for |r| <= ln2/2.
static inline float32x4_t scale_exp_r(float32x4_t n, float32x4_t r) {
  const float32x4_t p = horner(r, kExp, 5);
  const float32x4_t y = vaddq_f32(vfmaq_f32(r, vmulq_f32(r, r), p), vdupq_n_f32(1.0f));
  const int32x4_t e = vshlq_n_s32(vaddq_s32(vcvtq_s32_f32(n), vdupq_n_s32(127)), 23);
  return vmulq_f32(y, vreinterpretq_f32_s32(e));
}

// exp(x) for x in [-87.34, 88.03] (no range handling): x = n ln2 + r.
static inline float32x4_t exp_core(float32x4_t x) {
  const float32x4_t n = vrndnq_f32(vmulq_f32(x, vdupq_n_f32(1.44269504088896341f)));
  float32x4_t r = vfmsq_f32(x, n, vdupq_n_f32(6.931471825e-01f));  // x - n ln2, ln2 split hi + lo
  r = vfmsq_f32(r, n, vdupq_n_f32(-1.904654212e-09f));
  return scale_exp_r(n, r);
}

static inline float32x4_t select(uint32x4_t m, float32x4_t a, float32x4_t b) { return vbslq_f32(m, a, b); }
static inline float32x4_t zero_where(uint32x4_t m, float32x4_t v) {
  return vreinterpretq_f32_u32(vbicq_u32(vreinterpretq_u32_f32(v), m));
}

// exp(x). Results below 2^-126 flush to 0; above FLT_MAX give +inf; exp(-inf) = 0; NaN stays NaN.
static inline float32x4_t exp_v(float32x4_t x) {
  const float32x4_t lo_limit = vdupq_n_f32(-87.33654f), hi_limit = vdupq_n_f32(88.72283f);
  const float32x4_t xc = vminq_f32(vmaxq_f32(x, lo_limit), vdupq_n_f32(88.02969f));  // keeps n <= 127
  float32x4_t res = zero_where(vcltq_f32(x, lo_limit), exp_core(xc));
  return select(vcgtq_f32(x, hi_limit), vdupq_n_f32(__builtin_inff()), res);
}

// exp(x) for x <= 0 (not NaN); results below 2^-126 flush to 0.
static inline float32x4_t exp_nonpositive(float32x4_t x) {
  const float32x4_t lo_limit = vdupq_n_f32(-87.33654f);
  return zero_where(vcltq_f32(x, lo_limit), exp_core(vmaxq_f32(x, lo_limit)));
}

// 2^x (same limits as exp_v).
static inline float32x4_t exp2_v(float32x4_t x) {
  const float32x4_t lo_limit = vdupq_n_f32(-126.0f), hi_limit = vdupq_n_f32(128.0f);
  const float32x4_t xc = vminq_f32(vmaxq_f32(x, lo_limit), vdupq_n_f32(127.0f));
  const float32x4_t n = vrndnq_f32(xc);
  const float32x4_t r = vmulq_f32(vsubq_f32(xc, n), vdupq_n_f32(0.693147180559945309f));  // x - n exact
  const float32x4_t res = zero_where(vcltq_f32(x, lo_limit), scale_exp_r(n, r));
  return select(vcgeq_f32(x, hi_limit), vdupq_n_f32(__builtin_inff()), res);
}

// erfc(a) for a >= 1 (any a >= 0 gives a finite value): t R(t) exp(-a^2), t = 2/(2+a);
// a^2 = hi + lo exactly and exp(-hi-lo) ~ exp(-hi)(1-lo).
static inline float32x4_t erfc_tail(float32x4_t a) {
  const float32x4_t ac = vminq_f32(a, vdupq_n_f32(10.0f));
  const float32x4_t t = vdivq_f32(vdupq_n_f32(2.0f), vaddq_f32(vdupq_n_f32(2.0f), ac));
  const float32x4_t hi = vmulq_f32(ac, ac);
  const float32x4_t lo = vfmaq_f32(vnegq_f32(hi), ac, ac);  // ac*ac - hi, exact
  const float32x4_t e = exp_nonpositive(vnegq_f32(hi));
  const float32x4_t ex = vfmsq_f32(e, e, lo);
  return vmulq_f32(vmulq_f32(t, horner(t, kErfcTail, 9)), ex);
}

static inline float32x4_t erf_v(float32x4_t z) {
  const float32x4_t one = vdupq_n_f32(1.0f);
  const float32x4_t a = vabsq_f32(z);
  const float32x4_t small = vmulq_f32(a, horner(vmulq_f32(a, a), kErfSmall, 7));  // erf(a), a < 1
  const float32x4_t e = select(vcltq_f32(a, one), small, vsubq_f32(one, erfc_tail(a)));
  const uint32x4_t sign = vandq_u32(vreinterpretq_u32_f32(z), vdupq_n_u32(0x80000000u));
  return vreinterpretq_f32_u32(vorrq_u32(vreinterpretq_u32_f32(e), sign));
}

// 1 + erf(z) without cancellation for negative z (= erfc(|z|) there).
static inline float32x4_t erf1p_v(float32x4_t z) {
  const float32x4_t one = vdupq_n_f32(1.0f);
  const float32x4_t a = vabsq_f32(z);
  const float32x4_t small1p = vfmaq_f32(one, z, horner(vmulq_f32(z, z), kErfSmall, 7));  // |z| < 1
  const float32x4_t tail = erfc_tail(a);
  const uint32x4_t negative = vcltq_s32(vreinterpretq_s32_f32(z), vdupq_n_s32(0));  // sign bit, as blendv
  const float32x4_t tail1p = select(negative, tail, vsubq_f32(vdupq_n_f32(2.0f), tail));
  return select(vcltq_f32(a, one), small1p, tail1p);
}

// GELU(x) = 0.5 x (1 + erf(x / sqrt 2)), exact erf form.
static inline float32x4_t gelu_v(float32x4_t x) {
  const float32x4_t z = vmulq_f32(x, vdupq_n_f32(0.70710678118654752f));
  return vmulq_f32(vmulq_f32(vdupq_n_f32(0.5f), x), erf1p_v(z));
}

// x * sigmoid(k x) = x / (1 + exp(-k x)); k = 1 for SiLU, 1.702 for quick GELU.
static inline float32x4_t x_sigmoid_v(float32x4_t x, float k) {
  const float32x4_t e = exp_v(vmulq_f32(x, vdupq_n_f32(-k)));
  return vdivq_f32(x, vaddq_f32(vdupq_n_f32(1.0f), e));
}
static inline float32x4_t silu_v(float32x4_t x) { return x_sigmoid_v(x, 1.0f); }

// The first n (0..3) floats at p as a vector (zeros after), and back.
static inline float32x4_t load_tail(const float* p, int64_t n) {
  float b[4] = {0.0f, 0.0f, 0.0f, 0.0f};
  std::memcpy(b, p, size_t(n) * sizeof(float));
  return vld1q_f32(b);
}
static inline void store_tail(float* p, float32x4_t v, int64_t n) {
  float b[4];
  vst1q_f32(b, v);
  std::memcpy(p, b, size_t(n) * sizeof(float));
}

// x[i] = exp(x[i] - m) for i < n; returns the sum of the new values.
static inline float exp_shifted_sum(float* x, int64_t n, float m) {
  const float32x4_t vm = vdupq_n_f32(m);
  float32x4_t sum = vdupq_n_f32(0.0f);
  int64_t i = 0;
  for (; i + 4 <= n; i += 4) {
    const float32x4_t e = exp_v(vsubq_f32(vld1q_f32(x + i), vm));
    vst1q_f32(x + i, e);
    sum = vaddq_f32(sum, e);
  }
  if (i < n) {
    store_tail(x + i, exp_v(vsubq_f32(load_tail(x + i, n - i), vm)), n - i);
    sum = vaddq_f32(sum, load_tail(x + i, n - i));  // the valid lanes only
  }
  return vaddvq_f32(sum);
}

}  // namespace egopd::nmath
