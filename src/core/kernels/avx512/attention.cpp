// AVX-512 attention for one (batch, head, query tile): the flow of attention_tile.h (the AVX2 kernel's blocked
// two-GEMM scheme with an online softmax) in zmm registers:
//  * S^T[key, query] = K · (c Q)^T in 12-key x 32-query micro-tiles (24 accumulators; K elements broadcast from
//    the source rows, so keys are never packed), or 12 x 16 for the last 16 query columns;
//  * the softmax runs down columns, 16 queries per vector;
//  * P·V in 6-query x 64-channel micro-tiles (24 accumulators), the last channel vector masked.
#include <cstdint>

#pragma GCC target("avx512f,avx512bw,avx512vl,avx512dq,avx2,fma,f16c")
#include <immintrin.h>

#include "core/kernels/attention.h"
#include "core/kernels/attention_tile.h"
#include "core/kernels/avx512/vec_math.h"

namespace egopd::avx512 {

using namespace egopd::vmath;

namespace {

constexpr int64_t kBQ = 64;  // queries per tile (2 column blocks of 32)
constexpr int64_t kBK = 48;  // keys per tile (4 row blocks of 12)
constexpr int kSR = 12;      // score micro-tile rows (keys)
constexpr int kPR = 6;       // P·V micro-tile rows (queries)
constexpr int kPV = 4;       // P·V micro-tile channel vectors (64 channels)

inline __mmask16 lanes(int64_t n) { return tail_mask16(n < 16 ? n : 16); }

// The one micro-tile of both products: C[r][0..16*NC) (+)= sum_j A(r, j) * B[j][0..16*NC) for R rows, A(r, j) =
// a[r * a_rs + j * a_js] broadcast, B rows at stride b_ld with the last vector masked by `last`; C starts from zero
// (scores) or from memory (P·V accumulators).
template <int R, int NC, bool kLoadC>
inline void bcast_tile(const float* a, int64_t a_rs, int64_t a_js, const float* b, int64_t b_ld, __mmask16 last,
                       int64_t n, float* c, int64_t c_ld) {
  __m512 acc[R][NC];
#pragma GCC unroll 12
  for (int r = 0; r < R; ++r)
#pragma GCC unroll 4
    for (int q = 0; q < NC; ++q) acc[r][q] = kLoadC ? _mm512_loadu_ps(c + r * c_ld + q * 16) : _mm512_setzero_ps();
#pragma GCC unroll 2
  for (int64_t j = 0; j < n; ++j) {
    __m512 bv[NC];
#pragma GCC unroll 4
    for (int q = 0; q < NC; ++q)
      bv[q] = q == NC - 1 ? _mm512_maskz_loadu_ps(last, b + j * b_ld + q * 16) : _mm512_loadu_ps(b + j * b_ld + q * 16);
#pragma GCC unroll 12
    for (int r = 0; r < R; ++r) {
      const __m512 av = _mm512_set1_ps(a[r * a_rs + j * a_js]);
#pragma GCC unroll 4
      for (int q = 0; q < NC; ++q) acc[r][q] = _mm512_fmadd_ps(av, bv[q], acc[r][q]);
    }
  }
#pragma GCC unroll 12
  for (int r = 0; r < R; ++r)
#pragma GCC unroll 4
    for (int q = 0; q < NC; ++q) _mm512_storeu_ps(c + r * c_ld + q * 16, acc[r][q]);
}

// S^T[r][0..16*NC) = sum_d K[r][d] * Qt[d][0..16*NC) for R key rows; qt points at Qt[0][i0] (stride kBQ).
template <int R, int NC>
inline void score_block(const float* qt, int64_t dh, const float* k, int64_t k_ld, float* st) {
  bcast_tile<R, NC, false>(k, k_ld, 1, qt, kBQ, 0xffff, dh, st, kBQ);
}

template <int NC>
void score_rows(const float* qt, int64_t dh, const float* k, int64_t k_ld, int64_t rows, float* st) {
  int64_t r = 0;
  for (; r + kSR <= rows; r += kSR) score_block<kSR, NC>(qt, dh, k + r * k_ld, k_ld, st + r * kBQ);
  const float* kr = k + r * k_ld;
  float* sr = st + r * kBQ;
  switch (rows - r) {  // tails as at most two blocks: 8 + (1..3), or one block of 1..8 rows
    case 11: score_block<8, NC>(qt, dh, kr, k_ld, sr), score_block<3, NC>(qt, dh, kr + 8 * k_ld, k_ld, sr + 8 * kBQ); break;
    case 10: score_block<8, NC>(qt, dh, kr, k_ld, sr), score_block<2, NC>(qt, dh, kr + 8 * k_ld, k_ld, sr + 8 * kBQ); break;
    case 9: score_block<8, NC>(qt, dh, kr, k_ld, sr), score_block<1, NC>(qt, dh, kr + 8 * k_ld, k_ld, sr + 8 * kBQ); break;
    case 8: score_block<8, NC>(qt, dh, kr, k_ld, sr); break;
    case 7: score_block<7, NC>(qt, dh, kr, k_ld, sr); break;
    case 6: score_block<6, NC>(qt, dh, kr, k_ld, sr); break;
    case 5: score_block<5, NC>(qt, dh, kr, k_ld, sr); break;
    case 4: score_block<4, NC>(qt, dh, kr, k_ld, sr); break;
    case 3: score_block<3, NC>(qt, dh, kr, k_ld, sr); break;
    case 2: score_block<2, NC>(qt, dh, kr, k_ld, sr); break;
    case 1: score_block<1, NC>(qt, dh, kr, k_ld, sr); break;
    default: break;
  }
}

// O[r][0..16*NV) += sum_j P^T[j][r] * V[j][0..16*NV) for R query rows; the last vector of V masked by `last`.
template <int R, int NV>
inline void pv_block(const float* pt, int64_t nk, const float* v, int64_t v_ld, __mmask16 last, float* o,
                     int64_t o_ld) {
  bcast_tile<R, NV, true>(pt, 1, kBQ, v, v_ld, last, nk, o, o_ld);
}

// All dh channels of R query rows: blocks of 64, then one block of 1-3 vectors (O rows are padded to 16).
template <int R>
void pv_cols(const float* pt, int64_t nk, const float* v, int64_t v_ld, int64_t dh, float* o, int64_t o_ld) {
  int64_t d = 0;
  for (; d + 16 * kPV <= dh; d += 16 * kPV) pv_block<R, kPV>(pt, nk, v + d, v_ld, 0xffff, o + d, o_ld);
  const int64_t rest = dh - d;
  const __mmask16 last = lanes(rest - (rest - 1) / 16 * 16);
  switch ((rest + 15) / 16) {
    case 3: pv_block<R, 3>(pt, nk, v + d, v_ld, last, o + d, o_ld); break;
    case 2: pv_block<R, 2>(pt, nk, v + d, v_ld, last, o + d, o_ld); break;
    case 1: pv_block<R, 1>(pt, nk, v + d, v_ld, last, o + d, o_ld); break;
    default: break;
  }
}

void pv_rows(const float* pt, int64_t nk, const float* v, int64_t v_ld, int64_t dh, int64_t rows, float* o,
             int64_t o_ld) {
  int64_t r = 0;
  for (; r + kPR <= rows; r += kPR) pv_cols<kPR>(pt + r, nk, v, v_ld, dh, o + r * o_ld, o_ld);
  const float* pr = pt + r;
  float* orow = o + r * o_ld;
  switch (rows - r) {
    case 5: pv_cols<5>(pr, nk, v, v_ld, dh, orow, o_ld); break;
    case 4: pv_cols<4>(pr, nk, v, v_ld, dh, orow, o_ld); break;
    case 3: pv_cols<3>(pr, nk, v, v_ld, dh, orow, o_ld); break;
    case 2: pv_cols<2>(pr, nk, v, v_ld, dh, orow, o_ld); break;
    case 1: pv_cols<1>(pr, nk, v, v_ld, dh, orow, o_ld); break;
    default: break;
  }
}

// Online softmax of one key tile down each column (16 queries per vector): st holds S^T on entry and P^T on exit;
// m (running max, log2 domain) and l (running sum) are updated; corr receives each column's rescale factor.
void softmax_columns(float* st, int64_t nk, int64_t ncol, float* m, float* l, float* corr) {
  const __m512 ninf = _mm512_set1_ps(-__builtin_inff());
  for (int64_t i = 0; i < ncol; i += 16) {
    __m512 mx = ninf;
    for (int64_t j = 0; j < nk; ++j) mx = _mm512_max_ps(mx, _mm512_loadu_ps(st + j * kBQ + i));
    const __m512 m_old = _mm512_loadu_ps(m + i);
    const __m512 m_new = _mm512_max_ps(m_old, mx);
    // A column with no visible key yet keeps m = -inf; subtract 0 instead so exp2(-inf - 0) = 0, not NaN.
    const __m512 m_sub = _mm512_mask_blend_ps(_mm512_cmp_ps_mask(m_new, ninf, _CMP_EQ_OQ), m_new, _mm512_setzero_ps());
    const __m512 cr = exp2_ps(_mm512_sub_ps(m_old, m_sub));
    __m512 sum = _mm512_setzero_ps();
    for (int64_t j = 0; j < nk; ++j) {
      const __m512 p = exp2_ps(_mm512_sub_ps(_mm512_loadu_ps(st + j * kBQ + i), m_sub));
      _mm512_storeu_ps(st + j * kBQ + i, p);
      sum = _mm512_add_ps(sum, p);
    }
    _mm512_storeu_ps(m + i, m_new);
    _mm512_storeu_ps(l + i, _mm512_fmadd_ps(_mm512_loadu_ps(l + i), cr, sum));
    _mm512_storeu_ps(corr + i, cr);
  }
}

struct Kernel {
  static constexpr int64_t kBQ = avx512::kBQ, kBK = avx512::kBK, kPad = 16;
  static void scores(const float* qt, int64_t dh, const float* k, int64_t k_ld, int64_t nk, int64_t ncol, float* st) {
    const int64_t ncol32 = ncol / 32 * 32;
    for (int64_t i0 = 0; i0 < ncol32; i0 += 32) score_rows<2>(qt + i0, dh, k, k_ld, nk, st + i0);
    if (ncol32 < ncol) score_rows<1>(qt + ncol32, dh, k, k_ld, nk, st + ncol32);
  }
  static constexpr auto softmax_columns = avx512::softmax_columns;
  static void scale_row(float* o, int64_t n, float f) {
    const __m512 vf = _mm512_set1_ps(f);
    for (int64_t d = 0; d < n; d += 16) _mm512_storeu_ps(o + d, _mm512_mul_ps(_mm512_loadu_ps(o + d), vf));
  }
  static constexpr auto pv_rows = avx512::pv_rows;
  static void store_row(float* dst, const float* o, int64_t dh, float f) {
    const __m512 vf = _mm512_set1_ps(f);
    for (int64_t d = 0; d < dh; d += 16) _mm512_mask_storeu_ps(dst + d, lanes(dh - d), _mm512_mul_ps(_mm512_loadu_ps(o + d), vf));
  }
};

}  // namespace

int64_t attention_tile_queries() { return kBQ; }

int64_t attention_tile_workspace(int64_t dh) { return attention_detail::tile_workspace<Kernel>(dh); }

void attention_tile(const AttentionArgs& a, int64_t b, int64_t h, int64_t q0, int64_t nq, float* work) {
  attention_detail::attention_tile<Kernel>(a, b, h, q0, nq, work);
}

}  // namespace egopd::avx512
