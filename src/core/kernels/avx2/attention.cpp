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
#include "core/kernels/avx2/vec_math.h"

namespace egopd::avx2 {

using namespace egopd::vmath;

namespace {

constexpr int64_t kBQ = 64;  // queries per tile (4 column blocks of 16)
constexpr int64_t kBK = 48;  // keys per tile (8 row blocks of 6)
constexpr int kMR = 6;       // micro-tile rows (keys for S^T, queries for P·V)

static inline int64_t round_up8(int64_t n) { return (n + 7) / 8 * 8; }
static inline int64_t min64(int64_t a, int64_t b) { return a < b ? a : b; }

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

// dst[d][i] = c * src[i][d] for an 8x8 block (src rows at stride ld, dst rows at stride kBQ).
static inline void transpose8_scaled(const float* src, int64_t ld, __m256 c, float* dst) {
  __m256 r0 = _mm256_loadu_ps(src), r1 = _mm256_loadu_ps(src + ld), r2 = _mm256_loadu_ps(src + 2 * ld),
         r3 = _mm256_loadu_ps(src + 3 * ld), r4 = _mm256_loadu_ps(src + 4 * ld), r5 = _mm256_loadu_ps(src + 5 * ld),
         r6 = _mm256_loadu_ps(src + 6 * ld), r7 = _mm256_loadu_ps(src + 7 * ld);
  const __m256 t0 = _mm256_unpacklo_ps(r0, r1), t1 = _mm256_unpackhi_ps(r0, r1), t2 = _mm256_unpacklo_ps(r2, r3),
               t3 = _mm256_unpackhi_ps(r2, r3), t4 = _mm256_unpacklo_ps(r4, r5), t5 = _mm256_unpackhi_ps(r4, r5),
               t6 = _mm256_unpacklo_ps(r6, r7), t7 = _mm256_unpackhi_ps(r6, r7);
  const __m256 u0 = _mm256_shuffle_ps(t0, t2, 0x44), u1 = _mm256_shuffle_ps(t0, t2, 0xEE),
               u2 = _mm256_shuffle_ps(t1, t3, 0x44), u3 = _mm256_shuffle_ps(t1, t3, 0xEE),
               u4 = _mm256_shuffle_ps(t4, t6, 0x44), u5 = _mm256_shuffle_ps(t4, t6, 0xEE),
               u6 = _mm256_shuffle_ps(t5, t7, 0x44), u7 = _mm256_shuffle_ps(t5, t7, 0xEE);
  r0 = _mm256_permute2f128_ps(u0, u4, 0x20), r1 = _mm256_permute2f128_ps(u1, u5, 0x20);
  r2 = _mm256_permute2f128_ps(u2, u6, 0x20), r3 = _mm256_permute2f128_ps(u3, u7, 0x20);
  r4 = _mm256_permute2f128_ps(u0, u4, 0x31), r5 = _mm256_permute2f128_ps(u1, u5, 0x31);
  r6 = _mm256_permute2f128_ps(u2, u6, 0x31), r7 = _mm256_permute2f128_ps(u3, u7, 0x31);
  _mm256_storeu_ps(dst, _mm256_mul_ps(r0, c)), _mm256_storeu_ps(dst + kBQ, _mm256_mul_ps(r1, c));
  _mm256_storeu_ps(dst + 2 * kBQ, _mm256_mul_ps(r2, c)), _mm256_storeu_ps(dst + 3 * kBQ, _mm256_mul_ps(r3, c));
  _mm256_storeu_ps(dst + 4 * kBQ, _mm256_mul_ps(r4, c)), _mm256_storeu_ps(dst + 5 * kBQ, _mm256_mul_ps(r5, c));
  _mm256_storeu_ps(dst + 6 * kBQ, _mm256_mul_ps(r6, c)), _mm256_storeu_ps(dst + 7 * kBQ, _mm256_mul_ps(r7, c));
}

// Qt[d][i] = c * q[i][d] for i < nq (zero for nq <= i < ncol): [nq, dh] (stride q_ld) -> [dh, kBQ].
static void pack_queries(const float* q, int64_t q_ld, int64_t nq, int64_t ncol, int64_t dh, float c, float* qt) {
  const int64_t nq8 = nq / 8 * 8, dh8 = dh / 8 * 8;
  const __m256 vc = _mm256_set1_ps(c);
  for (int64_t i = 0; i < nq8; i += 8)
    for (int64_t d = 0; d < dh8; d += 8) transpose8_scaled(q + i * q_ld + d, q_ld, vc, qt + d * kBQ + i);
  for (int64_t d = 0; d < dh; ++d) {
    float* row = qt + d * kBQ;
    for (int64_t i = d < dh8 ? nq8 : 0; i < nq; ++i) row[i] = q[i * q_ld + d] * c;
    for (int64_t i = nq; i < ncol; ++i) row[i] = 0.0f;
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

int64_t attention_tile_workspace(int64_t dh) {
  return dh * kBQ + kBK * kBQ + kBQ * round_up8(dh) + 3 * kBQ;
}

// Queries [q0, q0 + nq) (nq <= attention_tile_queries()) of head h in batch b.
// work: attention_tile_workspace(dh) floats.
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
  pack_queries(q, a.q_ld, nq, ncol, dh, c, qt);
  for (int64_t i = 0; i < nq * dhp; ++i) o[i] = 0.0f;
  for (int64_t i = 0; i < ncol; ++i) m[i] = -__builtin_inff(), l[i] = 0.0f;

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
      const __m256 m_new = _mm256_max_ps(m_old, mx);
      // A column with no visible key yet keeps m = -inf; subtract 0 instead so exp2(-inf - 0) = 0, not NaN.
      const __m256 m_sub = _mm256_blendv_ps(m_new, _mm256_setzero_ps(),
                                            _mm256_cmp_ps(m_new, _mm256_set1_ps(-__builtin_inff()), _CMP_EQ_OQ));
      const __m256 cr = exp2_ps(_mm256_sub_ps(m_old, m_sub));
      __m256 sum = _mm256_setzero_ps();
      for (int64_t j = 0; j < nk; ++j) {
        const __m256 p = exp2_ps(_mm256_sub_ps(_mm256_loadu_ps(st + j * kBQ + i), m_sub));
        _mm256_storeu_ps(st + j * kBQ + i, p);
        sum = _mm256_add_ps(sum, p);
      }
      _mm256_storeu_ps(m + i, m_new);
      _mm256_storeu_ps(l + i, _mm256_fmadd_ps(_mm256_loadu_ps(l + i), cr, sum));
      _mm256_storeu_ps(corr + i, cr);
    }
    if (k0 > 0) {  // rescale the accumulators of rows whose running max rose
      for (int64_t i = 0; i < nq; ++i) {
        if (corr[i] == 1.0f) continue;
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
