// Winograd transforms on the avx512 path: the lane loops of winograd_transforms.h compiled for AVX-512, 32 lanes
// (the NR of the AVX-512 GEMM), and the F(4x4,3x3) input transform written for AVX-512.
#include <immintrin.h>

#include <algorithm>
#include <cstdint>

#include "core/kernels/gemm_internal.h"
#include "core/kernels/winograd_internal.h"

#pragma GCC target("avx512f,avx512bw,avx512vl,avx512dq,avx2,fma,f16c")
#include "core/kernels/winograd_transforms.h"

namespace egopd::wino_detail {
namespace {

// Bits [lo, hi) of a 16-lane mask.
inline __mmask16 lane_range(int64_t lo, int64_t hi) {
  lo = std::max<int64_t>(lo, 0);
  hi = std::min<int64_t>(hi, 16);
  return hi <= lo ? 0 : __mmask16(((1u << hi) - 1) & ~((1u << lo) - 1));
}

// [b1, ..., b15, a0]
inline __m512 next_lane(__m512 a, __m512 b) {
  return _mm512_castsi512_ps(_mm512_alignr_epi32(_mm512_castps_si512(a), _mm512_castps_si512(b), 1));
}

// F(4x4,3x3) input transform of channels [c0, c1) of a 32-tile panel, as two halves of 16 tiles. Tile j of a
// segment reads columns 4j - 1 .. 4j + 4 of six rows: each row's 66 columns are loaded with masks (zeros outside the
// frame) and de-interleaved in registers. The generic lane loop assembled them with scalar stores that its wide
// loads then waited on (about 30% of a 128-channel 256x256 convolution, against 40% for its GEMM).
void input_panel_f4(const float* x, int64_t cin, const PanelGeom& pg, int64_t c0, int64_t c1, float* dst,
                    int64_t xi_stride) {
  constexpr int A = 6, L = gemm_detail::kNrAvx512;
  static_assert(L == 32, "two halves of 16 lanes");
  const int64_t h = pg.h, w = pg.w, plane = h * w;
  const __m512i phase01 = _mm512_setr_epi32(0, 4, 8, 12, 16, 20, 24, 28, 1, 5, 9, 13, 17, 21, 25, 29);
  const __m512i phase23 = _mm512_setr_epi32(2, 6, 10, 14, 18, 22, 26, 30, 3, 7, 11, 15, 19, 23, 27, 31);
  const __m512i low8 = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 16, 17, 18, 19, 20, 21, 22, 23);
  const __m512i high8 = _mm512_setr_epi32(8, 9, 10, 11, 12, 13, 14, 15, 24, 25, 26, 27, 28, 29, 30, 31);
  const __m512 zero = _mm512_setzero_ps();
  alignas(64) __m512 t[A][A][2];  // t[r][l][half] = (Bᵀ d_r)_l, d_r input row r of each tile
  for (int64_t c = c0; c < c1; ++c) {
    if (c + 1 < cin)  // the next channel's rows: its plane is far from this one, out of the prefetchers' sight
      for (int si = 0; si < pg.nseg; ++si) {
        const Segment& s = pg.seg[si];
        const int64_t x0 = std::max<int64_t>(4 * s.tx0 - 1, 0), x1 = std::min<int64_t>(4 * (s.tx0 + s.j1 - s.j0) + 2, w);
        for (int r = 0; r < A; ++r) {
          const int64_t iy = s.ty * 4 - 1 + r;
          if (iy < 0 || iy >= h) continue;
          const char* row = reinterpret_cast<const char*>(x + (s.f * cin + c + 1) * plane + iy * w);
          for (int64_t b = x0 * 4 / 64 * 64; b < x1 * 4; b += 64) _mm_prefetch(row + b, _MM_HINT_T0);
        }
      }
    for (int r = 0; r < A; ++r)
      for (int half = 0; half < 2; ++half) {
        __m512 d[A] = {zero, zero, zero, zero, zero, zero};  // d[q] lane i: column q of the tile's patch row
        for (int si = 0; si < pg.nseg; ++si) {
          const Segment& s = pg.seg[si];
          const __mmask16 lanes = lane_range(s.j0 - 16 * half, s.j1 - 16 * half);
          const int64_t iy = s.ty * 4 - 1 + r;
          if (!lanes || iy < 0 || iy >= h) continue;
          // Element e of the span is column col0 + e; lane i reads elements 4i .. 4i + 5.
          const int64_t col0 = 4 * (s.tx0 + 16 * half - s.j0) - 1;
          const float* row = x + (s.f * cin + c) * plane + iy * w;
          const auto load = [&](int64_t e, __mmask16 keep) {  // 16 elements from e, zero outside the frame
            const __mmask16 m = lane_range(-col0 - e, w - col0 - e) & keep;
            return _mm512_maskz_loadu_ps(m, row + (col0 + e));  // masked-off lanes are never read
          };
          const __m512 a0 = load(0, 0xffff), a1 = load(16, 0xffff), a2 = load(32, 0xffff), a3 = load(48, 0xffff);
          const __m512 tail = load(64, 0x3);
          const __m512 x01 = _mm512_permutex2var_ps(a0, phase01, a1), x23 = _mm512_permutex2var_ps(a0, phase23, a1);
          const __m512 y01 = _mm512_permutex2var_ps(a2, phase01, a3), y23 = _mm512_permutex2var_ps(a2, phase23, a3);
          const __m512 q0 = _mm512_permutex2var_ps(x01, low8, y01), q1 = _mm512_permutex2var_ps(x01, high8, y01);
          const __m512 q2 = _mm512_permutex2var_ps(x23, low8, y23), q3 = _mm512_permutex2var_ps(x23, high8, y23);
          d[0] = _mm512_mask_mov_ps(d[0], lanes, q0);
          d[1] = _mm512_mask_mov_ps(d[1], lanes, q1);
          d[2] = _mm512_mask_mov_ps(d[2], lanes, q2);
          d[3] = _mm512_mask_mov_ps(d[3], lanes, q3);
          d[4] = _mm512_mask_mov_ps(d[4], lanes, next_lane(tail, q0));
          d[5] = _mm512_mask_mov_ps(d[5], lanes, next_lane(next_lane(zero, tail), q1));
        }
        __m512 v[A];
        Transform<4>::bt(d, v);
        for (int l = 0; l < A; ++l) t[r][l][half] = v[l];
      }
    for (int half = 0; half < 2; ++half)
      for (int l = 0; l < A; ++l) {
        const __m512 col[A] = {t[0][l][half], t[1][l][half], t[2][l][half],
                               t[3][l][half], t[4][l][half], t[5][l][half]};
        __m512 v[A];
        Transform<4>::bt(col, v);
        for (int k = 0; k < A; ++k) _mm512_storeu_ps(dst + (k * A + l) * xi_stride + c * L + 16 * half, v[k]);
      }
  }
}

}  // namespace

const WinogradKernels& winograd_kernels_avx512() {
  static const WinogradKernels k = [] {
    WinogradKernels w = make_winograd_kernels<gemm_detail::kNrAvx512>();
    w.input[1] = input_panel_f4;
    return w;
  }();
  return k;
}

}  // namespace egopd::wino_detail
