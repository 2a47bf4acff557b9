#pragma once
// Register-level packing helpers shared by the AVX2 and AVX-512 GEMM and convolution files. Include ONLY from
// kernels/avx2/ and kernels/avx512/, after a `#pragma GCC target` enabling at least avx2,fma,f16c and <immintrin.h>
// (core/dtype.h included before the pragma); everything is static (one private copy per file).
#include <immintrin.h>

#include "core/kernels/avx2/transpose.h"

namespace egopd::pack_avx2 {

// 8 consecutive elements starting at element idx, as float32 (I8: before its scale).
static inline __attribute__((always_inline)) __m256 load8(const void* p, DType dt, int64_t idx) {
  if (dt == DType::F32) return _mm256_loadu_ps(static_cast<const float*>(p) + idx);
  if (dt == DType::I8) {
    const __m128i q = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(static_cast<const int8_t*>(p) + idx));
    return _mm256_cvtepi32_ps(_mm256_cvtepi8_epi32(q));
  }
  const __m128i h = _mm_loadu_si128(reinterpret_cast<const __m128i*>(static_cast<const uint16_t*>(p) + idx));
  if (dt == DType::F16) return _mm256_cvtph_ps(h);
  return _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_cvtepu16_epi32(h), 16));  // BF16
}

}  // namespace egopd::pack_avx2
