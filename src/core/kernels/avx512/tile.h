#pragma once
// The AVX-512 micro-tile (12 x 32: twenty-four named zmm accumulators) and its epilogue, shared by the GEMM
// micro-kernels (gemm.cpp) and the direct 3x3 convolution (conv.cpp). Include ONLY from kernels/avx512/, after
// the `#pragma GCC target` of those files and <immintrin.h>; everything is file-local.
#include <cstdint>

#include "core/kernels/avx512/vec_math.h"
#include "core/kernels/gemm_internal.h"

namespace egopd::gemm_detail {
namespace {

constexpr int MR = kMrAvx512, NR = kNrAvx512;

inline __mmask16 lanes(int n) { return n <= 0 ? __mmask16(0) : n >= 16 ? __mmask16(0xffff) : __mmask16((1u << n) - 1u); }

// The activations of the AVX2 path (vec_math.h: the same per-lane operations, so both paths round alike).
inline __m512 act_ps(Act act, __m512 v) {
  switch (act) {
    case Act::SiLU: return vmath::silu_ps(v);
    case Act::GELU: return vmath::gelu_ps(v);
    case Act::QuickGELU: return vmath::x_sigmoid_ps(v, 1.702f);
    default: return v;
  }
}

// 16 columns of row i of the tile (mask m of the valid ones), old = C's previous values (zero when not read):
// C = act(v + old? + bias) + old?.
inline void store16(float* c, const float* bias_col, __m512 v, __m512 old, int i, __mmask16 m, const TileEpilogue& ep) {
  if (!m) return;
  if (ep.load_c) v = _mm512_add_ps(v, old);
  if (ep.bias_row) v = _mm512_add_ps(v, _mm512_set1_ps(ep.bias_row[i]));
  if (bias_col) v = _mm512_add_ps(v, _mm512_maskz_loadu_ps(m, bias_col));
  if (ep.act != Act::None) v = act_ps(ep.act, v);
  if (ep.add_after) v = _mm512_add_ps(v, old);
  _mm512_mask_storeu_ps(c, m, v);
}

// The tile's MR x NR sum (row-major) into C, mr x nr of it. Every row of C is read before any is written: with a
// row stride that is a multiple of 4 KiB, a load of row i + 1 issued behind the store to row i can be taken for a
// read of that store and wait for it (bench gemm, AMD EPYC Zen 5 class: +0.5-2.7% on four multi-pass shapes).
inline void store_tile(const float* sum, float* c, int64_t ldc, int mr, int nr, const TileEpilogue& ep) {
  const __mmask16 m0 = lanes(nr), m1 = lanes(nr - 16);
  const float* bias_col1 = ep.bias_col ? ep.bias_col + 16 : nullptr;
  __m512 old[2 * MR];
  const bool read = ep.load_c || ep.add_after;
  for (int i = 0; i < mr; ++i) {
    old[2 * i] = read ? _mm512_maskz_loadu_ps(m0, c + i * ldc) : _mm512_setzero_ps();
    old[2 * i + 1] = read ? _mm512_maskz_loadu_ps(m1, c + i * ldc + 16) : _mm512_setzero_ps();
  }
  for (int i = 0; i < mr; ++i) {
    store16(c + i * ldc, ep.bias_col, _mm512_load_ps(sum + i * NR), old[2 * i], i, m0, ep);
    store16(c + i * ldc + 16, bias_col1, _mm512_load_ps(sum + i * NR + 16), old[2 * i + 1], i, m1, ep);
  }
}

inline void prefetch_c(const float* c, int64_t ldc, int mr) { prefetch_c_rows(c, ldc, mr, 16); }

// Twenty-four named accumulators (an array of vectors would live in memory): row i of the tile is (c<i>0, c<i>1).
#define EGOPD_ROWS(X) X(0) X(1) X(2) X(3) X(4) X(5) X(6) X(7) X(8) X(9) X(10) X(11)
#define EGOPD_DECLARE(i) __m512 c##i##0 = _mm512_setzero_ps(), c##i##1 = _mm512_setzero_ps();
// Row i of the tile += A_AT(i) (defined at each use) times the two B vectors b0, b1.
#define EGOPD_FMA(i)                            \
  {                                             \
    const __m512 av = _mm512_set1_ps(A_AT(i));  \
    c##i##0 = _mm512_fmadd_ps(av, b0, c##i##0); \
    c##i##1 = _mm512_fmadd_ps(av, b1, c##i##1); \
  }

}  // namespace
}  // namespace egopd::gemm_detail
