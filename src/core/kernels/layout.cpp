#include "core/kernels/layout.h"

#include <algorithm>

namespace egopd {

template <bool kAdd>
static void transpose_tiles(const float* src, float* dst, int64_t batch, int64_t rows, int64_t cols) {
  constexpr int64_t T = 32;  // tile so both sides stay in cache
#pragma omp parallel for collapse(2) schedule(static) if (batch * rows * cols > 32768)
  for (int64_t b = 0; b < batch; ++b) {
    for (int64_t r0 = 0; r0 < rows; r0 += T) {
      const float* s = src + b * rows * cols;
      float* d = dst + b * rows * cols;
      const int64_t r1 = std::min(rows, r0 + T);
      for (int64_t c0 = 0; c0 < cols; c0 += T) {
        const int64_t c1 = std::min(cols, c0 + T);
        for (int64_t r = r0; r < r1; ++r)
          for (int64_t c = c0; c < c1; ++c) {
            if constexpr (kAdd) d[c * rows + r] += s[r * cols + c];
            else d[c * rows + r] = s[r * cols + c];
          }
      }
    }
  }
}

void transpose_batched(const float* src, float* dst, int64_t batch, int64_t rows, int64_t cols) {
  transpose_tiles<false>(src, dst, batch, rows, cols);
}

void transpose_add_batched(const float* src, float* dst, int64_t batch, int64_t rows, int64_t cols) {
  transpose_tiles<true>(src, dst, batch, rows, cols);
}

// [B*F, L, C] <-> [B*L, F, C]: both are row copies of C floats.
void frames_to_sequences(const float* src, float* dst, int64_t b, int64_t f, int64_t l, int64_t c) {
#pragma omp parallel for collapse(2) schedule(static)
  for (int64_t bi = 0; bi < b; ++bi)
    for (int64_t li = 0; li < l; ++li)
      for (int64_t fi = 0; fi < f; ++fi)
        std::copy_n(src + ((bi * f + fi) * l + li) * c, c, dst + ((bi * l + li) * f + fi) * c);
}

void sequences_to_frames(const float* src, float* dst, int64_t b, int64_t f, int64_t l, int64_t c) {
#pragma omp parallel for collapse(2) schedule(static)
  for (int64_t bi = 0; bi < b; ++bi)
    for (int64_t fi = 0; fi < f; ++fi)
      for (int64_t li = 0; li < l; ++li)
        std::copy_n(src + ((bi * l + li) * f + fi) * c, c, dst + ((bi * f + fi) * l + li) * c);
}

}  // namespace egopd
