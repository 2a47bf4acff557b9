// SGEMM driver (simple portable version; the blocked, packed implementation replaces it).
#include "core/kernels/gemm.h"

#include <omp.h>

#include <cmath>
#include <vector>

#include "core/error.h"

namespace egopd {

float apply_act(Act act, float x) {
  switch (act) {
    case Act::None: return x;
    case Act::SiLU: return x / (1.0f + std::exp(-x));
    case Act::GELU: return 0.5f * x * (1.0f + std::erf(x * 0.70710678118654752f));
    case Act::QuickGELU: return x / (1.0f + std::exp(-1.702f * x));
  }
  return x;
}

// Element (r, c) of a logical matrix operand as float32; `chan` is the output channel for the I8 scale.
static float operand_at(const Operand& op, int64_t r, int64_t c, int64_t chan) {
  int64_t idx = op.trans ? c * op.ld + r : r * op.ld + c;
  switch (op.dtype) {
    case DType::F32: return static_cast<const float*>(op.data)[idx];
    case DType::F16: return half_to_float(static_cast<const uint16_t*>(op.data)[idx]);
    case DType::BF16: return bf16_to_float(static_cast<const uint16_t*>(op.data)[idx]);
    case DType::I8: return float(static_cast<const int8_t*>(op.data)[idx]) * op.scale[chan];
    default: throw Error(std::string("gemm: unsupported operand dtype ") + dtype_name(op.dtype));
  }
}

void gemm(int64_t M, int64_t N, int64_t K, const Operand& A, const Operand& B, float* C, int64_t ldc,
          const Epilogue& ep) {
  if (M <= 0 || N <= 0) return;
  EGOPD_CHECK(A.dtype != DType::I8 || A.scale, "gemm: I8 operand A needs a scale");
  EGOPD_CHECK(B.dtype != DType::I8 || B.scale, "gemm: I8 operand B needs a scale");
  // A as float rows [M,K], B as float columns [N,K].
  std::vector<float> a(size_t(M) * K), bt(size_t(N) * K);
  for (int64_t i = 0; i < M; ++i)
    for (int64_t k = 0; k < K; ++k) a[i * K + k] = operand_at(A, i, k, i);
  for (int64_t j = 0; j < N; ++j)
    for (int64_t k = 0; k < K; ++k) bt[j * K + k] = operand_at(B, k, j, j);
#pragma omp parallel for schedule(static) if (!omp_in_parallel() && M * N * K > 65536)
  for (int64_t i = 0; i < M; ++i) {
    for (int64_t j = 0; j < N; ++j) {
      const float* ai = &a[i * K];
      const float* bj = &bt[j * K];
      float s = 0;
      for (int64_t k = 0; k < K; ++k) s += ai[k] * bj[k];
      if (ep.bias) s += ep.bias_per_row ? ep.bias[i] : ep.bias[j];
      s = apply_act(ep.act, s);
      float& c = C[i * ldc + j];
      c = ep.accumulate ? c + s : s;
    }
  }
}

}  // namespace egopd
