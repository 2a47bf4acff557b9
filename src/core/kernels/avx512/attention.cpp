// AVX-512 attention for one (batch, head, query tile): the flow of attention_tile.h (the AVX2 kernel's blocked
// two-GEMM scheme with an online softmax) in zmm registers:
//  * S^T[key, query] = K · (c Q)^T in 12-key x 32-query micro-tiles (24 accumulators; K elements broadcast from
//    the source rows, so keys are never packed), or 12 x 16 for the last 16 query columns;
//  * the softmax runs down columns, 16 queries per vector;
//  * P·V in 6-query x 64-channel micro-tiles (24 accumulators), the last channel vector masked.
#include <cstdint>

#include "core/kernels/avx512/isa.h"

#include "core/kernels/attention.h"
#include "core/kernels/attention_tile.h"
#include "core/kernels/gemm_internal.h"
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

// Online softmax of one key tile down each column (16 queries per vector): st holds the scores on entry (times
// `scale`, the log2-domain factor not folded into the queries) and P^T on exit; m (running max, log2 domain) and l
// (running sum) are updated; corr receives each column's rescale factor. kBf16 (Precision::Bf16, attention.h): the
// running max is an integer and P is rounded to bfloat16.
template <bool kBf16>
void softmax_columns(float* st, int64_t nk, int64_t ncol, float* m, float* l, float* corr, float scale) {
  const __m512 ninf = _mm512_set1_ps(-__builtin_inff()), vscale = _mm512_set1_ps(scale);
  for (int64_t i = 0; i < ncol; i += 16) {
    __m512 mx = ninf;
    for (int64_t j = 0; j < nk; ++j) {
      __m512 s = _mm512_loadu_ps(st + j * kBQ + i);
      if (kBf16) _mm512_storeu_ps(st + j * kBQ + i, s = _mm512_mul_ps(s, vscale));
      mx = _mm512_max_ps(mx, s);
    }
    if (kBf16) mx = _mm512_roundscale_ps(mx, _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC);
    const __m512 m_old = _mm512_loadu_ps(m + i);
    const __m512 m_new = _mm512_max_ps(m_old, mx);
    // A column with no visible key yet keeps m = -inf; subtract 0 instead so exp2(-inf - 0) = 0, not NaN.
    const __m512 m_sub = _mm512_mask_blend_ps(_mm512_cmp_ps_mask(m_new, ninf, _CMP_EQ_OQ), m_new, _mm512_setzero_ps());
    const __m512 cr = exp2_ps(_mm512_sub_ps(m_old, m_sub));
    __m512 sum = _mm512_setzero_ps();
    for (int64_t j = 0; j < nk; ++j) {
      __m512 p = exp2_ps(_mm512_sub_ps(_mm512_loadu_ps(st + j * kBQ + i), m_sub));
      if (kBf16) p = round_bf16_ps(p);
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
  template <bool kBf16>
  static void softmax_columns(float* st, int64_t nk, int64_t ncol, float* m, float* l, float* corr, float scale) {
    avx512::softmax_columns<kBf16>(st, nk, ncol, m, l, corr, scale);
  }
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

// ---- Precision::Bf16 on CPUs with AVX512-BF16 -------------------------------------------------------------------
// The same flow with both products on vdpbf16ps (lane += a.lo * b.lo + a.hi * b.hi, exact products summed in
// float32), 32-bit slots holding bfloat16 pairs:
//  * K rows as pairs along channels, kb[key][d/2] (attention_bf16_prepare, once per call and head);
//  * the query tile as pairs along channels, qp[d/2][query];
//  * P^T (rounded to bfloat16 by the softmax) as pairs along keys, in place in st;
//  * V as pairs along keys, vp[key/2][channel] (once per call, rows padded to 16 channels).
// Scores come out unscaled: the softmax multiplies them by c (c * bf16(q) would round twice).

// bf16 bits of 16 floats (nearest even), in the low half of each 32-bit lane. x finite.
inline __m512i bf16_lo16(__m512 x) { return _mm512_srli_epi32(_mm512_castps_si512(round_bf16_ps(x)), 16); }

// 16 bfloat16 pairs: lane i = bf16(lo[i]) | bf16(hi[i]) << 16.
inline __m512i bf16_pairs16(__m512 lo, __m512 hi) {
  return _mm512_or_si512(bf16_lo16(lo), _mm512_slli_epi32(bf16_lo16(hi), 16));
}

// dst[p] = bf16(x[2p]) | bf16(x[2p + 1]) << 16 for p < (n + 1) / 2 (x[n] = 0).
inline void row_to_pairs(const float* x, int64_t n, uint32_t* dst) {
  for (int64_t d = 0; d < n; d += 32) {
    const __m512i lo = bf16_lo16(_mm512_maskz_loadu_ps(lanes(n - d), x + d));
    const __m512i hi = bf16_lo16(_mm512_maskz_loadu_ps(lanes(n - d - 16 > 0 ? n - d - 16 : 0), x + d + 16));
    const __m256i p0 = _mm512_cvtepi32_epi16(lo), p1 = _mm512_cvtepi32_epi16(hi);  // 16 bf16 each, in order
    const int64_t pairs = ((n - d < 32 ? n - d : 32) + 1) / 2;
    _mm512_mask_storeu_epi32(dst + d / 2, tail_mask16(pairs), _mm512_inserti64x4(_mm512_castsi256_si512(p0), p1, 1));
  }
}

// P^T's rows (stride kBQ, columns [0, ncol)) as key pairs in place: slot p * kBQ + i = P^T[2p][i] | P^T[2p + 1][i]
// << 16 (P^T[nk][i] = 0). Pair p overwrites float row p <= 2p, whose values are loaded first.
inline void key_pairs_in_place(float* st, int64_t nk, int64_t ncol) {
  uint32_t* out = reinterpret_cast<uint32_t*>(st);
  for (int64_t p = 0; 2 * p < nk; ++p)
    for (int64_t i = 0; i < ncol; i += 16) {
      const __m512 hi = 2 * p + 1 < nk ? _mm512_loadu_ps(st + (2 * p + 1) * kBQ + i) : _mm512_setzero_ps();
      _mm512_storeu_si512(out + p * kBQ + i, bf16_pairs16(_mm512_loadu_ps(st + 2 * p * kBQ + i), hi));
    }
}

// acc[r][q] (+)= sum over the n slots j of a(r, j) . b[j][16q .. 16q + 16) for R rows, a(r, j) = a[r * a_rs + j]
// broadcast; b rows at stride b_ld. The intrinsic, not gemm.cpp's inline assembly: on these unrolled arrays GCC keeps
// the accumulators in registers, and the assembly form made it spill them. The only function that needs
// AVX512-BF16 (a call of its own from the rest, which runs on CPUs without it too).
template <int R, int NC, bool kLoadC>
EGOPD_TARGET_BF16 void dp_tile(const uint32_t* a, int64_t a_rs, int64_t a_js, const uint32_t* b, int64_t b_ld,
                               int64_t n, float* c, int64_t c_ld) {
  __m512 acc[R][NC];
#pragma GCC unroll 12
  for (int r = 0; r < R; ++r)
#pragma GCC unroll 4
    for (int q = 0; q < NC; ++q) acc[r][q] = kLoadC ? _mm512_loadu_ps(c + r * c_ld + q * 16) : _mm512_setzero_ps();
  for (int64_t j = 0; j < n; ++j) {
    __m512i bv[NC];
#pragma GCC unroll 4
    for (int q = 0; q < NC; ++q) bv[q] = _mm512_loadu_si512(b + j * b_ld + q * 16);
#pragma GCC unroll 12
    for (int r = 0; r < R; ++r) {
      const __m512i av = _mm512_set1_epi32(int(a[r * a_rs + j * a_js]));
#pragma GCC unroll 4
      for (int q = 0; q < NC; ++q) acc[r][q] = _mm512_dpbf16_ps(acc[r][q], (__m512bh)av, (__m512bh)bv[q]);
    }
  }
#pragma GCC unroll 12
  for (int r = 0; r < R; ++r)
#pragma GCC unroll 4
    for (int q = 0; q < NC; ++q) _mm512_storeu_ps(c + r * c_ld + q * 16, acc[r][q]);
}

// Calls f.template operator()<R>(r0) for row blocks covering [0, rows): blocks of RMax, then one block of the rest.
template <int RMax, int R = RMax, class F>
inline void row_blocks(int64_t rows, F&& f) {
  if constexpr (R == RMax) {
    int64_t r = 0;
    for (; r + RMax <= rows; r += RMax) f.template operator()<RMax>(r);
    if (rows > r) row_blocks<RMax, RMax - 1>(rows - r, [&]<int T>(int64_t r0) { f.template operator()<T>(r + r0); });
  } else if constexpr (R > 0) {
    if (rows == R) f.template operator()<R>(0);
    else row_blocks<RMax, R - 1>(rows, f);
  }
}

struct Bf16Shape {
  int64_t dh2, dhv;  // channel pairs, V row stride (channels padded to 16)
};
Bf16Shape bf16_shape(int64_t dh) { return {(dh + 1) / 2, (dh + 15) / 16 * 16}; }

}  // namespace

int64_t attention_bf16_operand_slots(int64_t lk, int64_t dh) {
  const Bf16Shape sh = bf16_shape(dh);
  return lk * sh.dh2 + (lk + 1) / 2 * sh.dhv;
}

void attention_bf16_prepare(const AttentionArgs& a, int64_t b, int64_t h, uint32_t* ops) {
  const Bf16Shape sh = bf16_shape(a.dh);
  uint32_t* kb = ops;
  uint32_t* vp = ops + a.lk * sh.dh2;
  for (int64_t j = 0; j < a.lk; ++j) row_to_pairs(a.k + b * a.k_bs + j * a.k_ld + h * a.dh, a.dh, kb + j * sh.dh2);
  for (int64_t jp = 0; 2 * jp < a.lk; ++jp) {
    const float* v0 = a.v + b * a.v_bs + 2 * jp * a.v_ld + h * a.dh;
    const bool has_odd = 2 * jp + 1 < a.lk;
    for (int64_t d = 0; d < sh.dhv; d += 16) {
      const __mmask16 m = lanes(a.dh - d > 0 ? a.dh - d : 0);
      const __m512 hi = has_odd ? _mm512_maskz_loadu_ps(m, v0 + a.v_ld + d) : _mm512_setzero_ps();
      _mm512_storeu_si512(vp + jp * sh.dhv + d, bf16_pairs16(_mm512_maskz_loadu_ps(m, v0 + d), hi));
    }
  }
}

int64_t attention_bf16_workspace(int64_t dh) {
  const Bf16Shape sh = bf16_shape(dh);
  return dh * kBQ + kBK * kBQ + kBQ * sh.dhv + 3 * kBQ;
}

void attention_tile_bf16(const AttentionArgs& a, const uint32_t* ops, int64_t b, int64_t h, int64_t q0, int64_t nq,
                         float* work) {
  const Bf16Shape sh = bf16_shape(a.dh);
  const int64_t dh2 = sh.dh2, dhv = sh.dhv;
  const int64_t ncol = (nq + 15) / 16 * 16;  // query columns computed (multiple of 16)
  float* qt = work;                          // [dh][ncol] Q^T, zero beyond nq; then [dh2][ncol] its channel pairs
  float* st = work + a.dh * kBQ;             // [kBK][kBQ] scores, then P^T, then its key pairs
  float* o = st + kBK * kBQ;                 // [kBQ][dhv] unnormalised output
  float* m = o + kBQ * dhv;                  // [kBQ] running max (log2 domain, integral)
  float* l = m + kBQ;                        // [kBQ] running sum
  float* corr = l + kBQ;                     // [kBQ] rescale factor of this key tile
  const uint32_t* kb = ops;
  const uint32_t* vp = ops + a.lk * dh2;

  pack_avx2::transpose_scaled(a.q + b * a.q_bs + q0 * a.q_ld + h * a.dh, a.q_ld, nq, a.dh, 1.0f, qt, ncol, ncol);
  gemm_detail::to_bf16_pairs_avx512(qt, int(ncol), a.dh);
  const uint32_t* qp = reinterpret_cast<const uint32_t*>(qt);
  for (int64_t i = 0; i < nq * dhv; ++i) o[i] = 0.0f;
  for (int64_t i = 0; i < ncol; ++i) m[i] = -__builtin_inff(), l[i] = 0.0f;

  const float c = a.scale * 1.44269504088896341f;
  const int64_t kend = a.causal ? (a.lk < q0 + nq ? a.lk : q0 + nq) : a.lk;
  for (int64_t k0 = 0; k0 < kend; k0 += kBK) {  // k0 even: key pairs never straddle tiles
    const int64_t nk = kend - k0 < kBK ? kend - k0 : kBK, nkp = (nk + 1) / 2;
    // S^T[key][query] = K · Q^T: key rows (12 at a time) by 32 or 16 query columns
    for (int64_t i0 = 0; i0 < ncol; i0 += 32) {
      const uint32_t* kr = kb + k0 * dh2;
      if (ncol - i0 >= 32)
        row_blocks<kSR>(nk, [&]<int R>(int64_t r) {
          dp_tile<R, 2, false>(kr + r * dh2, dh2, 1, qp + i0, ncol, dh2, st + r * kBQ + i0, kBQ);
        });
      else
        row_blocks<kSR>(nk, [&]<int R>(int64_t r) {
          dp_tile<R, 1, false>(kr + r * dh2, dh2, 1, qp + i0, ncol, dh2, st + r * kBQ + i0, kBQ);
        });
    }
    if (a.causal) attention_detail::mask_causal(st, kBQ, nk, ncol, k0, q0);
    softmax_columns<true>(st, nk, ncol, m, l, corr, c);
    if (k0 > 0)
      for (int64_t i = 0; i < nq; ++i)
        if (corr[i] != 1.0f) Kernel::scale_row(o + i * dhv, dhv, corr[i]);
    key_pairs_in_place(st, nk, ncol);  // exact: P is already in bfloat16
    // O[query][channel] += P · V: 6 query rows by 64 channels (the last block 16-48)
    const uint32_t* pp = reinterpret_cast<const uint32_t*>(st);
    const uint32_t* vt = vp + k0 / 2 * dhv;
    row_blocks<kPR>(nq, [&]<int R>(int64_t r) {
      int64_t d = 0;
      for (; d + 64 <= dhv; d += 64) dp_tile<R, 4, true>(pp + r, 1, kBQ, vt + d, dhv, nkp, o + r * dhv + d, dhv);
      switch ((dhv - d) / 16) {
        case 3: dp_tile<R, 3, true>(pp + r, 1, kBQ, vt + d, dhv, nkp, o + r * dhv + d, dhv); break;
        case 2: dp_tile<R, 2, true>(pp + r, 1, kBQ, vt + d, dhv, nkp, o + r * dhv + d, dhv); break;
        case 1: dp_tile<R, 1, true>(pp + r, 1, kBQ, vt + d, dhv, nkp, o + r * dhv + d, dhv); break;
        default: break;
      }
    });
  }
  float* out = a.out + b * a.out_bs + q0 * a.out_ld + h * a.dh;
  for (int64_t i = 0; i < nq; ++i) Kernel::store_row(out + i * a.out_ld, o + i * dhv, a.dh, 1.0f / l[i]);
}

int64_t attention_tile_queries() { return kBQ; }

int64_t attention_tile_workspace(int64_t dh) { return attention_detail::tile_workspace<Kernel>(dh); }

void attention_tile(const AttentionArgs& a, int64_t b, int64_t h, int64_t q0, int64_t nq, float* work, bool bf16) {
  attention_detail::attention_tile<Kernel>(a, b, h, q0, nq, work, bf16);
}

}  // namespace egopd::avx512
