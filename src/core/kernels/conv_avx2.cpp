// AVX2 implicit-im2col packing: each 16-column row of a B panel is two masked loads of the shifted frame
// (masked-out lanes are never touched, so the zero padding costs nothing and nothing is read out of bounds).
#include <cstdint>

#include "core/kernels/conv_internal.h"

#pragma GCC target("avx2,fma,f16c")
#include <immintrin.h>

namespace egopd::conv_detail {

void pack_im2col_shift_avx2(const float* xf, const ShiftGeom& s, int64_t k0, int64_t kc, int64_t n0, int nr,
                            float* dst) {
  uint16_t masks[kMaxTaps];
  shift_masks(s, n0, nr, masks);
  const int64_t taps = s.kh * s.kw;
  __m256i lo[kMaxTaps], hi[kMaxTaps];
  int64_t offs[kMaxTaps];
  const __m256i bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
  for (int64_t t = 0; t < taps; ++t) {
    const __m256i ml = _mm256_set1_epi32(masks[t] & 0xff), mh = _mm256_set1_epi32(masks[t] >> 8);
    lo[t] = _mm256_cmpeq_epi32(_mm256_and_si256(ml, bit), bit);
    hi[t] = _mm256_cmpeq_epi32(_mm256_and_si256(mh, bit), bit);
    offs[t] = n0 + (t / s.kw - s.ph) * s.w + (t % s.kw - s.pw);
  }
  const int64_t plane = s.h * s.w;
  int64_t c = k0 / taps, t = k0 % taps;
  for (int64_t k = 0; k < kc; ++k) {
    const float* src = xf + c * plane + offs[t];
    _mm256_store_ps(dst + k * 16, _mm256_maskload_ps(src, lo[t]));
    _mm256_store_ps(dst + k * 16 + 8, _mm256_maskload_ps(src + 8, hi[t]));
    if (++t == taps) t = 0, ++c;
  }
}

}  // namespace egopd::conv_detail
