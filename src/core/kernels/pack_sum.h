#pragma once
// The B packer of the temporal Winograd (conv_temporal.cpp): a panel of the sum of two float32 matrices, written
// as plain loops over compile-time panel widths so that each kernel path's file compiles it with its own vector
// instructions (include after that file's `#pragma GCC target`; everything is file-local).
#include <cstdint>

namespace egopd::gemm_detail {
namespace {

// dst[k*NR + j] = a[k*ld + j] + sb * b[k*ld + j] for j < nr, 0 for nr <= j < NR.
template <int NR>
void pack_b_sum_rows(const float* a, const float* b, float sb, int64_t ld, int64_t kc, int nr, float* dst) {
  for (int64_t k = 0; k < kc; ++k) {
    const float* ak = a + k * ld;
    const float* bk = b + k * ld;
    float* d = dst + k * NR;
    if (nr == NR) {
      for (int j = 0; j < NR; ++j) d[j] = ak[j] + sb * bk[j];
    } else {
      for (int j = 0; j < nr; ++j) d[j] = ak[j] + sb * bk[j];
      for (int j = nr; j < NR; ++j) d[j] = 0.0f;
    }
  }
}

}  // namespace
}  // namespace egopd::gemm_detail
