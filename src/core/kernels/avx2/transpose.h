#pragma once
// An 8x8 float transposition in ymm registers (the attention kernels pack their query tiles with it). Include ONLY
// from kernels/avx2/ and kernels/avx512/, after a `#pragma GCC target` enabling at least avx2 and <immintrin.h>.
#include <immintrin.h>

#include <cstdint>

namespace egopd::avx2 {

// dst[d][i] = c * src[i][d] for an 8x8 block (src rows at stride ld, dst rows at stride dst_ld).
static inline void transpose8_scaled(const float* src, int64_t ld, __m256 c, float* dst, int64_t dst_ld) {
  __m256 r0 = _mm256_loadu_ps(src), r1 = _mm256_loadu_ps(src + ld), r2 = _mm256_loadu_ps(src + 2 * ld),
         r3 = _mm256_loadu_ps(src + 3 * ld), r4 = _mm256_loadu_ps(src + 4 * ld), r5 = _mm256_loadu_ps(src + 5 * ld),
         r6 = _mm256_loadu_ps(src + 6 * ld), r7 = _mm256_loadu_ps(src + 7 * ld);
  const __m256 t0 = _mm256_unpacklo_ps(r0, r1), t1 = _mm256_unpackhi_ps(r0, r1), t2 = _mm256_unpacklo_ps(r2, r3),
               t3 = _mm256_unpackhi_ps(r2, r3), t4 = _mm256_unpacklo_ps(r4, r5), t5 = _mm256_unpackhi_ps(r4, r5),
               t6 = _mm256_unpacklo_ps(r6, r7), t7 = _mm256_unpackhi_ps(r6, r7);
  const __m256 u0 = _mm256_shuffle_ps(t0, t2, 0x44), u1 = _mm256_shuffle_ps(t0, t2, 0xEE),
               u2 = _mm256_shuffle_ps(t1, t3, 0x44), u3 = _mm256_shuffle_ps(t1, t3, 0xEE),
               u4 = _mm256_shuffle_ps(t4, t6, 0x44), u5 = _mm256_shuffle_ps(t4, t6, 0xEE),
               u6 = _mm256_shuffle_ps(t5, t7, 0x44), u7 = _mm256_shuffle_ps(t5, t7, 0xEE);
  r0 = _mm256_permute2f128_ps(u0, u4, 0x20), r1 = _mm256_permute2f128_ps(u1, u5, 0x20);
  r2 = _mm256_permute2f128_ps(u2, u6, 0x20), r3 = _mm256_permute2f128_ps(u3, u7, 0x20);
  r4 = _mm256_permute2f128_ps(u0, u4, 0x31), r5 = _mm256_permute2f128_ps(u1, u5, 0x31);
  r6 = _mm256_permute2f128_ps(u2, u6, 0x31), r7 = _mm256_permute2f128_ps(u3, u7, 0x31);
  _mm256_storeu_ps(dst, _mm256_mul_ps(r0, c)), _mm256_storeu_ps(dst + dst_ld, _mm256_mul_ps(r1, c));
  _mm256_storeu_ps(dst + 2 * dst_ld, _mm256_mul_ps(r2, c)), _mm256_storeu_ps(dst + 3 * dst_ld, _mm256_mul_ps(r3, c));
  _mm256_storeu_ps(dst + 4 * dst_ld, _mm256_mul_ps(r4, c)), _mm256_storeu_ps(dst + 5 * dst_ld, _mm256_mul_ps(r5, c));
  _mm256_storeu_ps(dst + 6 * dst_ld, _mm256_mul_ps(r6, c)), _mm256_storeu_ps(dst + 7 * dst_ld, _mm256_mul_ps(r7, c));
}

}  // namespace egopd::avx2
