#pragma once
// Vectorised float32 math for AVX2/FMA kernels: exp, erf, 1+erf, SiLU, GELU, horizontal reductions.
// Include ONLY from kernels/avx2/ and kernels/avx512/, after a `#pragma GCC target` enabling at least
// avx2,fma,f16c and <immintrin.h>.
// Every function is `static inline` so each AVX2 translation unit gets its own internal copy (nothing leaks
// into portable code). Polynomial coefficients (vec_math_poly.h, shared with the other paths) are Chebyshev fits
// of the exact functions; accuracy (tested against double precision): exp ~1 ulp, erf and 1+erf a few ulp
// relative over the whole float range. avx512/vec_math.h has the 512-bit counterparts.
#include <immintrin.h>

#include "core/kernels/vec_math_poly.h"

namespace egopd::vmath {

using vmath_poly::kErfcTail;
using vmath_poly::kErfSmall;
using vmath_poly::kExp;

static inline __m256 horner(__m256 x, const float* c, int n) {  // c[0] x^(n-1) + ... + c[n-1]
  __m256 p = _mm256_set1_ps(c[0]);
  for (int i = 1; i < n; ++i) p = _mm256_fmadd_ps(p, x, _mm256_set1_ps(c[i]));
  return p;
}

// exp(x) for x in [-87.34, 88.03] (no range handling): Chebyshev polynomial after x = n ln2 + r.
static inline __m256 exp_core_ps(__m256 x) {
  const __m256 n = _mm256_round_ps(_mm256_mul_ps(x, _mm256_set1_ps(1.44269504088896341f)),
                                   _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
  __m256 r = _mm256_fnmadd_ps(n, _mm256_set1_ps(6.931471825e-01f), x);  // x - n ln2, ln2 split hi + lo
  r = _mm256_fnmadd_ps(n, _mm256_set1_ps(-1.904654212e-09f), r);
  const __m256 p = horner(r, kExp, 5);
  const __m256 y = _mm256_add_ps(_mm256_fmadd_ps(_mm256_mul_ps(r, r), p, r), _mm256_set1_ps(1.0f));
  const __m256i e = _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127)), 23);
  return _mm256_mul_ps(y, _mm256_castsi256_ps(e));
}

// exp(x). Results below 2^-126 flush to 0; above FLT_MAX give +inf; exp(-inf) = 0.
static inline __m256 exp_ps(__m256 x) {
  const __m256 lo_limit = _mm256_set1_ps(-87.33654f), hi_limit = _mm256_set1_ps(88.72283f);
  const __m256 xc = _mm256_min_ps(_mm256_max_ps(x, lo_limit), _mm256_set1_ps(88.02969f));  // keeps n <= 127
  __m256 res = exp_core_ps(xc);
  res = _mm256_andnot_ps(_mm256_cmp_ps(x, lo_limit, _CMP_LT_OQ), res);
  return _mm256_blendv_ps(res, _mm256_set1_ps(__builtin_inff()), _mm256_cmp_ps(x, hi_limit, _CMP_GT_OQ));
}

// exp(x) for x <= 0 (not NaN); results below 2^-126 flush to 0.
static inline __m256 exp_nonpositive_ps(__m256 x) {
  const __m256 lo_limit = _mm256_set1_ps(-87.33654f);
  const __m256 res = exp_core_ps(_mm256_max_ps(x, lo_limit));
  return _mm256_andnot_ps(_mm256_cmp_ps(x, lo_limit, _CMP_LT_OQ), res);
}

// 2^x (same limits as exp_ps): attention folds log2(e) into its query scale and calls this directly.
static inline __m256 exp2_ps(__m256 x) {
  const __m256 lo_limit = _mm256_set1_ps(-126.0f), hi_limit = _mm256_set1_ps(128.0f);
  const __m256 xc = _mm256_min_ps(_mm256_max_ps(x, lo_limit), _mm256_set1_ps(127.0f));
  const __m256 n = _mm256_round_ps(xc, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
  const __m256 r = _mm256_mul_ps(_mm256_sub_ps(xc, n), _mm256_set1_ps(0.693147180559945309f));  // x - n exact
  const __m256 p = horner(r, kExp, 5);
  const __m256 y = _mm256_add_ps(_mm256_fmadd_ps(_mm256_mul_ps(r, r), p, r), _mm256_set1_ps(1.0f));
  const __m256i e = _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127)), 23);
  __m256 res = _mm256_mul_ps(y, _mm256_castsi256_ps(e));
  res = _mm256_andnot_ps(_mm256_cmp_ps(x, lo_limit, _CMP_LT_OQ), res);
  return _mm256_blendv_ps(res, _mm256_set1_ps(__builtin_inff()), _mm256_cmp_ps(x, hi_limit, _CMP_GE_OQ));
}

