// AVX2/FMA row kernels for the normalisations (the caller splits work across threads).
#include <cstdint>

#pragma GCC target("avx2,fma,f16c")
#include <immintrin.h>

#include "core/kernels/avx2/vec_math.h"

namespace egopd::avx2 {

using namespace egopd::vmath;

// Accumulates sum(x - shift) and sum((x - shift)^2) over n floats in double precision.
void shifted_sums(const float* x, int64_t n, double shift, double* sum, double* sumsq) {
  const __m256d k = _mm256_set1_pd(shift);
  __m256d s0 = _mm256_setzero_pd(), s1 = s0, q0 = s0, q1 = s0;
  int64_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256 v = _mm256_loadu_ps(x + i);
    const __m256d d0 = _mm256_sub_pd(_mm256_cvtps_pd(_mm256_castps256_ps128(v)), k);
    const __m256d d1 = _mm256_sub_pd(_mm256_cvtps_pd(_mm256_extractf128_ps(v, 1)), k);
    s0 = _mm256_add_pd(s0, d0), s1 = _mm256_add_pd(s1, d1);
    q0 = _mm256_fmadd_pd(d0, d0, q0), q1 = _mm256_fmadd_pd(d1, d1, q1);
  }
  double s = hsum_pd(_mm256_add_pd(s0, s1)), q = hsum_pd(_mm256_add_pd(q0, q1));
  for (; i < n; ++i) {
    const double d = static_cast<double>(x[i]) - shift;
    s += d, q += d * d;
  }
  *sum += s, *sumsq += q;
}

// y = (x - mean) * scale + shift, optionally followed by SiLU.
void affine_span(const float* x, float* y, int64_t n, float mean, float scale, float shift, bool silu) {
  const __m256 m0 = _mm256_set1_ps(mean), a = _mm256_set1_ps(scale), b = _mm256_set1_ps(shift);
  int64_t i = 0;
  if (silu) {
    for (; i + 8 <= n; i += 8)
      _mm256_storeu_ps(y + i, silu_ps(_mm256_fmadd_ps(_mm256_sub_ps(_mm256_loadu_ps(x + i), m0), a, b)));
  } else {
    for (; i + 8 <= n; i += 8)
      _mm256_storeu_ps(y + i, _mm256_fmadd_ps(_mm256_sub_ps(_mm256_loadu_ps(x + i), m0), a, b));
  }
  if (i < n) {
    const __m256i m = tail_mask(n - i);
    __m256 v = _mm256_fmadd_ps(_mm256_sub_ps(_mm256_maskload_ps(x + i, m), m0), a, b);
    if (silu) v = silu_ps(v);
    _mm256_maskstore_ps(y + i, m, v);
  }
}

