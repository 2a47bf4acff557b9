// AVX-512 row kernels for the normalisations (the caller splits work across threads): the algorithms of
// avx2/norm.cpp in 512-bit registers, tails by masked loads and stores (masked-off lanes add zeros to the sums).
// Only reached through the avx512 kernel path.
#include <cstdint>

#include "core/kernels/avx512/isa.h"

#include "core/kernels/avx512/vec_math.h"

namespace egopd::avx512 {

using namespace egopd::vmath;

// Accumulates sum(x - shift) and sum((x - shift)^2) over n floats in double precision.
void shifted_sums(const float* x, int64_t n, double shift, double* sum, double* sumsq) {
  const __m512d k = _mm512_set1_pd(shift);
  __m512d s0 = _mm512_setzero_pd(), s1 = s0, q0 = s0, q1 = s0;
  for_each_block16(n, [&](int64_t i, __mmask16 m) {
    const __m512 v = _mm512_maskz_loadu_ps(m, x + i);
    const __m512d d0 = _mm512_maskz_sub_pd(__mmask8(m), _mm512_cvtps_pd(low_half(v)), k);
    const __m512d d1 = _mm512_maskz_sub_pd(__mmask8(m >> 8), _mm512_cvtps_pd(high_half(v)), k);
    s0 = _mm512_add_pd(s0, d0), s1 = _mm512_add_pd(s1, d1);
    q0 = _mm512_fmadd_pd(d0, d0, q0), q1 = _mm512_fmadd_pd(d1, d1, q1);
  });
  *sum += hsum_pd(_mm512_add_pd(s0, s1)), *sumsq += hsum_pd(_mm512_add_pd(q0, q1));
}

// y = (x - mean) * scale + shift, optionally followed by SiLU.
void affine_span(const float* x, float* y, int64_t n, float mean, float scale, float shift, bool silu) {
  const __m512 m0 = _mm512_set1_ps(mean), a = _mm512_set1_ps(scale), b = _mm512_set1_ps(shift);
  const auto affine = [&](int64_t i, __mmask16 m) {
    return _mm512_fmadd_ps(_mm512_sub_ps(_mm512_maskz_loadu_ps(m, x + i), m0), a, b);
  };
  if (silu)
    for_each_block16(n, [&](int64_t i, __mmask16 m) { _mm512_mask_storeu_ps(y + i, m, silu_ps(affine(i, m))); });
  else
    for_each_block16(n, [&](int64_t i, __mmask16 m) { _mm512_mask_storeu_ps(y + i, m, affine(i, m)); });
}

// LayerNorm of one row: pass 1 a float mean m0 (four accumulators); pass 2 sums d = x - m0 and d^2, which corrects
// the mean (m = m0 + mean(d)) and gives the biased variance mean(d^2) - mean(d)^2 without cancellation.
void layer_norm_row(const float* x, float* y, int64_t c, const float* gamma, const float* beta, float eps) {
  __m512 s0 = _mm512_setzero_ps(), s1 = s0, s2 = s0, s3 = s0;
  int64_t i = 0;
  for (; i + 64 <= c; i += 64) {
    s0 = _mm512_add_ps(s0, _mm512_loadu_ps(x + i)), s1 = _mm512_add_ps(s1, _mm512_loadu_ps(x + i + 16));
    s2 = _mm512_add_ps(s2, _mm512_loadu_ps(x + i + 32)), s3 = _mm512_add_ps(s3, _mm512_loadu_ps(x + i + 48));
  }
  for_each_block16(i, c, [&](int64_t j, __mmask16 m) { s0 = _mm512_add_ps(s0, _mm512_maskz_loadu_ps(m, x + j)); });
  const float inv_c = 1.0f / static_cast<float>(c);
  const float m0 = hsum_ps(_mm512_add_ps(_mm512_add_ps(s0, s1), _mm512_add_ps(s2, s3))) * inv_c;

  const __m512 vm0 = _mm512_set1_ps(m0);
  __m512 d0 = _mm512_setzero_ps(), d1 = d0, q0 = d0, q1 = d0;
  for (i = 0; i + 32 <= c; i += 32) {
    const __m512 a = _mm512_sub_ps(_mm512_loadu_ps(x + i), vm0), b = _mm512_sub_ps(_mm512_loadu_ps(x + i + 16), vm0);
    d0 = _mm512_add_ps(d0, a), d1 = _mm512_add_ps(d1, b);
    q0 = _mm512_fmadd_ps(a, a, q0), q1 = _mm512_fmadd_ps(b, b, q1);
  }
  for_each_block16(i, c, [&](int64_t j, __mmask16 m) {
    const __m512 a = _mm512_maskz_sub_ps(m, _mm512_maskz_loadu_ps(m, x + j), vm0);
    d0 = _mm512_add_ps(d0, a), q0 = _mm512_fmadd_ps(a, a, q0);
  });
  const float dmean = hsum_ps(_mm512_add_ps(d0, d1)) * inv_c;
  const float var = hsum_ps(_mm512_add_ps(q0, q1)) * inv_c - dmean * dmean;
  const __m512 vm = _mm512_set1_ps(m0 + dmean);
  const __m512 rstd = _mm512_set1_ps(1.0f / __builtin_sqrtf((var > 0.0f ? var : 0.0f) + eps));

  for_each_block16(c, [&](int64_t j, __mmask16 m) {
    __m512 v = _mm512_mul_ps(_mm512_sub_ps(_mm512_maskz_loadu_ps(m, x + j), vm), rstd);
    if (gamma) v = _mm512_mul_ps(v, _mm512_maskz_loadu_ps(m, gamma + j));
    if (beta) v = _mm512_add_ps(v, _mm512_maskz_loadu_ps(m, beta + j));
    _mm512_mask_storeu_ps(y + j, m, v);
  });
}

// Stable softmax of one row in place: max, exp(x - max) with the sum, scale by 1/sum.
void softmax_row(float* x, int64_t n) {
  const __m512 ninf = _mm512_set1_ps(-__builtin_inff());
  __m512 mx = ninf;
  for_each_block16(n, [&](int64_t i, __mmask16 m) { mx = _mm512_max_ps(mx, _mm512_mask_loadu_ps(ninf, m, x + i)); });
  const __m512 vmax = _mm512_set1_ps(hmax_ps(mx));
  __m512 sum = _mm512_setzero_ps();
  for_each_block16(n, [&](int64_t i, __mmask16 m) {
    const __m512 e = _mm512_maskz_mov_ps(m, exp_ps(_mm512_sub_ps(_mm512_maskz_loadu_ps(m, x + i), vmax)));
    _mm512_mask_storeu_ps(x + i, m, e);
    sum = _mm512_add_ps(sum, e);
  });
  const __m512 inv = _mm512_set1_ps(1.0f / hsum_ps(sum));
  for_each_block16(n, [&](int64_t i, __mmask16 m) {
    _mm512_mask_storeu_ps(x + i, m, _mm512_mul_ps(_mm512_maskz_loadu_ps(m, x + i), inv));
  });
}

}  // namespace egopd::avx512
