// AVX-512 re-layout kernel: one block of a batched transpose in 16x16 register transposes; partial blocks use
// masked loads and stores (no scalar edges). A plain copy takes the AVX2 8x8 kernel: measured 1.5x faster on the
// U-Net's [16, 320, 1024] (AMD EPYC, Zen 5 class), where the 16x16 kernel wins 1.8x when adding onto a residual.
#include <cstdint>

#include "core/kernels/avx512/isa.h"

namespace egopd {
namespace avx2 {
void transpose_block(const float* s, int64_t lds, float* d, int64_t ldd, int64_t rows, int64_t cols, bool add);
}

namespace avx512 {

namespace {

inline __mmask16 lanes(int64_t n) { return n >= 16 ? __mmask16(0xffff) : __mmask16((1u << n) - 1u); }

// r[i] (row i, 16 columns) -> r[j] (column j, 16 rows): 4x4 transposes inside each 128-bit lane, then a 4x4
// transpose of the lanes.
inline void transpose16(__m512* r) {
  __m512 s[16];
  for (int g = 0; g < 4; ++g) {
    const __m512 a = _mm512_unpacklo_ps(r[4 * g], r[4 * g + 1]), b = _mm512_unpackhi_ps(r[4 * g], r[4 * g + 1]);
    const __m512 c = _mm512_unpacklo_ps(r[4 * g + 2], r[4 * g + 3]), d = _mm512_unpackhi_ps(r[4 * g + 2], r[4 * g + 3]);
    s[4 * g] = _mm512_shuffle_ps(a, c, 0x44);  // lane L: column 4L of rows 4g..4g+3
    s[4 * g + 1] = _mm512_shuffle_ps(a, c, 0xEE);
    s[4 * g + 2] = _mm512_shuffle_ps(b, d, 0x44);
    s[4 * g + 3] = _mm512_shuffle_ps(b, d, 0xEE);
  }
  for (int j = 0; j < 4; ++j) {  // column 4L + j = lane L of s[j], s[4 + j], s[8 + j], s[12 + j]
    const __m512 p0 = _mm512_shuffle_f32x4(s[j], s[4 + j], 0x44), p1 = _mm512_shuffle_f32x4(s[j], s[4 + j], 0xEE);
    const __m512 p2 = _mm512_shuffle_f32x4(s[8 + j], s[12 + j], 0x44);
    const __m512 p3 = _mm512_shuffle_f32x4(s[8 + j], s[12 + j], 0xEE);
    r[j] = _mm512_shuffle_f32x4(p0, p2, 0x88);
    r[4 + j] = _mm512_shuffle_f32x4(p0, p2, 0xDD);
    r[8 + j] = _mm512_shuffle_f32x4(p1, p3, 0x88);
    r[12 + j] = _mm512_shuffle_f32x4(p1, p3, 0xDD);
  }
}

}  // namespace

// d[c * ldd + r] (+)= s[r * lds + c] for r < rows, c < cols.
void transpose_block(const float* s, int64_t lds, float* d, int64_t ldd, int64_t rows, int64_t cols, bool add) {
  if (!add) return avx2::transpose_block(s, lds, d, ldd, rows, cols, add);
  for (int64_t r0 = 0; r0 < rows; r0 += 16)
    for (int64_t c0 = 0; c0 < cols; c0 += 16) {
      const int64_t nr = rows - r0 < 16 ? rows - r0 : 16, nc = cols - c0 < 16 ? cols - c0 : 16;
      const __mmask16 row_m = lanes(nc), col_m = lanes(nr);
      __m512 v[16];
      for (int i = 0; i < 16; ++i)
        v[i] = i < nr ? _mm512_maskz_loadu_ps(row_m, s + (r0 + i) * lds + c0) : _mm512_setzero_ps();
      transpose16(v);
      for (int j = 0; j < nc; ++j) {
        float* dst = d + (c0 + j) * ldd + r0;
        _mm512_mask_storeu_ps(dst, col_m, add ? _mm512_add_ps(_mm512_maskz_loadu_ps(col_m, dst), v[j]) : v[j]);
      }
    }
}

}  // namespace avx512
}  // namespace egopd
