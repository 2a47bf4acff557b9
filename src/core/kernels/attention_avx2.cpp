// AVX2/FMA attention for one (batch, head, query tile): a blocked two-GEMM kernel with an online softmax.
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
#include "core/kernels/vec_math_avx2.h"

namespace egopd::avx2 {

using namespace egopd::vmath;

namespace {

constexpr int64_t kBQ = 64;  // queries per tile (4 column blocks of 16)
constexpr int64_t kBK = 48;  // keys per tile (8 row blocks of 6)
constexpr int kMR = 6;       // micro-tile rows (keys for S^T, queries for P·V)

static inline int64_t round_up8(int64_t n) { return (n + 7) / 8 * 8; }
static inline int64_t min64(int64_t a, int64_t b) { return a < b ? a : b; }

// S^T[r][0..15] = sum_d K[r][d] * Qt[d][0..15] for R key rows; qt points at Qt[0][i0] (stride kBQ).
template <int R>
static inline void score_block(const float* qt, int64_t dh, const float* k, int64_t k_ld, float* st) {
  __m256 acc0[R], acc1[R];
  for (int r = 0; r < R; ++r) acc0[r] = acc1[r] = _mm256_setzero_ps();
  for (int64_t d = 0; d < dh; ++d) {
    const __m256 q0 = _mm256_loadu_ps(qt + d * kBQ), q1 = _mm256_loadu_ps(qt + d * kBQ + 8);
    for (int r = 0; r < R; ++r) {
      const __m256 kb = _mm256_broadcast_ss(k + r * k_ld + d);
      acc0[r] = _mm256_fmadd_ps(kb, q0, acc0[r]);
      acc1[r] = _mm256_fmadd_ps(kb, q1, acc1[r]);
    }
  }
  for (int r = 0; r < R; ++r) {
    _mm256_storeu_ps(st + r * kBQ, acc0[r]);
    _mm256_storeu_ps(st + r * kBQ + 8, acc1[r]);
  }
}

static void score_rows(const float* qt, int64_t dh, const float* k, int64_t k_ld, int64_t rows, float* st) {
  int64_t r = 0;
  for (; r + kMR <= rows; r += kMR) score_block<kMR>(qt, dh, k + r * k_ld, k_ld, st + r * kBQ);
  const float* kr = k + r * k_ld;
  float* sr = st + r * kBQ;
  switch (rows - r) {
    case 5: score_block<5>(qt, dh, kr, k_ld, sr); break;
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

}  // namespace

int64_t attention_tile_workspace(int64_t dh) {
  return dh * kBQ + kBK * kBQ + kBQ * round_up8(dh) + 3 * kBQ;
}

// Queries [q0, q0 + nq) (nq <= 64) of head h in batch b. work: attention_tile_workspace(dh) floats.
void attention_tile(const AttentionArgs& a, int64_t b, int64_t h, int64_t q0, int64_t nq, float* work) {
  const int64_t dh = a.dh, dhp = round_up8(dh);
  float* qt = work;            // [dh][kBQ]  c * Q^T, zero beyond nq
  float* st = qt + dh * kBQ;   // [kBK][kBQ] S^T, then P^T
  float* o = st + kBK * kBQ;   // [kBQ][dhp] unnormalised output
  float* m = o + kBQ * dhp;    // [kBQ] running max (log2 domain)
  float* l = m + kBQ;          // [kBQ] running sum
  float* corr = l + kBQ;       // [kBQ] rescale factor of this key tile

  const float c = a.scale * 1.44269504088896341f;
  const float* q = a.q + b * a.q_bs + q0 * a.q_ld + h * dh;
  const float* k = a.k + b * a.k_bs + h * dh;
  const float* v = a.v + b * a.v_bs + h * dh;
  const int64_t ncol = (nq + 15) / 16 * 16;  // query columns computed (multiple of 16)
  // [nq, dh] (stride q_ld) -> [dh, kBQ], scaled
  for (int64_t d = 0; d < dh; ++d) {
    float* row = qt + d * kBQ;
    for (int64_t i = 0; i < nq; ++i) row[i] = q[i * a.q_ld + d] * c;
    for (int64_t i = nq; i < kBQ; ++i) row[i] = 0.0f;
  }
  for (int64_t i = 0; i < kBQ * dhp; ++i) o[i] = 0.0f;
  for (int64_t i = 0; i < kBQ; ++i) m[i] = -__builtin_inff(), l[i] = 0.0f;

  const int64_t kend = a.causal ? min64(a.lk, q0 + nq) : a.lk;
  for (int64_t k0 = 0; k0 < kend; k0 += kBK) {
    const int64_t nk = min64(kBK, kend - k0);
    for (int64_t i0 = 0; i0 < ncol; i0 += 16) score_rows(qt + i0, dh, k + k0 * a.k_ld, a.k_ld, nk, st + i0);
    if (a.causal && k0 + nk - 1 > q0) {  // key k0+j is hidden from query q0+i when k0+j > q0+i
      for (int64_t j = 0; j < nk; ++j)
        for (int64_t i = 0; i < ncol; ++i)
          if (k0 + j > q0 + i) st[j * kBQ + i] = -__builtin_inff();
    }
    // Online softmax down each column (8 queries per vector).
    for (int64_t i = 0; i < ncol; i += 8) {
      __m256 mx = _mm256_set1_ps(-__builtin_inff());
      for (int64_t j = 0; j < nk; ++j) mx = _mm256_max_ps(mx, _mm256_loadu_ps(st + j * kBQ + i));
      const __m256 m_old = _mm256_loadu_ps(m + i);
      __m256 m_new = _mm256_max_ps(m_old, mx);
      // A column with no visible key yet keeps m = -inf; use 0 so exp2(-inf - 0) = 0 instead of NaN.
      m_new = _mm256_blendv_ps(m_new, _mm256_setzero_ps(),
                               _mm256_cmp_ps(m_new, _mm256_set1_ps(-__builtin_inff()), _CMP_EQ_OQ));
      const __m256 cr = exp2_ps(_mm256_sub_ps(m_old, m_new));
      __m256 sum = _mm256_setzero_ps();
      for (int64_t j = 0; j < nk; ++j) {
        const __m256 p = exp2_ps(_mm256_sub_ps(_mm256_loadu_ps(st + j * kBQ + i), m_new));
        _mm256_storeu_ps(st + j * kBQ + i, p);
        sum = _mm256_add_ps(sum, p);
      }
      _mm256_storeu_ps(m + i, m_new);
      _mm256_storeu_ps(l + i, _mm256_fmadd_ps(_mm256_loadu_ps(l + i), cr, sum));
      _mm256_storeu_ps(corr + i, cr);
    }
    if (k0 > 0) {  // rescale the accumulators to the new running max
      for (int64_t i = 0; i < nq; ++i) {
        const __m256 cr = _mm256_broadcast_ss(corr + i);
        float* orow = o + i * dhp;
        for (int64_t d = 0; d < dhp; d += 8) _mm256_storeu_ps(orow + d, _mm256_mul_ps(_mm256_loadu_ps(orow + d), cr));
      }
    }
    pv_rows(st, nk, v + k0 * a.v_ld, a.v_ld, dh, nq, o, dhp);
  }

  float* out = a.out + b * a.out_bs + q0 * a.out_ld + h * dh;
  for (int64_t i = 0; i < nq; ++i) {
    const __m256 inv = _mm256_set1_ps(1.0f / l[i]);
    const float* orow = o + i * dhp;
    float* dst = out + i * a.out_ld;
    int64_t d = 0;
    for (; d + 8 <= dh; d += 8) _mm256_storeu_ps(dst + d, _mm256_mul_ps(_mm256_loadu_ps(orow + d), inv));
    if (d < dh) _mm256_maskstore_ps(dst + d, tail_mask(dh - d), _mm256_mul_ps(_mm256_loadu_ps(orow + d), inv));
  }
}

}  // namespace egopd::avx2
