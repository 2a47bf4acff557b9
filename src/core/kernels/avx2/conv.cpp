// AVX2 implicit-im2col packing: each 16-column row of a B panel is two masked loads of the shifted frame
// (masked-out lanes are never touched, so the zero padding costs nothing and nothing is read out of bounds).
#include <cstdint>

#include "core/kernels/conv_internal.h"

#pragma GCC target("avx2,fma,f16c")
#include <immintrin.h>

#include "core/kernels/avx2/pack.h"

namespace egopd::conv_detail {

void pack_im2col_shift_avx2(const float* xf, const ShiftGeom& s, int64_t k0, int64_t kc, int64_t n0, int nr,
                            float* dst) {
  uint32_t masks[kMaxTaps];
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
    // The next panel reads the following 64 bytes of the same rows: fetch them into L2 now (each row is its own
    // stream, far more than the hardware prefetchers track).
    _mm_prefetch(reinterpret_cast<const char*>(src + 16), _MM_HINT_T1);
    _mm256_store_ps(dst + k * 16, _mm256_maskload_ps(src, lo[t]));
    _mm256_store_ps(dst + k * 16 + 8, _mm256_maskload_ps(src + 8, hi[t]));
    if (++t == taps) t = 0, ++c;
  }
}

namespace {

using pack_avx2::load8;
using pack_avx2::transpose8;

// dst[k*ld + i] = W[m0 + i, c0 + k, tap] for i < 6 and k < len / 8 * 8 (returned).
__attribute__((always_inline)) inline int64_t temporal6(const void* w, DType dt, int64_t cin, int64_t m0, int64_t tap,
                                                        int64_t c0, int64_t len, int64_t ld, float* dst) {
  // Elements e = tap + 3j (j < 8) of 24 consecutive ones: 3j mod 8 is a permutation, so lane (tap + 3j) mod 8
  // of exactly one of the three loaded vectors holds element j: blend the three, then permute.
  alignas(32) int32_t from1[8], from2[8], perm[8];
  for (int j = 0; j < 8; ++j) {
    const int e = int(tap) + 3 * j, lane = e % 8;
    from1[lane] = e / 8 == 1 ? -1 : 0;
    from2[lane] = e / 8 == 2 ? -1 : 0;
    perm[j] = lane;
  }
  const __m256 m1 = _mm256_castsi256_ps(_mm256_load_si256(reinterpret_cast<const __m256i*>(from1)));
  const __m256 m2 = _mm256_castsi256_ps(_mm256_load_si256(reinterpret_cast<const __m256i*>(from2)));
  const __m256i pidx = _mm256_load_si256(reinterpret_cast<const __m256i*>(perm));
  const int64_t n8 = len / 8 * 8;
  for (int64_t k = 0; k < n8; k += 8) {
    __m256 r[8];
    for (int i = 0; i < 6; ++i) {
      const int64_t base = (m0 + i) * 3 * cin + (c0 + k) * 3;
      const __m256 v0 = load8(w, dt, base), v1 = load8(w, dt, base + 8), v2 = load8(w, dt, base + 16);
      r[i] = _mm256_permutevar8x32_ps(_mm256_blendv_ps(_mm256_blendv_ps(v0, v1, m1), v2, m2), pidx);
    }
    r[6] = r[7] = _mm256_setzero_ps();
    transpose8(r);
    for (int q = 0; q < 8; ++q) {  // column q: lanes 0-5 are the 6 rows
      float* d = dst + (k + q) * ld;
      _mm_storeu_ps(d, _mm256_castps256_ps128(r[q]));
      _mm_storel_pi(reinterpret_cast<__m64*>(d + 4), _mm256_extractf128_ps(r[q], 1));
    }
  }
  return n8;
}

// A panel of 6 * kRuns rows as kRuns runs of temporal6; the dtype is a constant at each call (load8 specialised).
template <int kRuns>
int64_t temporal_panel(const void* w, DType dt, int64_t cin, int64_t m0, int64_t tap, int64_t c0, int64_t len,
                       float* dst) {
  const auto runs = [&](DType d) {
    int64_t done = 0;
    for (int r = 0; r < kRuns; ++r) done = temporal6(w, d, cin, m0 + 6 * r, tap, c0, len, 6 * kRuns, dst + 6 * r);
    return done;
  };
  if (dt == DType::F32) return runs(DType::F32);
  if (dt == DType::F16) return runs(DType::F16);
  if (dt == DType::BF16) return runs(DType::BF16);
  return 0;
}

}  // namespace

int64_t pack_a_temporal6_avx2(const void* w, DType dt, int64_t cin, int64_t m0, int64_t tap, int64_t c0, int64_t len,
                              float* dst) {
  return temporal_panel<1>(w, dt, cin, m0, tap, c0, len, dst);
}

int64_t pack_a_temporal12_avx2(const void* w, DType dt, int64_t cin, int64_t m0, int64_t tap, int64_t c0,
                               int64_t len, float* dst) {
  return temporal_panel<2>(w, dt, cin, m0, tap, c0, len, dst);
}

}  // namespace egopd::conv_detail
