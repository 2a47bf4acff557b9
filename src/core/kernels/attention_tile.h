#pragma once
// The flow of one (batch, head, query tile) shared by the blocked attention kernels (avx2/attention.cpp,
// avx512/attention.cpp): pack the query tile, then per key tile compute S^T = K (c Q)^T, mask (causal), update the
// online softmax down the columns, rescale the rows whose running max rose and accumulate P·V; finally divide by
// the running sums. c = scale * log2(e), so the kernels exponentiate with exp2. Include after the kernel file's
// `#pragma GCC target` (AVX2 or wider: the query tile is packed by avx2/transpose.h). K supplies the vector code:
//   K::kBQ, K::kBK                          queries and keys per tile
//   K::kPad                                 output rows are padded to a multiple of this (the vector width)
//   K::scores(qt, dh, k, k_ld, nk, ncol, st)         st[j][i] = sum_d k[j][d] qt[d][i] (stride kBQ), i < ncol
//   K::softmax_columns<kBf16>(st, nk, ncol, m, l, corr, scale)   st -> P^T; running max m, sum l; corr = rescale
//                                                    factors (kBf16: scores times scale, integer max, P in bf16)
//   K::scale_row(o, n, f)                            o[0..n) *= f (n a multiple of kPad)
//   K::pv_rows(pt, nk, v, v_ld, dh, nq, o, o_ld)     o[i][d] += sum_j pt[j][i] v[j][d]
//   K::store_row(dst, o, dh, f)                      dst[0..dh) = o * f
#include <cstdint>

#include "core/kernels/attention.h"
#include "core/kernels/avx2/transpose.h"

namespace egopd::attention_detail {

template <class K>
int64_t padded(int64_t n) {
  return (n + K::kPad - 1) / K::kPad * K::kPad;
}

template <class K>
int64_t tile_workspace(int64_t dh) {
  return dh * K::kBQ + K::kBK * K::kBQ + K::kBQ * padded<K>(dh) + 3 * K::kBQ;
}

// Causal mask of one score tile (rows: keys k0.., columns: queries q0.., row stride ld): key k0+j is hidden from
// query q0+i when k0+j > q0+i.
inline void mask_causal(float* st, int64_t ld, int64_t nk, int64_t ncol, int64_t k0, int64_t q0) {
  if (k0 + nk - 1 <= q0) return;
  for (int64_t j = 0; j < nk; ++j)
    for (int64_t i = 0; i < ncol; ++i)
      if (k0 + j > q0 + i) st[j * ld + i] = -__builtin_inff();
}

// Queries [q0, q0 + nq) (nq <= K::kBQ) of head h in batch b; work: tile_workspace<K>(dh) floats. bf16: the
// emulated Precision::Bf16 softmax (q, k and v are already rounded copies).
template <class K>
void attention_tile(const AttentionArgs& a, int64_t b, int64_t h, int64_t q0, int64_t nq, float* work, bool bf16) {
  constexpr int64_t kBQ = K::kBQ, kBK = K::kBK;
  const int64_t dh = a.dh, dhp = padded<K>(dh);
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
  pack_avx2::transpose_scaled(q, a.q_ld, nq, dh, c, qt, kBQ, ncol);  // qt[d][i] = c q[i][d], zero for i >= nq
  for (int64_t i = 0; i < nq * dhp; ++i) o[i] = 0.0f;
  for (int64_t i = 0; i < ncol; ++i) m[i] = -__builtin_inff(), l[i] = 0.0f;

  const int64_t kend = a.causal ? (a.lk < q0 + nq ? a.lk : q0 + nq) : a.lk;
  for (int64_t k0 = 0; k0 < kend; k0 += kBK) {
    const int64_t nk = kend - k0 < kBK ? kend - k0 : kBK;
    K::scores(qt, dh, k + k0 * a.k_ld, a.k_ld, nk, ncol, st);
    if (a.causal) mask_causal(st, kBQ, nk, ncol, k0, q0);
    if (bf16) K::template softmax_columns<true>(st, nk, ncol, m, l, corr, 1.0f);  // c is in qt already
    else K::template softmax_columns<false>(st, nk, ncol, m, l, corr, 1.0f);
    if (k0 > 0)  // rescale the accumulators of rows whose running max rose
      for (int64_t i = 0; i < nq; ++i)
        if (corr[i] != 1.0f) K::scale_row(o + i * dhp, dhp, corr[i]);
    K::pv_rows(st, nk, v + k0 * a.v_ld, a.v_ld, dh, nq, o, dhp);
  }

  float* out = a.out + b * a.out_bs + q0 * a.out_ld + h * dh;
  for (int64_t i = 0; i < nq; ++i) K::store_row(out + i * a.out_ld, o + i * dhp, dh, 1.0f / l[i]);
}

}  // namespace egopd::attention_detail
