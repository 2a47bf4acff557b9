#pragma once
// Scaled-dot-product multi-head attention, computed in tiles with an online (streaming) softmax: the
// [lq x lk] score matrix is never materialised beyond one tile. Heads are contiguous channel slices:
// head j of a row uses channels [j*dh, (j+1)*dh). Float32.
//
// Precision::Bf16: q, k and v are rounded to bfloat16 (both products multiply bfloat16 values, exactly, and sum in
// float32), and so are the softmax weights: with scores s = c q.k in the log2 domain (c = scale * log2 e) and an
// integral running max m, p = bf16(2^(s - m)), out = sum p v / sum p. Raising m by an integer scales every p by a
// power of two, which bfloat16 rounding commutes with: the result does not depend on how keys are tiled (the same
// on every kernel path, up to float32 rounding). Native vdpbf16ps on AVX512-BF16, else emulated.
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

// Whether Precision::Bf16 may use the CPU's bfloat16 dot product (default true); tests turn it off to run the
// emulation on the avx512 path too.
void set_attention_bf16_native(bool allowed);

}  // namespace egopd
