#pragma once
// The 512-bit counterparts of avx2/vec_math.h (exp, exp2, erf, 1+erf, SiLU, GELU, horizontal reductions, tail
// masks), as overloads in the same namespace. Each keeps the AVX2 version's coefficients (vec_math_poly.h) and
// operations lane by lane, so every lane rounds exactly as on the avx2 path (tested bit for bit); mask registers
// replace the blendv masks. Include ONLY from kernels/avx512/, after the `#pragma GCC target` of those files and
// <immintrin.h>.
#include <cstdint>

#include "core/kernels/avx2/vec_math.h"

namespace egopd::vmath {

static inline __m512 horner(__m512 x, const float* c, int n) {  // c[0] x^(n-1) + ... + c[n-1]
  __m512 p = _mm512_set1_ps(c[0]);
  for (int i = 1; i < n; ++i) p = _mm512_fmadd_ps(p, x, _mm512_set1_ps(c[i]));
  return p;
}

// (1 + r + r^2 P(r)) 2^n for integral n in -126..127: vscalefps rounds y 2^n once, as the AVX2 path's multiply by
// 2^n built in the exponent bits does, so both give the same bits (in one instruction instead of three).
static inline __m512 scale_exp_r(__m512 n, __m512 r) {
  const __m512 p = horner(r, kExp, 5);
  const __m512 y = _mm512_add_ps(_mm512_fmadd_ps(_mm512_mul_ps(r, r), p, r), _mm512_set1_ps(1.0f));
  return _mm512_scalef_ps(y, n);
}

static inline __m512 round_nearest(__m512 x) {
  return _mm512_roundscale_ps(x, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
}

// exp(x) for x in [-87.34, 88.03] (no range handling): x = n ln2 + r.
static inline __m512 exp_core_ps(__m512 x) {
  const __m512 n = round_nearest(_mm512_mul_ps(x, _mm512_set1_ps(1.44269504088896341f)));
  __m512 r = _mm512_fnmadd_ps(n, _mm512_set1_ps(6.931471825e-01f), x);  // x - n ln2, ln2 split hi + lo
  r = _mm512_fnmadd_ps(n, _mm512_set1_ps(-1.904654212e-09f), r);
  return scale_exp_r(n, r);
}

// exp(x). Results below 2^-126 flush to 0; above FLT_MAX give +inf; exp(-inf) = 0.
static inline __m512 exp_ps(__m512 x) {
  const __m512 lo_limit = _mm512_set1_ps(-87.33654f), hi_limit = _mm512_set1_ps(88.72283f);
  const __m512 xc = _mm512_min_ps(_mm512_max_ps(x, lo_limit), _mm512_set1_ps(88.02969f));  // keeps n <= 127
  const __m512 res = _mm512_maskz_mov_ps(_mm512_cmp_ps_mask(x, lo_limit, _CMP_NLT_UQ), exp_core_ps(xc));
  return _mm512_mask_blend_ps(_mm512_cmp_ps_mask(x, hi_limit, _CMP_GT_OQ), res, _mm512_set1_ps(__builtin_inff()));
}

// exp(x) for x <= 0 (not NaN); results below 2^-126 flush to 0.
static inline __m512 exp_nonpositive_ps(__m512 x) {
  const __m512 lo_limit = _mm512_set1_ps(-87.33654f);
  return _mm512_maskz_mov_ps(_mm512_cmp_ps_mask(x, lo_limit, _CMP_NLT_UQ), exp_core_ps(_mm512_max_ps(x, lo_limit)));
}

// 2^x (same limits as exp_ps), for kernels that fold log2(e) into a scale.
static inline __m512 exp2_ps(__m512 x) {
  const __m512 lo_limit = _mm512_set1_ps(-126.0f), hi_limit = _mm512_set1_ps(128.0f);
  const __m512 xc = _mm512_min_ps(_mm512_max_ps(x, lo_limit), _mm512_set1_ps(127.0f));
  const __m512 n = round_nearest(xc);
  const __m512 r = _mm512_mul_ps(_mm512_sub_ps(xc, n), _mm512_set1_ps(0.693147180559945309f));  // x - n exact
  const __m512 res = _mm512_maskz_mov_ps(_mm512_cmp_ps_mask(x, lo_limit, _CMP_NLT_UQ), scale_exp_r(n, r));
  return _mm512_mask_blend_ps(_mm512_cmp_ps_mask(x, hi_limit, _CMP_GE_OQ), res, _mm512_set1_ps(__builtin_inff()));
}

// erfc(a) for a >= 1 (any a >= 0 gives a finite value): t R(t) exp(-a^2), t = 2/(2+a);
// a^2 = hi + lo exactly and exp(-hi-lo) ~ exp(-hi)(1-lo).
static inline __m512 erfc_tail_ps(__m512 a) {
  const __m512 ac = _mm512_min_ps(a, _mm512_set1_ps(10.0f));
  const __m512 t = _mm512_div_ps(_mm512_set1_ps(2.0f), _mm512_add_ps(_mm512_set1_ps(2.0f), ac));
  const __m512 hi = _mm512_mul_ps(ac, ac);
  const __m512 lo = _mm512_fmsub_ps(ac, ac, hi);
  const __m512 e = exp_nonpositive_ps(_mm512_sub_ps(_mm512_setzero_ps(), hi));
  const __m512 ex = _mm512_fnmadd_ps(e, lo, e);
  return _mm512_mul_ps(_mm512_mul_ps(t, horner(t, kErfcTail, 9)), ex);
}

static inline __m512 abs_ps(__m512 z) { return _mm512_andnot_ps(_mm512_set1_ps(-0.0f), z); }
static inline __mmask16 sign_mask(__m512 z) { return _mm512_movepi32_mask(_mm512_castps_si512(z)); }  // as blendv

static inline __m512 erf_ps(__m512 z) {
  const __m512 one = _mm512_set1_ps(1.0f);
  const __m512 a = abs_ps(z);
  const __m512 small = _mm512_mul_ps(a, horner(_mm512_mul_ps(a, a), kErfSmall, 7));  // erf(a), a < 1
  const __m512 tail = erfc_tail_ps(a);                                                 // erfc(a), a >= 1
  const __m512 e = _mm512_mask_blend_ps(_mm512_cmp_ps_mask(a, one, _CMP_LT_OQ), _mm512_sub_ps(one, tail), small);
  return _mm512_or_ps(e, _mm512_and_ps(z, _mm512_set1_ps(-0.0f)));
}

// 1 + erf(z) without cancellation for negative z (= erfc(|z|) there).
static inline __m512 erf1p_ps(__m512 z) {
  const __m512 one = _mm512_set1_ps(1.0f);
  const __m512 a = abs_ps(z);
  const __m512 small1p = _mm512_fmadd_ps(z, horner(_mm512_mul_ps(z, z), kErfSmall, 7), one);  // |z| < 1
  const __m512 tail = erfc_tail_ps(a);
  const __m512 tail1p = _mm512_mask_blend_ps(sign_mask(z), _mm512_sub_ps(_mm512_set1_ps(2.0f), tail), tail);
  return _mm512_mask_blend_ps(_mm512_cmp_ps_mask(a, one, _CMP_LT_OQ), tail1p, small1p);
}

// GELU(x) = 0.5 x (1 + erf(x / sqrt 2)), exact erf form.
static inline __m512 gelu_ps(__m512 x) {
  const __m512 z = _mm512_mul_ps(x, _mm512_set1_ps(0.70710678118654752f));
  return _mm512_mul_ps(_mm512_mul_ps(_mm512_set1_ps(0.5f), x), erf1p_ps(z));
}

// x * sigmoid(k x) = x / (1 + exp(-k x)); k = 1 for SiLU, 1.702 for quick GELU.
static inline __m512 x_sigmoid_ps(__m512 x, float k) {
  const __m512 e = exp_ps(_mm512_mul_ps(x, _mm512_set1_ps(-k)));
  return _mm512_div_ps(x, _mm512_add_ps(_mm512_set1_ps(1.0f), e));
}
static inline __m512 silu_ps(__m512 x) { return x_sigmoid_ps(x, 1.0f); }

// Horizontal reductions: the two 256-bit halves combined, then the AVX2 reduction.
// x rounded to the nearest bfloat16 (ties to even), as float32; x finite.
static inline __m512 round_bf16_ps(__m512 x) {
  const __m512i u = _mm512_castps_si512(x);
  const __m512i odd = _mm512_and_si512(_mm512_srli_epi32(u, 16), _mm512_set1_epi32(1));
  const __m512i r = _mm512_add_epi32(_mm512_add_epi32(u, _mm512_set1_epi32(0x7fff)), odd);
  return _mm512_castsi512_ps(_mm512_and_si512(r, _mm512_set1_epi32(int(0xffff0000u))));
}

static inline __m256 low_half(__m512 v) { return _mm512_castps512_ps256(v); }
static inline __m256 high_half(__m512 v) { return _mm512_extractf32x8_ps(v, 1); }
static inline float hsum_ps(__m512 v) { return hsum_ps(_mm256_add_ps(low_half(v), high_half(v))); }
static inline float hmax_ps(__m512 v) { return hmax_ps(_mm256_max_ps(low_half(v), high_half(v))); }
static inline double hsum_pd(__m512d v) {
  return hsum_pd(_mm256_add_pd(_mm512_castpd512_pd256(v), _mm512_extractf64x4_pd(v, 1)));
}

// Mask of the first n (0..16) lanes, for tail loads and stores.
static inline __mmask16 tail_mask16(int64_t n) { return __mmask16((1u << n) - 1u); }

// Calls f(i, m) for each block of 16 floats of [begin, n), m masking its lanes below n: the full blocks with every
// lane (a constant mask: the masked loads and stores compile to plain ones), then the tail, if any.
template <class F>
static inline void for_each_block16(int64_t begin, int64_t n, F f) {
  int64_t i = begin;
  for (; i + 16 <= n; i += 16) f(i, __mmask16(0xffff));
  if (i < n) f(i, tail_mask16(n - i));
}
template <class F>
static inline void for_each_block16(int64_t n, F f) { for_each_block16(0, n, f); }

}  // namespace egopd::vmath