// LayerNorm of one row: pass 1 a float mean m0; pass 2 sums d = x - m0 and d^2 (4-way accumulators), which
// corrects the mean (m = m0 + mean(d)) and gives the biased variance mean(d^2) - mean(d)^2 without cancellation.
void layer_norm_row(const float* x, float* y, int64_t c, const float* gamma, const float* beta, float eps) {
  __m256 s0 = _mm256_setzero_ps(), s1 = s0, s2 = s0, s3 = s0;
  int64_t i = 0;
  for (; i + 32 <= c; i += 32) {
    s0 = _mm256_add_ps(s0, _mm256_loadu_ps(x + i)), s1 = _mm256_add_ps(s1, _mm256_loadu_ps(x + i + 8));
    s2 = _mm256_add_ps(s2, _mm256_loadu_ps(x + i + 16)), s3 = _mm256_add_ps(s3, _mm256_loadu_ps(x + i + 24));
  }
  for (; i + 8 <= c; i += 8) s0 = _mm256_add_ps(s0, _mm256_loadu_ps(x + i));
  if (i < c) s1 = _mm256_add_ps(s1, _mm256_maskload_ps(x + i, tail_mask(c - i)));
  const float inv_c = 1.0f / static_cast<float>(c);
  const float m0 = hsum_ps(_mm256_add_ps(_mm256_add_ps(s0, s1), _mm256_add_ps(s2, s3))) * inv_c;

  const __m256 vm0 = _mm256_set1_ps(m0);
  __m256 d0 = _mm256_setzero_ps(), d1 = d0, q0 = d0, q1 = d0;
  for (i = 0; i + 16 <= c; i += 16) {
    const __m256 a = _mm256_sub_ps(_mm256_loadu_ps(x + i), vm0), b = _mm256_sub_ps(_mm256_loadu_ps(x + i + 8), vm0);
    d0 = _mm256_add_ps(d0, a), d1 = _mm256_add_ps(d1, b);
    q0 = _mm256_fmadd_ps(a, a, q0), q1 = _mm256_fmadd_ps(b, b, q1);
  }
  for (; i + 8 <= c; i += 8) {
    const __m256 a = _mm256_sub_ps(_mm256_loadu_ps(x + i), vm0);
    d0 = _mm256_add_ps(d0, a), q0 = _mm256_fmadd_ps(a, a, q0);
  }
  if (i < c) {
    const __m256i m = tail_mask(c - i);
    const __m256 a = _mm256_and_ps(_mm256_sub_ps(_mm256_maskload_ps(x + i, m), vm0), _mm256_castsi256_ps(m));
    d1 = _mm256_add_ps(d1, a), q1 = _mm256_fmadd_ps(a, a, q1);
  }
  const float dmean = hsum_ps(_mm256_add_ps(d0, d1)) * inv_c;
  const float var = hsum_ps(_mm256_add_ps(q0, q1)) * inv_c - dmean * dmean;
  const __m256 vm = _mm256_set1_ps(m0 + dmean);
  const __m256 rstd = _mm256_set1_ps(1.0f / __builtin_sqrtf((var > 0.0f ? var : 0.0f) + eps));

  for (i = 0; i + 8 <= c; i += 8) {
    __m256 v = _mm256_mul_ps(_mm256_sub_ps(_mm256_loadu_ps(x + i), vm), rstd);
    if (gamma) v = _mm256_mul_ps(v, _mm256_loadu_ps(gamma + i));
    if (beta) v = _mm256_add_ps(v, _mm256_loadu_ps(beta + i));
    _mm256_storeu_ps(y + i, v);
  }
  if (i < c) {
    const __m256i m = tail_mask(c - i);
    __m256 v = _mm256_mul_ps(_mm256_sub_ps(_mm256_maskload_ps(x + i, m), vm), rstd);
    if (gamma) v = _mm256_mul_ps(v, _mm256_maskload_ps(gamma + i, m));
    if (beta) v = _mm256_add_ps(v, _mm256_maskload_ps(beta + i, m));
    _mm256_maskstore_ps(y + i, m, v);
  }
}

// Stable softmax of one row in place: max, exp(x - max) with the sum, scale by 1/sum.
void softmax_row(float* x, int64_t n) {
  const __m256 ninf = _mm256_set1_ps(-__builtin_inff());
  __m256 mx = ninf;
  int64_t i = 0;
  for (; i + 8 <= n; i += 8) mx = _mm256_max_ps(mx, _mm256_loadu_ps(x + i));
  const __m256i tm = tail_mask(n - i);
  if (i < n) mx = _mm256_max_ps(mx, _mm256_blendv_ps(ninf, _mm256_maskload_ps(x + i, tm), _mm256_castsi256_ps(tm)));
  const __m256 vmax = _mm256_set1_ps(hmax_ps(mx));
  __m256 sum = _mm256_setzero_ps();
  for (i = 0; i + 8 <= n; i += 8) {
    const __m256 e = exp_ps(_mm256_sub_ps(_mm256_loadu_ps(x + i), vmax));
    _mm256_storeu_ps(x + i, e);
    sum = _mm256_add_ps(sum, e);
  }
  if (i < n) {
    const __m256 e = _mm256_and_ps(exp_ps(_mm256_sub_ps(_mm256_maskload_ps(x + i, tm), vmax)), _mm256_castsi256_ps(tm));
    _mm256_maskstore_ps(x + i, tm, e);
    sum = _mm256_add_ps(sum, e);
  }
  const __m256 inv = _mm256_set1_ps(1.0f / hsum_ps(sum));
  for (i = 0; i + 8 <= n; i += 8) _mm256_storeu_ps(x + i, _mm256_mul_ps(_mm256_loadu_ps(x + i), inv));
  if (i < n) _mm256_maskstore_ps(x + i, tm, _mm256_mul_ps(_mm256_maskload_ps(x + i, tm), inv));
}

}  // namespace egopd::avx2
