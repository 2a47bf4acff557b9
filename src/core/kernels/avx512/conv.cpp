// AVX-512 implicit-im2col packing: each 32-column row of a B panel is two masked loads of the shifted frame (the
// validity bits of the tap are the load masks: padding costs nothing and nothing outside the frame is read).
#include <cstdint>

#include "core/kernels/conv_internal.h"
#include "core/kernels/gemm_internal.h"

#pragma GCC target("avx512f,avx512bw,avx512vl,avx512dq,avx2,fma,f16c")
#include <immintrin.h>

namespace egopd::conv_detail {

void pack_im2col_shift_avx512(const float* xf, const ShiftGeom& s, int64_t k0, int64_t kc, int64_t n0, int nr,
                              float* dst) {
  constexpr int NR = gemm_detail::kNrAvx512;
  uint32_t masks[kMaxTaps];
  shift_masks(s, n0, nr, masks);
  const int64_t taps = s.kh * s.kw;
  int64_t offs[kMaxTaps];
  for (int64_t t = 0; t < taps; ++t) offs[t] = n0 + (t / s.kw - s.ph) * s.w + (t % s.kw - s.pw);
  const int64_t plane = s.h * s.w;
  int64_t c = k0 / taps, t = k0 % taps;
  for (int64_t k = 0; k < kc; ++k) {
    const float* src = xf + c * plane + offs[t];
    // The next panel reads the following 64 bytes of the same rows: fetch them into L2 now (each row is its own
    // stream, far more than the hardware prefetchers track).
    _mm_prefetch(reinterpret_cast<const char*>(src + NR), _MM_HINT_T1);
    _mm_prefetch(reinterpret_cast<const char*>(src + NR + 16), _MM_HINT_T1);
    _mm512_store_ps(dst + k * NR, _mm512_maskz_loadu_ps(__mmask16(masks[t]), src));
    _mm512_store_ps(dst + k * NR + 16, _mm512_maskz_loadu_ps(__mmask16(masks[t] >> 16), src + 16));
    if (++t == taps) t = 0, ++c;
  }
}

}  // namespace egopd::conv_detail
