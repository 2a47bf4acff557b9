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
  ShiftRows rows(xf, s, k0, n0, nr);
  for (int64_t k = 0; k < kc; ++k) {
    uint32_t m;
    const float* src = rows.next(&m);
    // The next panel reads the following 64 bytes of the same rows: fetch them into L2 now (each row is its own
    // stream, far more than the hardware prefetchers track).
    _mm_prefetch(reinterpret_cast<const char*>(src + NR), _MM_HINT_T1);
    _mm_prefetch(reinterpret_cast<const char*>(src + NR + 16), _MM_HINT_T1);
    _mm512_store_ps(dst + k * NR, _mm512_maskz_loadu_ps(__mmask16(m), src));
    _mm512_store_ps(dst + k * NR + 16, _mm512_maskz_loadu_ps(__mmask16(m >> 16), src + 16));
  }
}

}  // namespace egopd::conv_detail
