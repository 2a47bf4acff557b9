// AVX2/FMA element-wise kernels on contiguous spans (the caller splits work across threads).
#include <cstdint>

#pragma GCC target("avx2,fma,f16c")
#include <immintrin.h>

#include "core/kernels/avx2/vec_math.h"

namespace egopd::avx2 {

using namespace egopd::vmath;

namespace {

enum Op { kSilu, kGelu, kQuickGelu, kErf };

template <int OP>
static inline __m256 apply(__m256 v) {
  if (OP == kSilu) return silu_ps(v);
  if (OP == kGelu) return gelu_ps(v);
  if (OP == kQuickGelu) return x_sigmoid_ps(v, 1.702f);
  return erf_ps(v);
}

template <int OP>
static void map_inplace(float* x, int64_t n) {
  int64_t i = 0;
  for (; i + 8 <= n; i += 8) _mm256_storeu_ps(x + i, apply<OP>(_mm256_loadu_ps(x + i)));
  if (i < n) {
    const __m256i m = tail_mask(n - i);
    _mm256_maskstore_ps(x + i, m, apply<OP>(_mm256_maskload_ps(x + i, m)));
  }
}

}  // namespace

void silu_inplace(float* x, int64_t n) { map_inplace<kSilu>(x, n); }
void gelu_inplace(float* x, int64_t n) { map_inplace<kGelu>(x, n); }
void quick_gelu_inplace(float* x, int64_t n) { map_inplace<kQuickGelu>(x, n); }
void erf_inplace(float* x, int64_t n) { map_inplace<kErf>(x, n); }

// One row of GEGLU: out[i] = a[i] * GELU(g[i]).
void geglu_row(const float* a, const float* g, int64_t d, float* out) {
  int64_t i = 0;
  for (; i + 8 <= d; i += 8)
    _mm256_storeu_ps(out + i, _mm256_mul_ps(_mm256_loadu_ps(a + i), gelu_ps(_mm256_loadu_ps(g + i))));
  if (i < d) {
    const __m256i m = tail_mask(d - i);
    _mm256_maskstore_ps(out + i, m, _mm256_mul_ps(_mm256_maskload_ps(a + i, m), gelu_ps(_mm256_maskload_ps(g + i, m))));
  }
}

void blend_inplace(float* y, const float* x, float a, int64_t n) {
  const __m256 va = _mm256_set1_ps(a), vb = _mm256_set1_ps(1.0f - a);
  int64_t i = 0;
  for (; i + 8 <= n; i += 8)
    _mm256_storeu_ps(y + i, _mm256_fmadd_ps(va, _mm256_loadu_ps(x + i), _mm256_mul_ps(vb, _mm256_loadu_ps(y + i))));
  for (; i < n; ++i) y[i] = a * x[i] + (1.0f - a) * y[i];
}

void add_inplace(float* y, const float* x, int64_t n) {
  int64_t i = 0;
  for (; i + 8 <= n; i += 8) _mm256_storeu_ps(y + i, _mm256_add_ps(_mm256_loadu_ps(y + i), _mm256_loadu_ps(x + i)));
  for (; i < n; ++i) y[i] += x[i];
}

}  // namespace egopd::avx2
