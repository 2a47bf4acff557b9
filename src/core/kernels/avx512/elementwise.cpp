// AVX-512 element-wise kernels on contiguous spans (the caller splits work across threads): the avx2 kernels in
// 512-bit registers, tails by masked loads and stores. Only reached through the avx512 kernel path.
#include <cstdint>

#include "core/kernels/avx512/isa.h"

#include "core/kernels/avx512/vec_math.h"

namespace egopd::avx512 {

using namespace egopd::vmath;

namespace {

// x[i] = f(x[i]) for i < n.
template <class F>
void map_inplace(float* x, int64_t n, F f) {
  for_each_block16(n, [&](int64_t i, __mmask16 m) {
    _mm512_mask_storeu_ps(x + i, m, f(_mm512_maskz_loadu_ps(m, x + i)));
  });
}

}  // namespace

void silu_inplace(float* x, int64_t n) { map_inplace(x, n, [](__m512 v) { return silu_ps(v); }); }
void gelu_inplace(float* x, int64_t n) { map_inplace(x, n, [](__m512 v) { return gelu_ps(v); }); }
void quick_gelu_inplace(float* x, int64_t n) { map_inplace(x, n, [](__m512 v) { return x_sigmoid_ps(v, 1.702f); }); }
void erf_inplace(float* x, int64_t n) { map_inplace(x, n, [](__m512 v) { return erf_ps(v); }); }

// One row of GEGLU: out[i] = a[i] * GELU(g[i]).
void geglu_row(const float* a, const float* g, int64_t d, float* out) {
  for_each_block16(d, [&](int64_t i, __mmask16 m) {
    const __m512 v = _mm512_mul_ps(_mm512_maskz_loadu_ps(m, a + i), gelu_ps(_mm512_maskz_loadu_ps(m, g + i)));
    _mm512_mask_storeu_ps(out + i, m, v);
  });
}

// y = a x + (1 - a) y.
void blend_inplace(float* y, const float* x, float a, int64_t n) {
  const __m512 va = _mm512_set1_ps(a), vb = _mm512_set1_ps(1.0f - a);
  for_each_block16(n, [&](int64_t i, __mmask16 m) {
    const __m512 xv = _mm512_maskz_loadu_ps(m, x + i), yv = _mm512_maskz_loadu_ps(m, y + i);
    _mm512_mask_storeu_ps(y + i, m, _mm512_fmadd_ps(va, xv, _mm512_mul_ps(vb, yv)));
  });
}

void add_inplace(float* y, const float* x, int64_t n) {
  for_each_block16(n, [&](int64_t i, __mmask16 m) {
    _mm512_mask_storeu_ps(y + i, m, _mm512_add_ps(_mm512_maskz_loadu_ps(m, y + i), _mm512_maskz_loadu_ps(m, x + i)));
  });
}

}  // namespace egopd::avx512
