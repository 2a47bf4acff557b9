// AVX2/FMA attention for one (batch, head, query tile): the blocked two-GEMM flow of attention_tile.h with an
// online softmax.
//
// Scores are computed transposed, S^T[key, query] = K · (c Q)^T with c = scale * log2(e), so that
//  * K rows are read straight from the source (broadcast per element; no key packing or transposition),
//  * the softmax over keys runs down columns, i.e. vectorised across 8 queries at a time,
//  * P·V broadcasts P^T[key, query] and streams V rows from the source.
// Only the query tile is packed (transposed and pre-scaled). exp2 is used since log2(e) is folded into c.
#include <cstdint>

#pragma GCC target("avx2,fma,f16c")
#include <immintrin.h>

#include "core/kernels/attention.h"
#include "core/kernels/attention_tile.h"
#include "core/kernels/avx2/vec_math.h"

namespace egopd::avx2 {

using namespace egopd::vmath;

namespace {

constexpr int64_t kBQ = 64;  // queries per tile (4 column blocks of 16)
constexpr int64_t kBK = 48;  // keys per tile (8 row blocks of 6)
constexpr int kMR = 6;       // micro-tile rows (keys for S^T, queries for P·V)


// S^T[r][0..15] = sum_d K[r][d] * Qt[d][0..15] for R key rows; qt points at Qt[0][i0] (stride kBQ).
// Used for tail blocks (R < 6). The accumulators start from memory: GCC keeps a zero-initialised array there.
template <int R>
static inline void score_block(const float* qt, int64_t dh, const float* k, int64_t k_ld, float* st) {
  for (int r = 0; r < R; ++r)
    for (int c = 0; c < 16; ++c) st[r * kBQ + c] = 0.0f;
  __m256 acc[R][2];
  for (int r = 0; r < R; ++r)
    for (int c = 0; c < 2; ++c) acc[r][c] = _mm256_loadu_ps(st + r * kBQ + c * 8);
  for (int64_t d = 0; d < dh; ++d) {
    const __m256 q0 = _mm256_loadu_ps(qt + d * kBQ), q1 = _mm256_loadu_ps(qt + d * kBQ + 8);
    for (int r = 0; r < R; ++r) {
      const __m256 kb = _mm256_broadcast_ss(k + r * k_ld + d);
      acc[r][0] = _mm256_fmadd_ps(kb, q0, acc[r][0]);
      acc[r][1] = _mm256_fmadd_ps(kb, q1, acc[r][1]);
    }
  }
  for (int r = 0; r < R; ++r)
    for (int c = 0; c < 2; ++c) _mm256_storeu_ps(st + r * kBQ + c * 8, acc[r][c]);
}

// The full 6-row block, with named accumulators.
static inline void score_block6(const float* qt, int64_t dh, const float* k, int64_t k_ld, float* st) {
  const float *k0 = k, *k1 = k + k_ld, *k2 = k + 2 * k_ld, *k3 = k + 3 * k_ld, *k4 = k + 4 * k_ld, *k5 = k + 5 * k_ld;
  __m256 a00 = _mm256_setzero_ps(), a01 = a00, a10 = a00, a11 = a00, a20 = a00, a21 = a00;
  __m256 a30 = a00, a31 = a00, a40 = a00, a41 = a00, a50 = a00, a51 = a00;
#pragma GCC unroll 4
  for (int64_t d = 0; d < dh; ++d) {
    const __m256 q0 = _mm256_loadu_ps(qt + d * kBQ), q1 = _mm256_loadu_ps(qt + d * kBQ + 8);
    __m256 kb = _mm256_broadcast_ss(k0 + d);
    a00 = _mm256_fmadd_ps(kb, q0, a00), a01 = _mm256_fmadd_ps(kb, q1, a01);
    kb = _mm256_broadcast_ss(k1 + d);
    a10 = _mm256_fmadd_ps(kb, q0, a10), a11 = _mm256_fmadd_ps(kb, q1, a11);
    kb = _mm256_broadcast_ss(k2 + d);
    a20 = _mm256_fmadd_ps(kb, q0, a20), a21 = _mm256_fmadd_ps(kb, q1, a21);
    kb = _mm256_broadcast_ss(k3 + d);
    a30 = _mm256_fmadd_ps(kb, q0, a30), a31 = _mm256_fmadd_ps(kb, q1, a31);
    kb = _mm256_broadcast_ss(k4 + d);
    a40 = _mm256_fmadd_ps(kb, q0, a40), a41 = _mm256_fmadd_ps(kb, q1, a41);
    kb = _mm256_broadcast_ss(k5 + d);
    a50 = _mm256_fmadd_ps(kb, q0, a50), a51 = _mm256_fmadd_ps(kb, q1, a51);
  }
  _mm256_storeu_ps(st, a00), _mm256_storeu_ps(st + 8, a01);
  _mm256_storeu_ps(st + kBQ, a10), _mm256_storeu_ps(st + kBQ + 8, a11);
  _mm256_storeu_ps(st + 2 * kBQ, a20), _mm256_storeu_ps(st + 2 * kBQ + 8, a21);
  _mm256_storeu_ps(st + 3 * kBQ, a30), _mm256_storeu_ps(st + 3 * kBQ + 8, a31);
  _mm256_storeu_ps(st + 4 * kBQ, a40), _mm256_storeu_ps(st + 4 * kBQ + 8, a41);
  _mm256_storeu_ps(st + 5 * kBQ, a50), _mm256_storeu_ps(st + 5 * kBQ + 8, a51);
}

static void score_rows(const float* qt, int64_t dh, const float* k, int64_t k_ld, int64_t rows, float* st) {
  int64_t r = 0;
  for (; r + kMR <= rows; r += kMR) score_block6(qt, dh, k + r * k_ld, k_ld, st + r * kBQ);
  const float* kr = k + r * k_ld;
  float* sr = st + r * kBQ;
  switch (rows - r) {
    case 5:  // 4 + 1: GCC spills the accumulators of a 5-row block
      score_block<4>(qt, dh, kr, k_ld, sr);
      score_block<1>(qt, dh, kr + 4 * k_ld, k_ld, sr + 4 * kBQ);
      break;
    case 4: score_block<4>(qt, dh, kr, k_ld, sr); break;
    case 3: score_block<3>(qt, dh, kr, k_ld, sr); break;
    case 2: score_block<2>(qt, dh, kr, k_ld, sr); break;
    case 1: score_block<1>(qt, dh, kr, k_ld, sr); break;
    default: break;
  }
}

// O[r][0..8*NV) += sum_j P^T[j][r] * V[j][0..8*NV) for R query rows; the last vector of V may be masked.
template <int R, int NV, bool MASKED>
static inline void pv_block(const float* pt, int64_t nk, const float* v, int64_t v_ld, __m256i mask, float* o,
                            int64_t o_ld) {
  __m256 acc[R][NV];
  for (int r = 0; r < R; ++r)
    for (int c = 0; c < NV; ++c) acc[r][c] = _mm256_loadu_ps(o + r * o_ld + c * 8);
#pragma GCC unroll 4
  for (int64_t j = 0; j < nk; ++j) {
    __m256 vv[NV];
    for (int c = 0; c < NV; ++c)
      vv[c] = (MASKED && c == NV - 1) ? _mm256_maskload_ps(v + j * v_ld + c * 8, mask)
                                      : _mm256_loadu_ps(v + j * v_ld + c * 8);
    for (int r = 0; r < R; ++r) {
      const __m256 p = _mm256_broadcast_ss(pt + j * kBQ + r);
      for (int c = 0; c < NV; ++c) acc[r][c] = _mm256_fmadd_ps(p, vv[c], acc[r][c]);
    }
  }
  for (int r = 0; r < R; ++r)
    for (int c = 0; c < NV; ++c) _mm256_storeu_ps(o + r * o_ld + c * 8, acc[r][c]);
}

template <int R>
static void pv_cols(const float* pt, int64_t nk, const float* v, int64_t v_ld, int64_t dh, float* o, int64_t o_ld) {
  int64_t d = 0;
  const __m256i all = _mm256_set1_epi32(-1);
  for (; d + 16 <= dh; d += 16) pv_block<R, 2, false>(pt, nk, v + d, v_ld, all, o + d, o_ld);
  if (d + 8 <= dh) {
    pv_block<R, 1, false>(pt, nk, v + d, v_ld, all, o + d, o_ld);
    d += 8;
  }
  if (d < dh) pv_block<R, 1, true>(pt, nk, v + d, v_ld, tail_mask(dh - d), o + d, o_ld);  // O is padded to 8
}

static void pv_rows(const float* pt, int64_t nk, const float* v, int64_t v_ld, int64_t dh, int64_t rows, float* o,
                    int64_t o_ld) {
  int64_t r = 0;
  for (; r + kMR <= rows; r += kMR) pv_cols<kMR>(pt + r, nk, v, v_ld, dh, o + r * o_ld, o_ld);
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

// Online softmax of one key tile down each column (8 queries per vector): st holds the scores on entry (times
// `scale` under kBf16) and P^T on exit; m (running max, log2 domain) and l (running sum) are updated; corr receives
// each column's rescale factor. kBf16 (Precision::Bf16, attention.h): the running max is an integer and P is
// rounded to bfloat16.
template <bool kBf16>
static void softmax_columns(float* st, int64_t nk, int64_t ncol, float* m, float* l, float* corr, float scale) {
  const __m256 ninf = _mm256_set1_ps(-__builtin_inff()), vscale = _mm256_set1_ps(scale);
  for (int64_t i = 0; i < ncol; i += 8) {
    __m256 mx = ninf;
    for (int64_t j = 0; j < nk; ++j) {
      __m256 s = _mm256_loadu_ps(st + j * kBQ + i);
      if (kBf16) _mm256_storeu_ps(st + j * kBQ + i, s = _mm256_mul_ps(s, vscale));
      mx = _mm256_max_ps(mx, s);
    }
    if (kBf16) mx = _mm256_round_ps(mx, _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC);
    const __m256 m_old = _mm256_loadu_ps(m + i);
    const __m256 m_new = _mm256_max_ps(m_old, mx);
    // A column with no visible key yet keeps m = -inf; subtract 0 instead so exp2(-inf - 0) = 0, not NaN.
    const __m256 m_sub = _mm256_blendv_ps(m_new, _mm256_setzero_ps(), _mm256_cmp_ps(m_new, ninf, _CMP_EQ_OQ));
    const __m256 cr = exp2_ps(_mm256_sub_ps(m_old, m_sub));
    __m256 sum = _mm256_setzero_ps();
    for (int64_t j = 0; j < nk; ++j) {
      __m256 p = exp2_ps(_mm256_sub_ps(_mm256_loadu_ps(st + j * kBQ + i), m_sub));
      if (kBf16) p = round_bf16_ps(p);
      _mm256_storeu_ps(st + j * kBQ + i, p);
      sum = _mm256_add_ps(sum, p);
    }
    _mm256_storeu_ps(m + i, m_new);
    _mm256_storeu_ps(l + i, _mm256_fmadd_ps(_mm256_loadu_ps(l + i), cr, sum));
    _mm256_storeu_ps(corr + i, cr);
  }
}

struct Kernel {
  static constexpr int64_t kBQ = avx2::kBQ, kBK = avx2::kBK, kPad = 8;
  static void scores(const float* qt, int64_t dh, const float* k, int64_t k_ld, int64_t nk, int64_t ncol, float* st) {
    for (int64_t i0 = 0; i0 < ncol; i0 += 16) score_rows(qt + i0, dh, k, k_ld, nk, st + i0);
  }
  template <bool kBf16>
  static void softmax_columns(float* st, int64_t nk, int64_t ncol, float* m, float* l, float* corr, float scale) {
    avx2::softmax_columns<kBf16>(st, nk, ncol, m, l, corr, scale);
  }
  static void scale_row(float* o, int64_t n, float f) {
    const __m256 vf = _mm256_set1_ps(f);
    for (int64_t d = 0; d < n; d += 8) _mm256_storeu_ps(o + d, _mm256_mul_ps(_mm256_loadu_ps(o + d), vf));
  }
  static constexpr auto pv_rows = avx2::pv_rows;
  static void store_row(float* dst, const float* o, int64_t dh, float f) {
    const __m256 vf = _mm256_set1_ps(f);
    int64_t d = 0;
    for (; d + 8 <= dh; d += 8) _mm256_storeu_ps(dst + d, _mm256_mul_ps(_mm256_loadu_ps(o + d), vf));
    if (d < dh) _mm256_maskstore_ps(dst + d, tail_mask(dh - d), _mm256_mul_ps(_mm256_loadu_ps(o + d), vf));
  }
};

}  // namespace

// Prefetches the q rows [q0, q0+nq) and all k, v rows of head h in batch b (the next unit's inputs): short
// sequences with large row strides (temporal attention) are otherwise bound by memory latency.
void prefetch_unit(const AttentionArgs& a, int64_t b, int64_t h, int64_t q0, int64_t nq) {
  const int64_t bytes = a.dh * 4;
  const char* q = reinterpret_cast<const char*>(a.q + b * a.q_bs + q0 * a.q_ld + h * a.dh);
  const char* k = reinterpret_cast<const char*>(a.k + b * a.k_bs + h * a.dh);
  const char* v = reinterpret_cast<const char*>(a.v + b * a.v_bs + h * a.dh);
  for (int64_t i = 0; i < nq; ++i)
    for (int64_t off = 0; off < bytes; off += 64) _mm_prefetch(q + i * a.q_ld * 4 + off, _MM_HINT_T0);
  for (int64_t j = 0; j < a.lk; ++j)
    for (int64_t off = 0; off < bytes; off += 64) {
      _mm_prefetch(k + j * a.k_ld * 4 + off, _MM_HINT_T0);
      _mm_prefetch(v + j * a.v_ld * 4 + off, _MM_HINT_T0);
    }
}

int64_t attention_tile_queries() { return kBQ; }

int64_t attention_tile_workspace(int64_t dh) { return attention_detail::tile_workspace<Kernel>(dh); }

void attention_tile(const AttentionArgs& a, int64_t b, int64_t h, int64_t q0, int64_t nq, float* work, bool bf16) {
  attention_detail::attention_tile<Kernel>(a, b, h, q0, nq, work, bf16);
}

}  // namespace egopd::avx2
