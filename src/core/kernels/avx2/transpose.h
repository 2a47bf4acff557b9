#pragma once
// 8x8 float transpositions in ymm registers (packing, attention query tiles, re-layouts). Include ONLY from
// kernels/avx2/ and kernels/avx512/, after a `#pragma GCC target` enabling at least avx2 and <immintrin.h>.
#include <immintrin.h>

#include <cstdint>

namespace egopd::pack_avx2 {

// r[i] (row i, 8 columns) -> r[j] (column j, 8 rows).
static inline __attribute__((always_inline)) void transpose8(__m256* r) {
  const __m256 t0 = _mm256_unpacklo_ps(r[0], r[1]), t1 = _mm256_unpackhi_ps(r[0], r[1]);
  const __m256 t2 = _mm256_unpacklo_ps(r[2], r[3]), t3 = _mm256_unpackhi_ps(r[2], r[3]);
  const __m256 t4 = _mm256_unpacklo_ps(r[4], r[5]), t5 = _mm256_unpackhi_ps(r[4], r[5]);
  const __m256 t6 = _mm256_unpacklo_ps(r[6], r[7]), t7 = _mm256_unpackhi_ps(r[6], r[7]);
  const __m256 s0 = _mm256_shuffle_ps(t0, t2, 0x44), s1 = _mm256_shuffle_ps(t0, t2, 0xEE);
  const __m256 s2 = _mm256_shuffle_ps(t1, t3, 0x44), s3 = _mm256_shuffle_ps(t1, t3, 0xEE);
  const __m256 s4 = _mm256_shuffle_ps(t4, t6, 0x44), s5 = _mm256_shuffle_ps(t4, t6, 0xEE);
  const __m256 s6 = _mm256_shuffle_ps(t5, t7, 0x44), s7 = _mm256_shuffle_ps(t5, t7, 0xEE);
  r[0] = _mm256_permute2f128_ps(s0, s4, 0x20);
  r[1] = _mm256_permute2f128_ps(s1, s5, 0x20);
  r[2] = _mm256_permute2f128_ps(s2, s6, 0x20);
  r[3] = _mm256_permute2f128_ps(s3, s7, 0x20);
  r[4] = _mm256_permute2f128_ps(s0, s4, 0x31);
  r[5] = _mm256_permute2f128_ps(s1, s5, 0x31);
  r[6] = _mm256_permute2f128_ps(s2, s6, 0x31);
  r[7] = _mm256_permute2f128_ps(s3, s7, 0x31);
}

// dst[d][i] = c * src[i][d] for an 8x8 block (src rows at stride ld, dst rows at stride dst_ld).
static inline void transpose8_scaled(const float* src, int64_t ld, __m256 c, float* dst, int64_t dst_ld) {
  __m256 r[8];
  for (int i = 0; i < 8; ++i) r[i] = _mm256_loadu_ps(src + i * ld);
  transpose8(r);
  for (int i = 0; i < 8; ++i) _mm256_storeu_ps(dst + i * dst_ld, _mm256_mul_ps(r[i], c));
}

// dst[d][i] = c * src[i][d] for i < rows, d < cols (src rows at stride ld), and dst[d][i] = 0 for rows <= i < pad
// (dst rows at stride dst_ld): 8x8 register blocks, scalar edges.
static inline void transpose_scaled(const float* src, int64_t ld, int64_t rows, int64_t cols, float c, float* dst,
                                    int64_t dst_ld, int64_t pad) {
  const int64_t rows8 = rows / 8 * 8, cols8 = cols / 8 * 8;
  const __m256 vc = _mm256_set1_ps(c);
  for (int64_t i = 0; i < rows8; i += 8)
    for (int64_t d = 0; d < cols8; d += 8) transpose8_scaled(src + i * ld + d, ld, vc, dst + d * dst_ld + i, dst_ld);
  for (int64_t d = 0; d < cols; ++d) {
    float* row = dst + d * dst_ld;
    for (int64_t i = d < cols8 ? rows8 : 0; i < rows; ++i) row[i] = src[i * ld + d] * c;
    for (int64_t i = rows; i < pad; ++i) row[i] = 0.0f;
  }
}

}  // namespace egopd::pack_avx2
