#pragma once
// Scaled-dot-product multi-head attention, computed in tiles with an online (streaming) softmax: the
// [lq x lk] score matrix is never materialised beyond one tile. Heads are contiguous channel slices:
// head j of a row uses channels [j*dh, (j+1)*dh). Float32.
#include <cstdint>

namespace egopd {

struct AttentionArgs {
  int64_t batch = 1, heads = 1, lq = 0, lk = 0, dh = 0;
  // q: row i of batch b at q + b*q_bs + i*q_ld (heads*dh channels); same for k, v (lk rows) and out (lq rows).
  const float* q = nullptr;
  int64_t q_ld = 0, q_bs = 0;
  const float* k = nullptr;
  int64_t k_ld = 0, k_bs = 0;
  const float* v = nullptr;
  int64_t v_ld = 0, v_bs = 0;
  float* out = nullptr;
  int64_t out_ld = 0, out_bs = 0;
  float scale = 1.0f;   // usually dh^-0.5
  bool causal = false;  // query i attends to keys j <= i (requires lq == lk)
};

void attention(const AttentionArgs& a);

}  // namespace egopd
