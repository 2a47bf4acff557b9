// AVX2 re-layout kernel: one block of a batched transpose in 8x8 register transposes, scalar edges.
#include <cstdint>

#pragma GCC target("avx2,fma,f16c")
#include <immintrin.h>

#include "core/kernels/avx2/transpose.h"

namespace egopd::avx2 {

// d[c * ldd + r] (+)= s[r * lds + c] for r < rows, c < cols.
void transpose_block(const float* s, int64_t lds, float* d, int64_t ldd, int64_t rows, int64_t cols, bool add) {
  const int64_t rows8 = rows / 8 * 8, cols8 = cols / 8 * 8;
  for (int64_t r0 = 0; r0 < rows8; r0 += 8)
    for (int64_t c0 = 0; c0 < cols8; c0 += 8) {
      __m256 v[8];
      for (int i = 0; i < 8; ++i) v[i] = _mm256_loadu_ps(s + (r0 + i) * lds + c0);
      pack_avx2::transpose8(v);
      for (int j = 0; j < 8; ++j) {
        float* dst = d + (c0 + j) * ldd + r0;
        _mm256_storeu_ps(dst, add ? _mm256_add_ps(_mm256_loadu_ps(dst), v[j]) : v[j]);
      }
    }
  for (int64_t r = 0; r < rows; ++r)  // the edges: columns from cols8 in the 8-row blocks, every column below them
    for (int64_t c = r < rows8 ? cols8 : 0; c < cols; ++c) {
      float* dst = d + c * ldd + r;
      *dst = add ? *dst + s[r * lds + c] : s[r * lds + c];
    }
}

}  // namespace egopd::avx2