// erfc(a) for a >= 1 (any a >= 0 gives a finite value): t R(t) exp(-a^2), t = 2/(2+a);
// a^2 = hi + lo exactly and exp(-hi-lo) ~ exp(-hi)(1-lo).
static inline __m256 erfc_tail_ps(__m256 a) {
  const __m256 ac = _mm256_min_ps(a, _mm256_set1_ps(10.0f));
  const __m256 t = _mm256_div_ps(_mm256_set1_ps(2.0f), _mm256_add_ps(_mm256_set1_ps(2.0f), ac));
  const __m256 hi = _mm256_mul_ps(ac, ac);
  const __m256 lo = _mm256_fmsub_ps(ac, ac, hi);
  const __m256 e = exp_nonpositive_ps(_mm256_sub_ps(_mm256_setzero_ps(), hi));
  const __m256 ex = _mm256_fnmadd_ps(e, lo, e);
  return _mm256_mul_ps(_mm256_mul_ps(t, horner(t, kErfcTail, 9)), ex);
}

// erf(a) and erfc(a) for a = |z| >= 0, each accurate relative to its own value.
static inline void erf_erfc_abs(__m256 a, __m256* erf_a, __m256* erfc_a) {
  const __m256 one = _mm256_set1_ps(1.0f);
  const __m256 small = _mm256_mul_ps(a, horner(_mm256_mul_ps(a, a), kErfSmall, 7));  // erf(a), a < 1
  const __m256 tail = erfc_tail_ps(a);                                                 // erfc(a), a >= 1
  const __m256 is_small = _mm256_cmp_ps(a, one, _CMP_LT_OQ);
  *erf_a = _mm256_blendv_ps(_mm256_sub_ps(one, tail), small, is_small);
  *erfc_a = _mm256_blendv_ps(tail, _mm256_sub_ps(one, small), is_small);
}

static inline __m256 sign_bit(__m256 z) { return _mm256_and_ps(z, _mm256_set1_ps(-0.0f)); }
static inline __m256 abs_ps(__m256 z) { return _mm256_andnot_ps(_mm256_set1_ps(-0.0f), z); }

static inline __m256 erf_ps(__m256 z) {
  __m256 e, c;
  erf_erfc_abs(abs_ps(z), &e, &c);
  return _mm256_or_ps(e, sign_bit(z));
}

// 1 + erf(z) without cancellation for negative z (= erfc(|z|) there).
static inline __m256 erf1p_ps(__m256 z) {
  const __m256 one = _mm256_set1_ps(1.0f);
  const __m256 a = abs_ps(z);
  const __m256 small1p = _mm256_fmadd_ps(z, horner(_mm256_mul_ps(z, z), kErfSmall, 7), one);  // |z| < 1
  const __m256 tail = erfc_tail_ps(a);
  const __m256 tail1p = _mm256_blendv_ps(_mm256_sub_ps(_mm256_set1_ps(2.0f), tail), tail, z);  // on z's sign
  return _mm256_blendv_ps(tail1p, small1p, _mm256_cmp_ps(a, one, _CMP_LT_OQ));
}

// GELU(x) = 0.5 x (1 + erf(x / sqrt 2)), exact erf form.
static inline __m256 gelu_ps(__m256 x) {
  const __m256 z = _mm256_mul_ps(x, _mm256_set1_ps(0.70710678118654752f));
  return _mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(0.5f), x), erf1p_ps(z));
}

// x * sigmoid(k x) = x / (1 + exp(-k x)); k = 1 for SiLU, 1.702 for quick GELU.
static inline __m256 x_sigmoid_ps(__m256 x, float k) {
  const __m256 e = exp_ps(_mm256_mul_ps(x, _mm256_set1_ps(-k)));
  return _mm256_div_ps(x, _mm256_add_ps(_mm256_set1_ps(1.0f), e));
}
static inline __m256 silu_ps(__m256 x) { return x_sigmoid_ps(x, 1.0f); }

// x rounded to the nearest bfloat16 (ties to even), as float32; x finite (Precision::Bf16's attention weights).
static inline __m256 round_bf16_ps(__m256 x) {
  const __m256i u = _mm256_castps_si256(x);
  const __m256i odd = _mm256_and_si256(_mm256_srli_epi32(u, 16), _mm256_set1_epi32(1));
  const __m256i r = _mm256_add_epi32(_mm256_add_epi32(u, _mm256_set1_epi32(0x7fff)), odd);
  return _mm256_castsi256_ps(_mm256_and_si256(r, _mm256_set1_epi32(int(0xffff0000u))));
}

static inline float hsum_ps(__m256 v) {
  __m128 s = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
  s = _mm_add_ps(s, _mm_movehl_ps(s, s));
  s = _mm_add_ss(s, _mm_movehdup_ps(s));
  return _mm_cvtss_f32(s);
}

static inline float hmax_ps(__m256 v) {
  __m128 s = _mm_max_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
  s = _mm_max_ps(s, _mm_movehl_ps(s, s));
  s = _mm_max_ss(s, _mm_movehdup_ps(s));
  return _mm_cvtss_f32(s);
}

static inline double hsum_pd(__m256d v) {
  __m128d s = _mm_add_pd(_mm256_castpd256_pd128(v), _mm256_extractf128_pd(v, 1));
  s = _mm_add_sd(s, _mm_unpackhi_pd(s, s));
  return _mm_cvtsd_f64(s);
}

// Mask with the first n (0..8) lanes set, for tail loads/stores.
static inline __m256i tail_mask(long n) {
  static const int kLanes[16] = {-1, -1, -1, -1, -1, -1, -1, -1, 0, 0, 0, 0, 0, 0, 0, 0};
  return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(kLanes + 8 - n));
}

}  // namespace egopd::vmath
